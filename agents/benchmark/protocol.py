"""The benchmark protocol: every policy of an id on the same held-out episodes, against the bar.

For each env id, on the fixed evaluation seeds ``agents.seeds.seeds("eval", episodes)`` (never
used for training or tuning; one native vector env, sub-env ``i`` reset with seed ``i``, so every
row is paired with every other by episode):

1. the **plain** filter (the task's ``plain`` baseline, else its neutral action);
2. **every** classical baseline of the id with its tuned parameters
   (:func:`agents.baselines.registry.make_baseline`, :func:`~agents.baselines.registry.load_tuned`);
3. the **bar**: the best tuned baseline, :func:`~agents.baselines.registry.best_tuned` (the
   highest tuning score, on tuning seeds: fixed before any held-out episode is run);
4. the **agents** of the id (:mod:`agents.benchmark.agent_specs`), each training seed apart;
5. the upper **references** the id has (:mod:`agents.benchmark.references`), on the same seeds.

Per (id, policy) a leaderboard row: the mean episode RMSE [m] (percentile bootstrap CI over
episodes), the mean return, the divergence rate and ``ΔRMSE % = 100 mean(policy - bar) /
mean(bar)`` with its paired bootstrap CI (:func:`agents.evaluation.comparison.delta_rmse`). An
agent given as several training seeds also gets an aggregate row: the seed-mean policy's paired
CI over episodes, and across the seeds the mean and IQM of the per-seed ΔRMSE % and RMSE with
stratified-bootstrap CIs (:mod:`agents.benchmark.aggregate`, Agarwal et al. 2021). A label used
for agents of several ids gets an across-ids aggregate too (the strata: the ids).
"""

from __future__ import annotations

import time
import zlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from agents.benchmark.agent_specs import AgentSpec, parse_agent
from agents.benchmark.aggregate import SEED_RESAMPLES, across_seeds
from agents.benchmark.references import neutral_policy, reference_policies
from agents.evaluation.bootstrap import DEFAULT_LEVEL, DEFAULT_RESAMPLES, bootstrap_mean_ci
from agents.evaluation.comparison import delta_rmse

__all__ = [
    "DEFAULT_EPISODES",
    "QUICK_EPISODES",
    "IdResult",
    "Leaderboard",
    "evaluate_id",
    "normalize_id",
    "run_protocol",
]

#: Held-out episodes per id of the standard protocol, and of ``--quick`` (tests, smoke runs).
DEFAULT_EPISODES = 500
QUICK_EPISODES = 16
#: Per-episode metrics the leaderboard keeps.
KEPT = ("rmse_m", "return", "diverged")
PLAIN = "plain"


@dataclass
class IdResult:
    """The per-episode metrics of every policy of one id, on the same seeds.

    Attributes:
        env_id, seeds: the episodes.
        bar, bar_score: the best tuned baseline and its tuning score.
        roles: ``{label: role}`` (``plain``, ``baseline``, ``bar``, ``agent``, ``seed``,
            ``reference``), in leaderboard order.
        episodes: ``{label: {metric: (n,) array}}`` for the metrics of :data:`KEPT`.
        agents: ``{agent label: [policy labels of its seeds]}``.
        references: the references run (their env kwargs and table source).
        skipped: ``{reference: why it was not run}``.
        notes: what a reader must know (untuned baselines, non-standard kwargs).
        wall_s: seconds of the id's rollouts.
    """

    env_id: str
    seeds: list[int]
    bar: str
    bar_score: float
    roles: dict[str, str] = field(default_factory=dict)
    episodes: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    agents: dict[str, list[str]] = field(default_factory=dict)
    references: dict[str, dict[str, Any]] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    wall_s: float = 0.0


@dataclass
class Leaderboard:
    """The result of :func:`run_protocol`: the rows and what they were computed from."""

    rows: list[dict[str, Any]]
    across_ids: list[dict[str, Any]]
    results: dict[str, IdResult]
    agents: list[AgentSpec]
    config: dict[str, Any]
    notes: list[str]


def normalize_id(env_id: str) -> str:
    """``env_id`` with the ``navgym/`` namespace added when it has none."""
    return env_id if "/" in env_id or ":" in env_id else f"navgym/{env_id}"


