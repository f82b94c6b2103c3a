"""Gate G2: the supervised policy against the plain filter and the best tuned baseline, held out.

Every policy runs on the same held-out **evaluation** episodes (:func:`agents.evaluation.runner.
run_policies`; paired by seed): the plain filter, the best tuned baseline of the env
(:func:`agents.baselines.registry.best_tuned`, on tuning seeds; absent when the env has no
tuned file yet), the supervised policy, and the regime oracle with the same table (reads truth:
the reference the policy imitates, never a baseline). Per policy the mean episode RMSE with its
percentile bootstrap 95 % CI, and the paired difference ``reference - policy`` (the reference:
the best tuned baseline, else plain) with its CI (:func:`agents.evaluation.bootstrap.paired_difference`).

**Gate G2**: the supervised policy's RMSE at least :data:`G2_MARGIN` (10 %) below the best tuned
baseline's, with the paired 95 % CI of the difference excluding 0.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from agents.baselines import ConstantAction
from agents.baselines.registry import best_tuned, load_tuned, make_baseline
from agents.evaluation.bootstrap import DEFAULT_RESAMPLES, bootstrap_mean_ci, paired_difference
from agents.evaluation.runner import run_policies
from agents.seeds import check_seeds
from navgym.envs.base import navigation_env

__all__ = ["G2_MARGIN", "compare", "markdown_table"]

#: The gate's margin: the supervised RMSE at least this far below the best tuned baseline's.
G2_MARGIN = 0.10
SUPERVISED = "supervised"
ORACLE = "regime oracle (truth)"


def _neutral(env: Any) -> ConstantAction:
    return ConstantAction(env.single_action_space, navigation_env(env).task.neutral_action(), ORACLE)


def compare(
    env_id: str,
    policy: Callable[[Any], Any],
    table: Sequence[float],
    seeds: Sequence[int],
    env_kwargs: Mapping[str, Any] | None = None,
    tuned_file: str | Path | None = None,
    n_boot: int = DEFAULT_RESAMPLES,
    kind: str = "eval",
) -> dict[str, Any]:
    """Evaluate plain, the best tuned baseline, ``policy`` (a factory of the env) and the oracle on ``seeds``.

    ``kind``: the seeds' range, ``"eval"`` (gate G2) or ``"tune"`` (choosing a configuration).
    Returns ``{"episodes": {name: rmse (B,)}, "rows": [...], "reference", "g2", ...}``.
    """
    if kind not in ("eval", "tune"):
        raise ValueError(f"kind must be 'eval' or 'tune'; got {kind!r}")
    seeds = [int(s) for s in seeds]
    check_seeds(kind, seeds)
    kwargs = dict(env_kwargs or {})
    pols: dict[str, Any] = {"plain": lambda env: make_baseline(env, "plain")}
    base = None
    try:
        base, _ = best_tuned(env_id, tuned_file)
    except FileNotFoundError:
        base = None
    if base is not None:
        params = load_tuned(env_id, tuned_file).get(base, {})
        pols[f"{base} (best tuned)"] = lambda env: make_baseline(env, base, **params)
    pols[SUPERVISED] = policy
    _, eps, _, _ = run_policies(env_id, pols, seeds, kwargs, progress=False)
    extra = {"regime_oracle": tuple(float(v) for v in table)}
    _, eps_o, _, _ = run_policies(env_id, {ORACLE: _neutral}, seeds, {**kwargs, **extra}, progress=False)
    eps.update(eps_o)
    rmse = {k: np.asarray(v["rmse_m"]) for k, v in eps.items()}
    ref = f"{base} (best tuned)" if base is not None else "plain"
    ref_mean = float(np.nanmean(rmse[ref]))
    rows = []
    for i, (name, x) in enumerate(rmse.items()):
        mean, lo, hi, n = bootstrap_mean_ci(x, n_boot, seed=100 + i)
        d = paired_difference(rmse[ref], x, n_boot, seed=200 + i)
        rows.append(
            {
                "policy": name,
                "rmse_m": mean,
                "rmse_lo": lo,
                "rmse_hi": hi,
                "diverged": float(np.mean(eps[name]["diverged"])),
                "gain_m": d["mean_diff"],
                "gain_lo": d["low"],
                "gain_hi": d["high"],
                "relative": d["mean_diff"] / ref_mean,
                "relative_lo": d["low"] / ref_mean,
                "n": n,
            }
        )
    sup = next(r for r in rows if r["policy"] == SUPERVISED)
    g2 = None if base is None else bool(sup["relative"] >= G2_MARGIN and sup["gain_lo"] > 0.0)
    return {
        "env_id": env_id,
        "reference": ref,
        "best_tuned": base,
        "rows": rows,
        "g2": g2,
        "episodes": {k: v.tolist() for k, v in rmse.items()},
        "seeds": [seeds[0], seeds[-1] + 1],
        "seed_kind": kind,
    }


def markdown_table(result: Mapping[str, Any]) -> str:
    """The comparison as a markdown table and the gate's verdict."""
    ref = result["reference"]
    lines = [
        f"| policy | RMSE [m] (95 % CI) | diverged | {ref} - policy [m] (95 % CI) | relative |",
        "|---|---|---|---|---|",
    ]
    for r in result["rows"]:
        gain = (
            "reference"
            if r["policy"] == ref
            else (f"{r['gain_m']:+.3f} ({r['gain_lo']:+.3f}, {r['gain_hi']:+.3f})")
        )
        rel = "" if r["policy"] == ref else f"{100 * r['relative']:+.1f} %"
        lines.append(
            f"| {r['policy']} | {r['rmse_m']:.3f} ({r['rmse_lo']:.3f}, {r['rmse_hi']:.3f}) | "
            f"{100 * r['diverged']:.1f} % | {gain} | {rel} |"
        )
    g2 = result["g2"]
    verdict = (
        "G2 not decidable: no tuned baselines for this env (compared with plain)"
        if g2 is None
        else f"G2 (>= {100 * G2_MARGIN:.0f} % below the best tuned baseline, CI excluding 0): "
        + ("PASS" if g2 else "FAIL")
    )
    kind = "held-out evaluation" if result.get("seed_kind", "eval") == "eval" else "TUNING (not held-out)"
    return "\n".join(lines) + f"\n\n{verdict}; {result['rows'][0]['n']} {kind} episodes.\n"
