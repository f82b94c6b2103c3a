"""``run_eval``: the evaluation job behind ``navgym eval`` (and ``python -m agents.evaluation``).

Policy specs (strings):

* ``baselines`` (or ``all``): every baseline of the env's task, with its tuned parameters;
* a baseline name (``suboptimal``, ``ess``, ...), optionally with parameters
  ``NAME:key=value,key=value`` (overriding the tuned ones);
* ``oracle``: :class:`~agents.baselines.HindsightOracle` over a grid of constant knobs plus the
  baselines requested before it (reads truth: an upper bound on them, never a baseline);
  ``greedy_oracle``: :class:`~agents.baselines.GreedyOracle` (one-step lookahead; no bound);
* ``[LABEL=]ALGO:PATH`` for a stable-baselines3 model, e.g. ``ppo:agents/zoo/x.zip``
  (``ALGO`` one of SB3's algorithms or ``ppo_lstm``, sb3-contrib's RecurrentPPO,
  case-insensitive; the label defaults to the file stem). A trained agent folder loads with its
  normalization and memory (``frame_stack``, LSTM), carried per episode by the rollout.
  A model saved by plain SB3 (no navgym manifest) loads with SB3's own loader only with
  ``--trust`` (``trust=True``): SB3 unpickles its archive (and ``--vecnormalize PATH.pkl``,
  SB3's pickled ``VecNormalize``), which can run arbitrary code.
* ``[LABEL=]supervised:DIR`` for a supervised RowScale agent of :mod:`agents.supervised` (a zoo
  folder such as ``agents/zoo/Robot2dRowScale-v3-supervised``; its manifest checks the weights'
  SHA-256 and the env's observation layout; nothing is unpickled).

Each policy needs its own label: two specs with one label (``plain`` as an agent's label beside
the ``plain`` baseline) are an error, never a silent replacement.
"""

from __future__ import annotations

import argparse
import copy
import functools
import json
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from agents.baselines import (
    GreedyOracle,
    HindsightOracle,
    baseline_specs,
    load_tuned,
    make_baseline,
)
from agents.baselines.oracle import constant_candidates
from agents.cli_args import add_gym_packages
from agents.evaluation.bootstrap import DEFAULT_LEVEL, DEFAULT_RESAMPLES
from agents.evaluation.report import results_table, write_outputs
from agents.evaluation.runner import EvalResults, evaluate
from agents.policy_runner import policy_kind
from agents.seeds import seeds as seed_range

__all__ = ["add_arguments", "parse_env_kwargs", "parse_policies", "run", "run_eval"]

SB3_ALGOS = ("a2c", "ddpg", "dqn", "ppo", "ppo_lstm", "sac", "td3")