def _boot_seed(boot_seed: int, *parts: str) -> int:
    """A bootstrap seed stable under the choice of the other policies (a hash of the row's names)."""
    return boot_seed + zlib.crc32("|".join(parts).encode()) % (1 << 30)


def _check_spaces(spec: AgentSpec, env: Any) -> None:
    for folder, agent in spec.loaded.items():
        for what in ("observation_space", "action_space"):
            mine, theirs = getattr(agent, what, None), getattr(env, what)
            if mine is not None and getattr(mine, "shape", None) != getattr(theirs, "shape", None):
                raise ValueError(
                    f"agent {spec.label!r} ({folder}): its {what} {mine} is not the env's {theirs} "
                    f"({spec.env_id} with the benchmark's env kwargs)"
                )


def evaluate_id(
    env_id: str,
    agents: Sequence[AgentSpec],
    seeds: Sequence[int],
    env_kwargs: Mapping[str, Any] | None = None,
    *,
    references: bool = True,
    progress: bool = True,
) -> IdResult:
    """Run the plain filter, every tuned baseline, ``agents`` and the references of ``env_id`` on ``seeds``.

    Raises:
        FileNotFoundError: ``env_id`` has no tuned baselines (no bar).
        ValueError: two policies with one label, an agent whose spaces are not the env's.
    """
    import gymnasium as gym

    from agents.baselines.registry import baseline_specs, best_tuned, load_tuned, make_baseline
    from agents.evaluation.runner import run_policies

    kwargs = dict(env_kwargs or {})
    bar, bar_score = best_tuned(env_id)
    tuned = load_tuned(env_id)
    layout = gym.make(env_id, **kwargs)
    try:
        specs = baseline_specs(layout)
        for spec in agents:
            _check_spaces(spec, layout)
    finally:
        layout.close()
    if bar not in specs:
        raise ValueError(
            f"the bar {bar!r} of {env_id}'s tuned file is not among its baselines {sorted(specs)}"
        )
    res = IdResult(env_id, [int(s) for s in seeds], bar, bar_score)
    pols: dict[str, Any] = {}

    def put(label: str, role: str, policy: Any) -> None:
        if label in pols or label in res.roles:
            raise ValueError(f"{env_id}: label {label!r} is given twice; name the agent with LABEL=PATH")
        pols[label], res.roles[label] = policy, role

    if PLAIN not in specs:
        put(PLAIN, "plain", neutral_policy)
    for name in specs:
        role = "bar" if name == bar else ("plain" if name == PLAIN else "baseline")
        put(name, role, lambda env, n=name: make_baseline(env, n, **tuned.get(n, {})))
    untuned = [n for n, s in specs.items() if s.tunable and n not in tuned]
    if untuned:
        res.notes.append(f"{env_id}: no tuned parameters for {untuned}; class defaults used")
    if tuned and kwargs:
        res.notes.append(f"{env_id}: the baselines were tuned with the default env kwargs, not {kwargs}")
    for spec in agents:
        labels = []
        for seed_name, folder in spec.seeds:
            label = spec.policy_label(seed_name)
            put(label, "seed" if seed_name else "agent", spec.factory(folder))
            labels.append(label)
        res.agents[spec.label] = labels
        for who, kw in spec.train_env_kwargs.items():
            res.notes.append(
                f"{env_id}: agent {spec.label!r} ({who}) was trained with env kwargs {kw}; "
                f"evaluated on the benchmark's ({kwargs or 'the defaults'})"
            )
    refs, res.skipped = reference_policies(env_id, kwargs) if references else ({}, {})
    for label in refs:
        if label in res.roles:
            raise ValueError(f"{env_id}: label {label!r} is the reference's; name the agent with LABEL=PATH")
    t0 = time.perf_counter()
    _, eps, _, _ = run_policies(env_id, pols, res.seeds, kwargs, progress=progress)
    for label, ref in refs.items():
        _, e, _, _ = run_policies(
            env_id, {label: neutral_policy}, res.seeds, ref["env_kwargs"], progress=progress
        )
        eps.update(e)
        res.roles[label] = "reference"
    res.wall_s = time.perf_counter() - t0
    res.references = refs
    res.episodes = {k: {m: np.asarray(eps[k][m], dtype=np.float64) for m in KEPT} for k in res.roles}
    return res


