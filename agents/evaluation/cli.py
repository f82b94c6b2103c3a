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
from agents.evaluation.bootstrap import DEFAULT_LEVEL, DEFAULT_RESAMPLES
from agents.evaluation.report import results_table, write_outputs
from agents.evaluation.runner import EvalResults, evaluate
from agents.policy_runner import policy_kind
from agents.seeds import seeds as seed_range

__all__ = ["add_arguments", "parse_policies", "run", "run_eval"]

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
) -> dict[str, Any]:
    """``{label: policy or factory}`` from the policy specs of the module docstring."""
    import gymnasium as gym

    import navgym  # noqa: F401

    layout_env = gym.make(env_id, **dict(env_kwargs or {}))
    specs_by_name = baseline_specs(layout_env)  # the per-row Mixture (v2) has its own set
    tuned = dict(tuned or {})
    out: dict[str, Any] = {}
    for spec in specs:
        label, _, rest = spec.partition("=") if "=" in spec.split(":")[0] else ("", "", spec)
        head, _, tail = rest.partition(":")
        key = head.lower()
        if key in ("baselines", "all"):
            for name in specs_by_name:
                out[name] = make_baseline(layout_env, name, **tuned.get(name, {}))
        elif key == "oracle":
            base = {k: v for k, v in out.items() if policy_kind(v) == "baseline"}
            out[label or "oracle"] = functools.partial(_oracle, base=base)
        elif key == "greedy_oracle":
            out[label or "greedy_oracle"] = GreedyOracle
        elif key in SB3_ALGOS and tail:
            out[label or Path(tail).stem] = _load_sb3(key, tail)
        elif key in specs_by_name:
            params = dict(tuned.get(key, {}))
            if tail:
                for kv in tail.split(","):
                    k, _, v = kv.partition("=")
                    params[k.strip()] = _value(v.strip())
            out[label or (key if not tail else spec)] = make_baseline(layout_env, key, **params)
        else:
            raise ValueError(
                f"unknown policy spec {spec!r}: use 'baselines', 'oracle', one of {sorted(specs_by_name)}, "
                f"NAME:k=v,..., or [LABEL=]ALGO:PATH with ALGO in {SB3_ALGOS}"
            )
    layout_env.close()
    return out


def _load_sb3(algo: str, path: str) -> Any:
    """An SB3 model from ``path`` (a run folder or a zip, ``.zip`` optional).

    Algorithms :func:`~agents.training.loading.load_agent` knows load through it, so a saved
    ``vecnormalize.npz`` beside the model normalizes the observations as in training (and a bad
    file raises :class:`~agents.training.loading.AgentLoadError`); others load with SB3 as is.
    """
    from agents.training.config import ALGOS
    from agents.training.loading import load_agent

    p = Path(path)
    if not p.exists() and p.suffix != ".zip" and p.with_name(p.name + ".zip").is_file():
        p = p.with_name(p.name + ".zip")
    if algo in ALGOS:
        return load_agent(p, algo=algo)
    if not p.is_file():
        raise FileNotFoundError(f"no {algo.upper()} model at {path}")
    import stable_baselines3 as sb3

    # SB3_ALGOS without a navgym configuration
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
        workers: > 1 (or an ``address``): split the episodes over Ray workers
            (:func:`agents.scale.distributed_eval.distributed_evaluate`; same results bit for
            bit; needs the ``scale`` extra).
        address: Ray cluster address (``ray://head:10001``); ``None``: local Ray.

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
        pols = parse_policies(list(policies), env_id, env_kwargs, tuned_params)
        specs = baseline_specs(env_id)
        untuned = [n for n in pols if n in specs and specs[n].tunable and n not in tuned_params]
        if untuned:
            warnings.warn(f"no tuned parameters for {untuned}: class defaults used", stacklevel=2)
    seeds = seed_range("eval", episodes, seed_offset)
    if workers > 1 or address is not None:
        from agents.scale.distributed_eval import distributed_evaluate

        source: Any = pols
        if not isinstance(policies, Mapping):  # each worker loads its own copies from the specs
            source = functools.partial(parse_policies, list(policies), env_id, env_kwargs, tuned_params)
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
        write_outputs(results, out, plots=plots)
    return results


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``navgym eval`` (``--env ID --policies ... --episodes N --out DIR``)."""
    parser.add_argument("--env", required=True, help="env id, e.g. navgym/GpsInsFading-v0")
    parser.add_argument(
        "--policies", nargs="+", default=["baselines"], help="policy specs (see agents.evaluation.cli)"
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
    parser.add_argument("--quiet", action="store_true", help="no progress bars")
    parser.add_argument(
        "--workers", type=int, default=1, help="split the episodes over N Ray workers (the 'scale' extra)"
    )
    parser.add_argument("--address", default=None, help="Ray cluster address (default: local Ray)")


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``navgym eval`` to the ``navgym`` command's sub-parsers (:mod:`navgym.cli`)."""
    parser = subparsers.add_parser(
        "eval", help="evaluate policies on held-out episodes (paired, bootstrap CIs)"
    )
    add_arguments(parser)
    parser.set_defaults(_run=run)


def _env_kwargs(text: str) -> dict[str, Any]:
    """A JSON object, or ``key=value[,key=value...]`` (each value JSON where it parses, else a string)."""
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


def run(args: argparse.Namespace) -> int:
    """Run :func:`run_eval` from parsed arguments; print the markdown table.

    Expected errors (unknown env id, missing or unloadable model, bad policy spec or JSON)
    print ``navgym eval: error: <message>`` to stderr and return 2 (:mod:`agents.cli_errors`).
    """
    from agents.cli_errors import report_errors

    if args.workers > 1 or args.address is not None:
        from agents.scale.ray_runtime import MissingExtraError, report_missing, require_ray

        try:
            require_ray("navgym eval --workers")
        except MissingExtraError as exc:
            return report_missing("navgym eval --workers", exc)
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
    )
    print(results_table(res), end="")
    print(f"\nwrote {out}/")
    return 0


def main(argv: list[str] | None = None) -> int:
    """``python -m agents.evaluation --env ID ...``."""
    p = argparse.ArgumentParser(prog="python -m agents.evaluation", description=__doc__.splitlines()[0])
    add_arguments(p)
    return run(p.parse_args(argv))
