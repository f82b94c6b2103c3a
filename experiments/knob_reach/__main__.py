"""``python -m experiments.knob_reach [--env ID ...] [--tune-episodes 64] [--episodes 256] [--quick]``.

How far can a task's own knob go when it is told which events are active? The headroom gate
(:mod:`experiments.headroom`) compares the best tuned baseline with the **clairvoyant** filter,
which is told every step's true Q, R and measurement bias; a task's knob reaches only part of
that (a fading factor only inflates the predicted covariance; two scales multiply Q and R).
This study bounds the knob from below with a **regime oracle**: a table of actions indexed by
the regime active at each step, read from the episode's :class:`~navgym.scenarios.Scenario`
(truth; an oracle, never a baseline):

``a_k = A[r_k]``, ``r_k`` = the last of ``none, outage, canyon, jam, multipath, burst`` whose
event interval ``[start, end]`` holds ``t_{k+1} = (k + 1) dt`` (later entries win overlaps).

``A`` starts at the best constant action of a grid and is improved by one coordinate-descent
pass (regime by regime, action component by component, over the same grid), scored by the mean
episode RMSE on **tuning** seeds; the table found is then evaluated on held-out **evaluation**
seeds beside the best tuned classical baseline (the committed tuned file's best score) and the
plain filter, on the same episodes. ``reach = (RMSE_base - RMSE_regime) / RMSE_base`` with a
paired percentile-bootstrap 95 % CI over episodes.

What it says: if a regime oracle cannot beat the best tuned baseline by 10 %, a learned policy
that must infer the regime from innovations is unlikely to (it may still do better than the
table where the best action varies within a regime, as an adaptive rule does). What it does not
say: a coordinate-descent pass on a grid is not the optimum over tables, so ``reach`` is a
lower bound of what the regime-indexed knob can do.

Tasks: ``Fading`` and ``NoiseScale`` (one knob vector for all rows), and ``RowScale`` (v3) with
a per-row regime oracle read from the step's truth (:mod:`experiments.knob_reach.row_regimes`,
the reach gate G1). The per-row ``Mixture`` and ``Resample`` are not covered.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

import navgym  # noqa: F401  (registers the ids)
from agents.baselines import ConstantAction
from agents.baselines.registry import best_tuned, load_tuned, make_baseline, tuned_path
from agents.evaluation.bootstrap import DEFAULT_RESAMPLES, paired_difference
from agents.evaluation.cli import parse_env_kwargs
from agents.evaluation.metrics import episode_metrics
from agents.evaluation.runner import make_vector_env, rollout
from agents.reporting import markdown_table
from agents.seeds import seeds as seed_range
from experiments.knob_reach.row_regimes import row_study
from experiments.outputs import write_manifest
from navgym.envs.base import navigation_env
from navgym.envs.distinct import EpisodeCache
from navgym.scenarios import Scenario

#: Regimes in increasing precedence (a later one wins where events overlap).
REGIMES = ("none", "outage", "canyon", "jam", "multipath", "burst")
#: Scenario field of each event regime.
FIELDS = {
    "outage": "outages",
    "canyon": "canyons",
    "jam": "jamming",
    "multipath": "multipath",
    "burst": "bursts",
}
#: Action grids per task (actions in [-1, 1]): Fading's lambda = lambda_max ** ((a + 1) / 2);
#: NoiseScale's scales 10 ** (-1 + 1.5 (a + 1)) in half decades from 0.1 to 100 (the default
#: range; other ranges: :func:`action_grid`).
GRIDS = {
    "Fading": (-1.0, -0.9, -0.8, -0.6, -0.4, 0.0, 0.5, 1.0),
    "NoiseScale": (-1.0, -2 / 3, -1 / 3, 0.0, 1 / 3, 2 / 3, 1.0),
}
#: Tasks by their ``task=`` keyword (``--env-kwargs task=noisescale`` on a v3 id).
TASK_TITLES = {"fading": "Fading", "noisescale": "NoiseScale", "rowscale": "RowScale"}
#: The ids studied by default (the v2 Fading and NoiseScale ids).
DEFAULT_ENVS = (
    "navgym/GpsInsFading-v2",
    "navgym/GpsInsNoiseScale-v2",
    "navgym/QuadrotorFading-v2",
    "navgym/QuadrotorNoiseScale-v2",
    "navgym/Robot2dFading-v2",
    "navgym/Robot2dNoiseScale-v2",
)
OUT = Path("results/knob_reach")


def task_of(env_id: str, env_kwargs: Mapping[str, Any] | None = None) -> str:
    """``Fading``, ``NoiseScale`` or ``RowScale``: ``env_kwargs["task"]``, else from the id.

    Raises:
        ValueError: another task.
    """
    task = (env_kwargs or {}).get("task")
    if task is not None:
        if task not in TASK_TITLES:
            raise ValueError(f"env_kwargs task={task!r}: the regime oracle covers {sorted(TASK_TITLES)}")
        return TASK_TITLES[task]
    for task in (*GRIDS, "RowScale"):
        if task in env_id:
            return task
    raise ValueError(
        f"env_id={env_id!r}: the regime oracle covers the Fading, NoiseScale and RowScale ids only"
    )


def regime_codes(scenarios: Sequence[Scenario], times: np.ndarray) -> np.ndarray:
    """``(B, T)`` index into :data:`REGIMES` of the regime active at each time (module docstring)."""
    codes = np.zeros((len(scenarios), times.size), dtype=np.int64)
    for i, sc in enumerate(scenarios):
        for code, name in enumerate(REGIMES):
            for ev in () if name == "none" else getattr(sc, FIELDS[name]):
                codes[i, (times >= ev.start) & (times <= ev.end)] = code
    return codes


class RegimeOracle:
    """SB3-style policy playing ``table[r_k]`` (module docstring); reads the episodes' scenarios.

    ``codes`` are the ``(B, T)`` regime codes of fixed episodes (:attr:`Scorer.codes`); it must be
    rolled out on exactly those episodes, one per sub-env, from step 0.
    """

    def __init__(self, codes: np.ndarray, table: np.ndarray) -> None:
        self.codes = np.asarray(codes)
        self.table = np.asarray(table, dtype=np.float32)
        self._k = 0

    def predict(
        self,
        obs: np.ndarray,
        state: Any = None,
        episode_start: np.ndarray | None = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, None]:
        if episode_start is not None and np.all(episode_start):
            self._k = 0
        k = min(self._k, self.codes.shape[1] - 1)
        self._k += 1
        return self.table[self.codes[:, k]], None


class Scorer:
    """Mean episode RMSE of a policy on fixed seeds, one vector env reused (episodes simulated once)."""

    def __init__(
        self, env_id: str, seeds: Sequence[int], env_kwargs: Mapping[str, Any] | None = None
    ) -> None:
        self.seeds = [int(s) for s in seeds]
        self.cache = EpisodeCache(maxsize=1)
        self.env = make_vector_env(env_id, len(self.seeds), dict(env_kwargs or {}))
        nav = navigation_env(self.env)
        self.divergence_m = float(nav.platform.divergence_m)
        _, info = self.env.reset(seed=self.seeds)
        #: (B, T) regime code of every step of the episodes (their scenarios from ``reset``).
        self.codes = regime_codes(
            list(info["scenario"]), (np.arange(nav.horizon) + 1) * float(nav.platform.dt)
        )

    def episodes(self, policy: Any) -> np.ndarray:
        """Per-episode RMSE [m]."""
        with self.cache.active():
            roll = rollout(self.env, policy, self.seeds)
        return episode_metrics(roll, self.divergence_m)["rmse_m"]

    def __call__(self, policy: Any) -> float:
        return float(np.mean(self.episodes(policy)))


def action_grid(task: str, nav: Any) -> tuple[float, ...]:
    """The action grid of ``task`` on the env ``nav`` (:data:`GRIDS`; NoiseScale from its ranges).

    NoiseScale: the scales ``10 ** e`` for ``e`` from ``log10 s_lo`` to ``log10 s_hi`` in half
    decades where the range spans at most 3 decades (the default 0.1 to 100: :data:`GRIDS`), in
    whole decades where it is wider (0.1 to 1e4: 0.1, 1, ..., 1e4), as actions
    ``a = -1 + 2 (e - lo) / (hi - lo)`` of the wider of the two scales' ranges.
    """
    if task != "NoiseScale":
        return GRIDS[task]
    lo = float(np.min(nav.task.log_low))
    hi = float(np.max(nav.task.log_high))
    step = 0.5 if hi - lo <= 3.0 + 1e-9 else 1.0
    e = np.arange(np.ceil(lo / step) * step, hi + step / 2, step)
    return tuple(float(v) for v in -1.0 + 2.0 * (e - lo) / (hi - lo))


def search_table(
    env_id: str, seeds: Sequence[int], progress: bool = True, env_kwargs: Mapping[str, Any] | None = None
) -> tuple[np.ndarray, float, np.ndarray, float]:
    """Best constant action on the grid, then one coordinate-descent pass over the regime table.

    Returns ``(constant, its mean RMSE, table, its mean RMSE)`` on ``seeds``.
    """
    score = Scorer(env_id, seeds, env_kwargs)
    grid = action_grid(task_of(env_id, env_kwargs), navigation_env(score.env))
    codes = score.codes  # the tuning episodes' regimes, shared by every table tried
    dim = int(np.prod(score.env.single_action_space.shape))
    constants = [np.array(c) for c in np.array(np.meshgrid(*[grid] * dim)).reshape(dim, -1).T]
    bar = tqdm(
        total=len(constants) + len(REGIMES) * dim * len(grid),
        desc=env_id.split("/")[-1],
        disable=not progress,
    )
    best_c, best = constants[0], np.inf
    for c in constants:
        r = score(RegimeOracle(codes, np.tile(c, (len(REGIMES), 1))))
        bar.update()
        if r < best:
            best_c, best = c, r
    table, best_t = np.tile(best_c, (len(REGIMES), 1)).astype(np.float64), best
    for ri in range(len(REGIMES)):
        for d in range(dim):
            for v in grid:
                trial = table.copy()
                trial[ri, d] = v
                r = score(RegimeOracle(codes, trial))
                bar.update()
                if r < best_t - 1e-12:
                    table, best_t = trial, r
    bar.close()
    score.env.close()
    return best_c, best, table, best_t


def study(
    env_id: str,
    tune_episodes: int,
    episodes: int,
    n_boot: int = DEFAULT_RESAMPLES,
    progress: bool = True,
    env_kwargs: Mapping[str, Any] | None = None,
    tuned_dir: Path | None = None,
) -> dict[str, Any]:
    """Search the table on tuning seeds; evaluate it, the best tuned baseline and plain on held-out seeds.

    The baseline is the best of the tuned file of ``env_id`` in ``tuned_dir`` (default: the
    shipped ``agents/baselines/tuned``), tuned with the same ``env_kwargs``.
    """
    tuned = None if tuned_dir is None else tuned_path(env_id, tuned_dir)
    t0 = time.perf_counter()
    const, const_tune, table, table_tune = search_table(
        env_id, seed_range("tune", tune_episodes), progress, env_kwargs
    )
    eval_seeds = seed_range("eval", episodes)
    score = Scorer(env_id, eval_seeds, env_kwargs)
    base_name, _ = best_tuned(env_id, tuned)
    base = make_baseline(score.env, base_name, **load_tuned(env_id, tuned).get(base_name, {}))
    space = score.env.single_action_space
    plain = ConstantAction(space, navigation_env(score.env).task.neutral_action(), "plain")
    rm = {
        "plain": score.episodes(plain),
        base_name: score.episodes(base),
        "regime oracle": score.episodes(RegimeOracle(score.codes, table)),
    }
    score.env.close()
    d = paired_difference(rm[base_name], rm["regime oracle"], n_boot=n_boot)
    b = float(np.mean(rm[base_name]))
    return {
        "env_id": env_id,
        "env_kwargs": dict(env_kwargs or {}),
        "best_tuned": base_name,
        "constant_action": const.tolist(),
        "constant_tune_rmse_m": const_tune,
        "table": {r: table[i].tolist() for i, r in enumerate(REGIMES)},
        "table_tune_rmse_m": table_tune,
        "eval_rmse_m": {k: float(np.mean(v)) for k, v in rm.items()},
        "reach": float(d["mean_diff"]) / b,
        "reach_low": float(d["low"]) / b,
        "reach_high": float(d["high"]) / b,
        "tune_episodes": tune_episodes,
        "episodes": episodes,
        "seconds": time.perf_counter() - t0,
    }


def table_rows(results: Sequence[dict[str, Any]]) -> list[dict[str, str]]:
    """One markdown row per id."""
    rows = []
    for r in results:
        e = r["eval_rmse_m"]
        row = {
            "id": f"`{r['env_id'].split('/')[-1]}`",
            "plain m": f"{e['plain']:.3f}",
            "best tuned baseline": f"{r['best_tuned']} {e[r['best_tuned']]:.3f}",
            "regime oracle m": f"{e['regime oracle']:.3f}",
            "reach % [95% CI]": (
                f"{100 * r['reach']:.1f} [{100 * r['reach_low']:.1f}, {100 * r['reach_high']:.1f}]"
            ),
        }
        if "g1" in r:  # the RowScale ids' gate (experiments.knob_reach.row_regimes)
            row["G1 (>= 25 %)"] = "pass" if r["g1"] else "miss"
            row["table"] = ", ".join(f"{k} {v:g}" for k, v in r["table"].items())
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.knob_reach", description=__doc__.split("\n\n")[1])
    p.add_argument(
        "--env", nargs="+", default=list(DEFAULT_ENVS), help="Fading / NoiseScale / RowScale env ids"
    )
    p.add_argument("--tune-episodes", type=int, default=64, help="tuning episodes of the table search")
    p.add_argument("--episodes", type=int, default=256, help="held-out evaluation episodes")
    p.add_argument("--quick", action="store_true", help="8 tuning and 16 held-out episodes")
    p.add_argument(
        "--env-kwargs",
        default="{}",
        help="env keyword arguments (JSON or key=value[,key=value]), e.g. task=noisescale on a v3 id",
    )
    p.add_argument(
        "--tuned",
        type=Path,
        default=None,
        help="folder of the tuned baselines (navgym tune --out) for --env-kwargs",
    )
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument("--quiet", action="store_true")
    a = p.parse_args(argv)
    kwargs = parse_env_kwargs(a.env_kwargs)
    for env_id in a.env:
        task_of(env_id, kwargs)
    tune_n, n = (8, 16) if a.quick else (a.tune_episodes, a.episodes)
    results = []
    for env_id in a.env:
        if task_of(env_id, kwargs) == "RowScale":
            if a.tuned is not None:
                p.error("--tuned goes with the Fading and NoiseScale studies")
            r = row_study(env_id, tune_n, n, progress=not a.quiet, env_kwargs=kwargs)
        else:
            r = study(env_id, tune_n, n, progress=not a.quiet, env_kwargs=kwargs, tuned_dir=a.tuned)
        results.append(r)
        print(markdown_table(table_rows([r])), flush=True)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "results.json").write_text(json.dumps(results, indent=1))
    (a.out / "table.md").write_text(markdown_table(table_rows(results)))
    write_manifest(a.out, "experiments.knob_reach", argv, tune_episodes=tune_n, episodes=n)
    print(markdown_table(table_rows(results)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