def _row(
    res: IdResult, label: str, rmse: np.ndarray, n_boot: int, level: float, boot_seed: int
) -> dict[str, Any]:
    """RMSE (CI over episodes) and ΔRMSE % against the bar (paired CI) of per-episode ``rmse``."""
    s = _boot_seed(boot_seed, res.env_id, label)
    m, lo, hi, n = bootstrap_mean_ci(rmse, n_boot, level, seed=s)
    row: dict[str, Any] = {
        "id": res.env_id,
        "policy": label,
        "n": n,
        "rmse_m": m,
        "rmse_low": lo,
        "rmse_high": hi,
    }
    if label == res.bar:
        row.update({"delta_pct": 0.0, "delta_low": 0.0, "delta_high": 0.0, "delta_m": 0.0})
        return row
    d = delta_rmse(rmse, res.episodes[res.bar]["rmse_m"], n_boot, level, seed=s + 1)
    if d["n"] != len(res.seeds):
        raise ValueError(f"{res.env_id}: {label}'s ΔRMSE is paired on {d['n']} of {len(res.seeds)} episodes")
    row.update(
        {
            "delta_pct": d["delta_pct"],
            "delta_low": d["low_pct"],
            "delta_high": d["high_pct"],
            "delta_m": d["delta_m"],
            "ci_excludes_0": bool(d["high_pct"] < 0 or d["low_pct"] > 0),
        }
    )
    return row


def id_rows(
    res: IdResult,
    n_boot: int = DEFAULT_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    boot_seed: int = 0,
    seed_reps: int = SEED_RESAMPLES,
) -> list[dict[str, Any]]:
    """The leaderboard rows of one id, in order (module docstring); seed rows before their aggregate."""
    seed_of = {lab: (agent, lab.partition("/")[2]) for agent, labs in res.agents.items() for lab in labs}
    rows = []
    for label, role in res.roles.items():
        e = res.episodes[label]
        row = _row(res, label, e["rmse_m"], n_boot, level, boot_seed)
        row.update(
            {"role": role, "return": float(np.mean(e["return"])), "diverged": float(np.mean(e["diverged"]))}
        )
        if label in seed_of:
            row.update({"agent": seed_of[label][0], "seed": seed_of[label][1] or None})
        rows.append(row)
        agent = seed_of.get(label, (None, ""))[0]
        if role == "seed" and agent is not None and label == res.agents[agent][-1]:
            rows.append(_seeds_row(res, agent, rows, n_boot, level, boot_seed, seed_reps))
    return rows


def _seeds_row(
    res: IdResult,
    agent: str,
    rows: Sequence[Mapping[str, Any]],
    n_boot: int,
    level: float,
    boot_seed: int,
    seed_reps: int,
) -> dict[str, Any]:
    """The aggregate row of a multi-seed agent: the seed-mean policy, and across-seed IQM / mean CIs."""
    labels = res.agents[agent]
    per = [r for r in rows if r["policy"] in labels]
    rmse = np.mean([res.episodes[lab]["rmse_m"] for lab in labels], axis=0)
    row = _row(res, agent, rmse, n_boot, level, boot_seed)
    s = _boot_seed(boot_seed, res.env_id, agent, "seeds")
    row.update(
        {
            "role": f"mean of {len(labels)} seeds",
            "agent": agent,
            "seeds": [lab.partition("/")[2] for lab in labels],
            "return": float(np.mean([r["return"] for r in per])),
            "diverged": float(np.mean([r["diverged"] for r in per])),
            "across_seeds": {
                "delta_pct": across_seeds(np.array([r["delta_pct"] for r in per]), seed_reps, level, s),
                "rmse_m": across_seeds(np.array([r["rmse_m"] for r in per]), seed_reps, level, s + 2),
            },
        }
    )
    return row


def across_ids(
    rows: Sequence[Mapping[str, Any]],
    level: float = DEFAULT_LEVEL,
    boot_seed: int = 0,
    seed_reps: int = SEED_RESAMPLES,
) -> list[dict[str, Any]]:
    """Per agent label used on two ids or more: mean and IQM of ΔRMSE % over every (id, seed) run.

    The stratified bootstrap resamples the training seeds within each id (rliable's strata are
    the tasks); an agent with one seed per id has a zero-width CI (no seed variation measured).
    """
    runs: dict[str, dict[str, list[float]]] = {}
    for r in rows:
        if r.get("role") in ("agent", "seed"):
            runs.setdefault(r["agent"], {}).setdefault(r["id"], []).append(float(r["delta_pct"]))
    out = []
    for agent, by_id in runs.items():
        if len(by_id) < 2:
            continue
        stats = across_seeds(list(by_id.values()), seed_reps, level, _boot_seed(boot_seed, agent, "ids"))
        out.append(
            {"agent": agent, "ids": list(by_id), "runs": {k: len(v) for k, v in by_id.items()}, **stats}
        )
    return out