def _value(text: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        return text


def parse_policies(
    specs: Sequence[str],
    env_id: str,
    env_kwargs: Mapping[str, Any] | None = None,
    tuned: Mapping[str, Mapping] | None = None,
    vecnormalize: str | Path | None = None,
    *,
    trust: bool = False,
) -> dict[str, Any]:
    """``{label: policy or factory}`` from the policy specs of the module docstring.

    Args:
        specs: policy specs.
        env_id: registered env id (its task gives the baselines).
        env_kwargs: env keyword arguments.
        tuned: baseline parameters by name.
        vecnormalize: a pickled ``VecNormalize`` (SB3's ``vecnormalize.pkl``) for the one plain
            SB3 model among the specs.
        trust: allow SB3's own loader (unpickling) for plain SB3 models and ``vecnormalize``.

    Raises:
        ValueError: an unknown spec, or two policies with one label.
    """
    import gymnasium as gym

    import navgym  # noqa: F401

    layout_env = gym.make(env_id, **dict(env_kwargs or {}))
    specs_by_name = baseline_specs(layout_env)  # the per-row Mixture (v2) has its own set
    tuned = dict(tuned or {})
    out: dict[str, Any] = {}
    origin: dict[str, str] = {}

    def put(name: str, policy: Any, spec: str) -> None:
        if name in out:
            raise ValueError(
                f"label {name!r} is given twice (by {origin[name]!r} and by {spec!r}): each policy "
                "needs its own label; name one with LABEL=SPEC, e.g. 'mine=ppo:agents/zoo/x.zip'"
            )
        out[name], origin[name] = policy, spec

    plain_sb3 = [s for s in specs if _is_plain_sb3(s)]
    if vecnormalize is not None and len(plain_sb3) != 1:
        raise ValueError(
            f"--vecnormalize belongs to one plain SB3 model (ALGO:PATH.zip without a navgym manifest); "
            f"got {len(plain_sb3)} such specs"
        )
    for spec in specs:
        label, _, rest = spec.partition("=") if "=" in spec.split(":")[0] else ("", "", spec)
        head, _, tail = rest.partition(":")
        key = head.lower()
        if key in ("baselines", "all"):
            for name in specs_by_name:
                put(name, make_baseline(layout_env, name, **tuned.get(name, {})), spec)
        elif key == "oracle":
            base = {k: v for k, v in out.items() if policy_kind(v) == "baseline"}
            put(label or "oracle", functools.partial(_oracle, base=base), spec)
        elif key == "greedy_oracle":
            put(label or "greedy_oracle", GreedyOracle, spec)
        elif key in SB3_ALGOS and tail:
            put(label or Path(tail).stem, _load_sb3(key, tail, vecnormalize, trust=trust), spec)
        elif key == "supervised" and tail:
            from agents.supervised.files import load_policy

            put(label or Path(tail).name, load_policy(tail, layout_env), spec)
        elif key in specs_by_name:
            params = dict(tuned.get(key, {}))
            if tail:
                for kv in tail.split(","):
                    k, _, v = kv.partition("=")
                    params[k.strip()] = _value(v.strip())
            put(label or (key if not tail else spec), make_baseline(layout_env, key, **params), spec)
        else:
            raise ValueError(
                f"unknown policy spec {spec!r}: use 'baselines', 'oracle', one of {sorted(specs_by_name)}, "
                f"NAME:k=v,..., [LABEL=]ALGO:PATH with ALGO in {SB3_ALGOS}, or [LABEL=]supervised:DIR"
            )
    layout_env.close()
    return out


def _sb3_path(spec: str) -> Path | None:
    """The model path of an ``[LABEL=]ALGO:PATH`` spec (``.zip`` added where needed); else None."""
    rest = spec.partition("=")[2] if "=" in spec.split(":")[0] else spec
    head, _, tail = rest.partition(":")
    if head.lower() not in SB3_ALGOS or not tail:
        return None
    p = Path(tail)
    if not p.exists() and p.suffix != ".zip" and p.with_name(p.name + ".zip").is_file():
        p = p.with_name(p.name + ".zip")
    return p


def _is_plain_sb3(spec: str) -> bool:
    """Whether a spec names a model archive saved by plain SB3 (no navgym manifest beside it)."""
    from agents.training.agent_files import MANIFEST_FILE, MODEL_FILE

    p = _sb3_path(spec)
    if p is None or not p.is_file():
        return False
    return p.name != MODEL_FILE or not (p.parent / MANIFEST_FILE).is_file()


def _load_sb3(algo: str, path: str, vecnormalize: str | Path | None = None, *, trust: bool = False) -> Any:
    """An SB3 model from ``path`` (a run folder or a zip, ``.zip`` optional).

    A navgym agent (folder with ``manifest.json``) loads through
    :func:`~agents.training.loading.load_agent` (its ``vecnormalize.npz`` normalizes the
    observations as in training, nothing is unpickled). A model saved by plain SB3 loads through
    SB3's own loader only with ``trust`` (it unpickles), with the statistics of ``vecnormalize``
    (a pickled ``VecNormalize``) when given.
    """
    from agents.training.agent import TrainedAgent
    from agents.training.agent_files import AgentLoadError
    from agents.training.config import ALGOS
    from agents.training.loading import load_agent
    from agents.training.normalization import VecNormalizeStats
    from agents.training.sb3_archive import algo_class

    p = _sb3_path(f"{algo}:{path}") or Path(path)
    plain = _is_plain_sb3(f"{algo}:{path}")
    if plain and not trust:
        raise AgentLoadError(
            f"{p} is a plain SB3 save (no navgym manifest.json beside a model.zip): SB3's loader "
            "unpickles it, which can run arbitrary code. Pass --trust (Python: trust=True) only if "
            f"you trust the file, or turn it once into a navgym agent with "
            f"'navgym import {p} --trust --env ID OUT_DIR' and evaluate that folder"
        )
    if plain:
        if not p.is_file():
            raise FileNotFoundError(f"no {algo.upper()} model at {path}")
        if algo in ALGOS:
            cls: Any = algo_class(algo)
        else:  # SB3_ALGOS without a navgym configuration
            import stable_baselines3 as sb3

            cls = {"ddpg": sb3.DDPG, "td3": sb3.TD3}[algo]
        model = cls.load(p, device="cpu")
        norm = None
        if vecnormalize is not None:
            norm = VecNormalizeStats.load(vecnormalize, trust=True)
            if norm is not None and norm.mean.shape != model.observation_space.shape:
                raise AgentLoadError(
                    f"{vecnormalize} normalizes observations of shape {norm.mean.shape}; the model "
                    f"{p} takes {model.observation_space.shape}"
                )
        return TrainedAgent(model, norm, p, {"algo": algo})
    if algo in ALGOS:
        return load_agent(p, algo=algo, trust=trust)
    if not p.is_file():
        raise FileNotFoundError(f"no {algo.upper()} model at {path}")
    import stable_baselines3 as sb3

    others: dict[str, type[sb3.common.base_class.BaseAlgorithm]] = {"ddpg": sb3.DDPG, "td3": sb3.TD3}
    return others[algo].load(p, device="cpu")


def _oracle(env: Any, base: Mapping[str, Any]) -> HindsightOracle:
    cands = constant_candidates(env)
    cands.update({f"baseline:{k}": copy.deepcopy(v) for k, v in base.items()})
    return HindsightOracle(env, cands)


def run_eval(
    env_id: str,
    policies: Sequence[str] | Mapping[str, Any] = ("baselines",),
    episodes: int = 200,
    out: str | Path | None = None,
    *,
    seed_offset: int = 0,
    env_kwargs: Mapping[str, Any] | None = None,
    tuned: bool | str | Path | Mapping[str, Mapping] = True,
    reference: str | None = None,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    boot_seed: int = 0,
    plots: bool = True,
    progress: bool = True,
    workers: int = 1,
    address: str | None = None,
    ray: bool = False,
    vecnormalize: str | Path | None = None,
    trust: bool = False,
    trace: int = 0,
) -> EvalResults:
    """Evaluate policies on ``episodes`` held-out episodes of ``env_id``; write the report to ``out``.

    Args:
        env_id: registered env id.
        policies: policy specs (module docstring) or a ready ``{label: policy or factory}``.
        episodes: number of episodes (evaluation seeds ``agents.seeds.seeds("eval", episodes,
            seed_offset)``).
        out: output directory (CSV, report.md, plots, manifest.json); None writes nothing.
        seed_offset: offset into the evaluation seed range.
        env_kwargs: env keyword arguments (the tuned parameters were tuned with the defaults;
            a warning says so when kwargs are given).
        tuned: True loads ``agents/baselines/tuned/<EnvName-vK>.json``; a path loads that file;
            a mapping gives the parameters; False uses the class defaults.
        reference: reference policy of the paired differences (default: best baseline).
        n_boot: bootstrap resamples (percentile bootstrap over episodes).
        level: confidence level of the intervals.
        boot_seed: seed of the bootstrap's NumPy generator.
        plots: write the PNG plots.
        progress: tqdm bars.
        workers: > 1: split the episodes over ``workers`` forked processes of this machine
            (:func:`agents.evaluation.parts.forked_evaluate`), or Ray workers with ``ray`` or an
            ``address``; the same results bit for bit.
        address: Ray cluster address (``ray://head:10001``; implies ``ray``).
        ray: split the episodes over Ray workers
            (:func:`agents.scale.distributed_eval.distributed_evaluate`; the ``scale`` extra;
            without an ``address``, a local Ray).
        vecnormalize: SB3's pickled ``VecNormalize`` of the one plain SB3 model among the specs.
        trust: allow SB3's own loader (which unpickles) for plain SB3 models and ``vecnormalize``;
            only for files you trust.
        trace: with ``plots``, ``knob_trace.png`` of the knob and error over time of every
            policy on the first ``trace`` episodes.

    Returns:
        :class:`~agents.evaluation.runner.EvalResults` (``out`` holds its files).
    """
    tuned_src: str | None
    if isinstance(tuned, Mapping):
        tuned_params = {k: dict(v) for k, v in tuned.items()}
        tuned_src = "mapping"
    elif tuned is True:
        tuned_params = load_tuned(env_id)
        tuned_src = "agents/baselines/tuned" if tuned_params else None
    elif tuned:
        tuned_params = load_tuned(env_id, tuned, missing_ok=False)
        tuned_src = str(tuned)
    else:
        tuned_params, tuned_src = {}, None
    if tuned_params and env_kwargs:
        warnings.warn("baseline parameters were tuned with the default env kwargs", stacklevel=2)
    if isinstance(policies, Mapping):
        pols = dict(policies)
    else:
        pols = parse_policies(list(policies), env_id, env_kwargs, tuned_params, vecnormalize, trust=trust)
        specs = baseline_specs(env_id)
        untuned = [n for n in pols if n in specs and specs[n].tunable and n not in tuned_params]
        if untuned:
            warnings.warn(f"no tuned parameters for {untuned}: class defaults used", stacklevel=2)
    if int(workers) < 1:
        raise ValueError(f"workers must be at least 1; got {workers}")
    seeds = seed_range("eval", episodes, seed_offset)
    if ray or address is not None:
        from agents.scale.distributed_eval import distributed_evaluate

        source: Any = pols
        if not isinstance(policies, Mapping):  # each worker loads its own copies from the specs
            source = functools.partial(
                parse_policies, list(policies), env_id, env_kwargs, tuned_params, vecnormalize, trust=trust
            )
        results = distributed_evaluate(
            env_id,
            source,
            seeds,
            env_kwargs,
            workers=workers,
            address=address,
            reference=reference,
            n_boot=n_boot,
            level=level,
            boot_seed=boot_seed,
        )
    elif workers > 1:
        results = _forked(
            env_id, pols, seeds, env_kwargs, workers, progress, reference, n_boot, level, boot_seed
        )
    else:
        results = evaluate(
            env_id,
            pols,
            seeds,
            env_kwargs,
            reference=reference,
            n_boot=n_boot,
            level=level,
            boot_seed=boot_seed,
            progress=progress,
        )
    results.config.update(
        {"tuned_source": tuned_src, "tuned_params": tuned_params, "seed_offset": seed_offset}
    )
    if out is not None:
        write_outputs(results, out, plots=plots, trace=trace)
    return results


def _forked(
    env_id: str,
    pols: Mapping[str, Any],
    seeds: list[int],
    env_kwargs: Mapping[str, Any] | None,
    workers: int,
    progress: bool,
    reference: str | None,
    n_boot: int,
    level: float,
    boot_seed: int,
) -> EvalResults:
    """:func:`agents.evaluation.parts.forked_evaluate` with a bar over the parts."""
    from agents.evaluation.parts import forked_evaluate, split_seeds

    n_parts = len(split_seeds(seeds, workers))
    pbar = None
    if progress:
        from tqdm.auto import tqdm

        pbar = tqdm(total=n_parts, desc=f"eval in {n_parts} processes", leave=False, disable=None)
    try:
        return forked_evaluate(
            env_id,
            pols,
            seeds,
            env_kwargs,
            workers=workers,
            reference=reference,
            n_boot=n_boot,
            level=level,
            boot_seed=boot_seed,
            on_done=None if pbar is None else (lambda i: pbar.update(1)),
        )
    finally:
        if pbar is not None:
            pbar.close()


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``navgym eval`` (``--env ID --policies ... --episodes N --out DIR``)."""
    parser.add_argument("--env", required=True, help="env id, e.g. navgym/GpsInsFading-v0")
    add_gym_packages(parser)
    parser.add_argument(
        "--policies",
        nargs="+",
        default=["baselines"],
        metavar="SPEC",
        help=(
            "policy specs, each a distinct label: 'baselines' (every baseline of the task, tuned); "
            "a baseline NAME or NAME:key=value,...; 'oracle' (hindsight bound over constant knobs and "
            "the baselines before it) or 'greedy_oracle'; [LABEL=]ALGO:PATH for an SB3 model (ALGO: "
            f"{', '.join(SB3_ALGOS)}; PATH a navgym agent folder, its model.zip, or a plain SB3 .zip "
            "with --trust); [LABEL=]supervised:DIR for an agents.supervised folder (v3 RowScale ids); "
            "the label defaults to the name, or the file stem (default: baselines)"
        ),
    )
    parser.add_argument(
        "--vecnormalize",
        default=None,
        metavar="PKL",
        help="SB3's vecnormalize.pkl of the one plain SB3 model in --policies (needs --trust)",
    )
    parser.add_argument(
        "--trust",
        action="store_true",
        help=(
            "load plain SB3 saves with SB3's own loader; it unpickles the files, which can run "
            "arbitrary code: only for files you trust (navgym agents with a manifest never need it)"
        ),
    )
    parser.add_argument("--episodes", type=int, default=200, help="held-out episodes (evaluation seeds)")
    parser.add_argument("--out", default=None, help="output directory (default results/eval/<EnvName-vK>)")
    parser.add_argument("--seed-offset", type=int, default=0, help="offset into the evaluation seed range")
    parser.add_argument(
        "--env-kwargs", default="{}", help="env keyword arguments: JSON, or key=value[,key=value]"
    )
    parser.add_argument("--tuned", default=None, help="tuned-parameter JSON (default: the committed one)")
    parser.add_argument("--no-tuned", action="store_true", help="use the baselines' class defaults")
    parser.add_argument("--reference", default=None, help="reference policy (default: best baseline)")
    parser.add_argument("--bootstrap", type=int, default=DEFAULT_RESAMPLES, help="bootstrap resamples")
    parser.add_argument("--boot-seed", type=int, default=0, help="bootstrap seed")
    parser.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    parser.add_argument(
        "--trace",
        type=int,
        default=0,
        metavar="N",
        help="knob_trace.png: the knob and error of every policy over time on the first N episodes",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        help="split the episodes over N forked processes here (with --ray or --address: N Ray "
        "workers, the 'scale' extra); the results do not depend on it",
    )
    parser.add_argument("--ray", action="store_true", help="split the episodes over Ray workers (local Ray)")
    parser.add_argument("--address", default=None, help="Ray cluster address (implies --ray)")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym eval`` to the ``navgym`` command's sub-parsers (:mod:`navgym.cli`)."""
    parser = subparsers.add_parser(
        "eval", help="evaluate policies on held-out episodes (paired, bootstrap CIs)"
    )
    add_arguments(parser)
    parser.set_defaults(_run=run)


def parse_env_kwargs(text: str) -> dict[str, Any]:
    """A JSON object, or ``key=value[,key=value...]`` (each value JSON where it parses, else a string).

    ``--env-kwargs`` of ``navgym eval`` and ``navgym tune``.

    Raises:
        ValueError: neither form.
    """
    if not text.lstrip().startswith("{") and "=" in text:
        pairs = [p.partition("=") for p in text.split(",")]
        if all(k.strip() and eq for k, eq, _ in pairs):
            return {k.strip(): _value(v.strip()) for k, _, v in pairs}
    try:
        value = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(
            f"--env-kwargs must be a JSON object or key=value pairs; {text!r} is neither ({e})"
        ) from None
    if not isinstance(value, dict):
        raise ValueError(f"--env-kwargs must be a JSON object or key=value pairs; got {text!r}")
    return value


_env_kwargs = parse_env_kwargs


def run(args: argparse.Namespace) -> int:
    """Run :func:`run_eval` from parsed arguments; print the markdown table.

    Expected errors (unknown env id, missing or unloadable model, bad policy spec or JSON)
    print ``navgym eval: error: <message>`` to stderr and return 2 (:mod:`agents.cli_errors`).
    """
    from agents.cli_errors import report_errors

    if args.ray or args.address is not None:
        from agents.scale.ray_runtime import MissingExtraError, report_missing, require_ray

        try:
            require_ray("navgym eval --ray")
        except MissingExtraError as exc:
            return report_missing("navgym eval --ray", exc)
    return report_errors("navgym eval", _run, args)


def _run(args: argparse.Namespace) -> int:
    out = args.out or str(Path("results") / "eval" / args.env.split("/")[-1])
    tuned: Any = False if args.no_tuned else (args.tuned or True)
    res = run_eval(
        args.env,
        args.policies,
        args.episodes,
        out,
        seed_offset=args.seed_offset,
        env_kwargs=_env_kwargs(args.env_kwargs),
        tuned=tuned,
        reference=args.reference,
        n_boot=args.bootstrap,
        boot_seed=args.boot_seed,
        plots=not args.no_plots,
        progress=not args.quiet,
        workers=args.workers,
        address=args.address,
        ray=args.ray,
        vecnormalize=args.vecnormalize,
        trust=args.trust,
        trace=args.trace,
    )
    print(results_table(res), end="")
    print(f"\nwrote {out}/")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m agents.evaluation --env ID ...``."""
    p = argparse.ArgumentParser(prog="python -m agents.evaluation", description=__doc__.splitlines()[0])
    add_arguments(p)
    return run(p.parse_args(argv))
