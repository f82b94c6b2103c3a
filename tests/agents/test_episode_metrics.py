"""The array form of ``episode_metrics`` equals the per-episode definitions of its docstring.

The reference below is the metrics' definition written episode by episode (the loop the array
passes replaced); random rollouts with every length from 0 to T, non-finite errors, outages at
both ends, negative and infinite NEES, NaN knobs and resampling flags.
"""

from __future__ import annotations

import numpy as np
import pytest

from agents.evaluation.metrics import METRICS, episode_metrics, outage_runs
from agents.evaluation.runner import Rollout

DIVERGENCE_M = 500.0


def _reference(roll: Rollout, divergence_m: float) -> dict[str, np.ndarray]:
    alive, B = roll.alive, roll.alive.shape[0]
    err = np.where(np.isfinite(roll.steps["pos_err_m"]), roll.steps["pos_err_m"], divergence_m)
    err = np.where(alive, err, np.nan)
    extra = roll.steps.get("extra_err")
    scored = err if extra is None else err + np.where(np.isfinite(extra), extra, 0.0)
    out = {m: np.full(B, np.nan) for m in METRICS}
    out["return"] = np.where(alive, roll.steps["reward"], 0.0).sum(axis=1)
    out["length"] = roll.length.astype(np.float64)
    out["diverged"] = roll.terminated.astype(np.float64)
    for i in range(B):
        n = int(roll.length[i])
        if n == 0:
            continue
        e = err[i, :n]
        out["rmse_m"][i] = np.sqrt(np.mean(e**2))
        out["scored_rmse_m"][i] = np.sqrt(np.mean(scored[i, :n] ** 2))
        out["p95_err_m"][i] = np.percentile(e, 95)
        out["max_err_m"][i] = e.max()
        no = ~roll.steps["gnss_available"][i, :n].astype(bool)
        runs = outage_runs(no)
        out["n_outages"][i] = len(runs)
        if runs:
            out["outage_mean_err_m"][i] = e[no].mean()
            out["outage_end_err_m"][i] = np.mean([e[b - 1] for _, b in runs])
        v = roll.steps["nees"][i, :n]
        v = v[np.isfinite(v) & (v >= 0)]
        if v.size:
            out["mean_nees"][i] = v.mean()
        k = roll.steps["knob"][i, :n].astype(np.float64)
        out["mean_knob"][i] = np.nanmean(k) if np.isfinite(k).any() else np.nan
        out["resamples"][i] = float(np.asarray(roll.steps["resampled"][i, :n], dtype=bool).sum())
    return out


def _rollout(seed: int, B: int = 64, T: int = 37, extra: bool = False) -> Rollout:
    rng = np.random.default_rng(seed)
    length = rng.integers(0, T + 1, B)
    length[:3] = [0, 1, T]
    length[5:9] = np.maximum(length[5:9], 5)
    alive = np.arange(T)[None, :] < length[:, None]
    err = rng.gamma(2.0, 3.0, (B, T))
    err[rng.random((B, T)) < 0.02] = np.inf
    err[rng.random((B, T)) < 0.02] = np.nan
    nees = rng.gamma(3.0, 1.0, (B, T))
    nees[rng.random((B, T)) < 0.05] = -1.0
    nees[rng.random((B, T)) < 0.05] = np.inf
    nees[5] = -1.0  # no usable NEES in this episode
    knob = rng.uniform(0.5, 2.0, (B, T))
    knob[rng.random((B, T)) < 0.1] = np.nan
    knob[6] = np.nan
    gnss = rng.random((B, T)) < 0.7
    gnss[7] = False  # one outage over the whole episode
    gnss[8] = True  # none
    steps = {
        "reward": np.where(alive, -err / 10, 0.0),
        "pos_err_m": np.where(alive, err, np.nan),
        "nees": np.where(alive, nees, np.nan),
        "knob": np.where(alive, knob, np.nan),
        "gnss_available": gnss & alive,
        "resampled": (rng.random((B, T)) < 0.3) & alive,
    }
    if extra:
        steps["extra_err"] = np.where(alive, rng.gamma(1.0, 1.0, (B, T)), np.nan)
    return Rollout(steps, alive, length, rng.random(B) < 0.2, 1.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("extra", [False, True])
def test_the_array_metrics_equal_the_per_episode_definitions(seed, extra):
    roll = _rollout(seed, extra=extra)
    got, ref = episode_metrics(roll, DIVERGENCE_M), _reference(roll, DIVERGENCE_M)
    assert set(got) == set(ref) == set(METRICS)
    for m in METRICS:
        np.testing.assert_allclose(got[m], ref[m], rtol=1e-12, atol=1e-12, err_msg=m)
    assert np.isnan(got["rmse_m"][0]) and np.isnan(got["n_outages"][0])  # the empty episode
    assert got["n_outages"][7] == 1 and got["n_outages"][8] == 0
    assert np.isnan(got["mean_nees"][5]) and np.isnan(got["mean_knob"][6])