def run_protocol(
    agents: Sequence[str | AgentSpec] = (),
    ids: Sequence[str] | None = None,
    episodes: int = DEFAULT_EPISODES,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    n_boot: int = DEFAULT_RESAMPLES,
    seed_reps: int = SEED_RESAMPLES,
    level: float = DEFAULT_LEVEL,
    boot_seed: int = 0,
    references: bool = True,
    progress: bool = True,
) -> Leaderboard:
    """The protocol of the module docstring on ``ids`` (default: the agents' ids).

    Args:
        agents: AGENT arguments (``[LABEL=]PATH``) or parsed :class:`AgentSpec`.
        ids: the env ids (``navgym/`` may be left out); agents of other ids are left out (a
            note says so); ids without an agent get the baselines and references only.
        episodes: held-out episodes per id (the evaluation seeds from 0).
        env_kwargs: env kwargs of every run (default none: the standard protocol).
        n_boot: bootstrap resamples over episodes.
        seed_reps: bootstrap resamples over training seeds.
        level: confidence level.
        boot_seed: offset of the bootstrap seeds.
        references: run the upper references.
        progress: tqdm bars.

    Raises:
        ValueError: no agent and no id, a bad agent folder, two agents with one label on an id.
        FileNotFoundError: a missing agent folder or tuned file (each message names it).
    """
    import gymnasium as gym
    from tqdm.auto import tqdm

    import navgym  # noqa: F401  (registers the ids)
    from agents.baselines.registry import best_tuned
    from agents.seeds import seeds as seed_range
    from navgym.envs.registration import superseded_ids_quiet

    if episodes < 1:
        raise ValueError(f"episodes must be >= 1; got {episodes}")
    specs = [a if isinstance(a, AgentSpec) else parse_agent(a) for a in agents]
    run_ids = [normalize_id(i) for i in ids] if ids else list(dict.fromkeys(s.env_id for s in specs))
    run_ids = list(dict.fromkeys(run_ids))
    if not run_ids:
        raise ValueError("nothing to benchmark: give at least one AGENT or --ids ID")
    notes = [
        f"agent {s.label!r} ({s.env_id}) is not run: its id is not among --ids"
        for s in specs
        if s.env_id not in run_ids
    ]
    seen: dict[tuple[str, str], str] = {}
    for s in specs:
        key = (s.env_id, s.label)
        if key in seen:
            raise ValueError(
                f"two agents of {s.env_id} have the label {s.label!r} ({seen[key]} and {s.path}); "
                "name them with LABEL=PATH"
            )
        seen[key] = str(s.path)
    seeds = seed_range("eval", episodes)
    kwargs = dict(env_kwargs or {})
    results: dict[str, IdResult] = {}
    rows: list[dict[str, Any]] = []
    with superseded_ids_quiet():
        for env_id in run_ids:  # fail before the first rollout: an unknown id, no bar
            gym.spec(env_id)
            best_tuned(env_id)
        bar = tqdm(run_ids, desc="benchmark", disable=None if progress else True)
        for env_id in bar:
            bar.set_postfix_str(env_id.split("/")[-1])
            mine = [s for s in specs if s.env_id == env_id]
            res = evaluate_id(env_id, mine, seeds, kwargs, references=references, progress=progress)
            results[env_id] = res
            rows += id_rows(res, n_boot, level, boot_seed, seed_reps)
            notes += res.notes
    config = {
        "episodes": episodes,
        "seeds": {"kind": "eval", "n": episodes, "first": seeds[0], "last": seeds[-1]},
        "env_kwargs": kwargs,
        "n_boot": n_boot,
        "seed_reps": seed_reps,
        "level": level,
        "boot_seed": boot_seed,
        "references": references,
    }
    return Leaderboard(rows, across_ids(rows, level, boot_seed, seed_reps), results, specs, config, notes)
