"""``python -m experiments.critical_scenario [--episodes 64] [--particles 1000] [--quick]``.

Seed 000 §V (Carvalho et al., IEEE T-AES 1997, Figs. 12-18): in the critical scenario (visibility
mask 50 deg, the visible satellites falling from 3 to 2, pseudo-ranges every 1 s for 3600 s) an
*a priori* (bootstrap) particle filter with N = 1000 particles keeps track of the INS drifts in
longitude, latitude and time, while the EKF cannot once only 2 satellites remain. That is the
seed's claim; README.md gives the measured verdict (not reproduced here).

Both filters run seed 000's eight-state error model (eq. 13)::

    x = [e_lambda, e_phi, de_lambda, de_phi, a_x, a_y, b, d]

(INS position errors east/north [m], their rates, accelerometer biases, receiver clock bias
``b = c delta`` [m] and drift), with the pseudo-ranges of eq. 10/15 predicted from the corrected
INS position (eq. 14)::

    h_i(x) = |s_i' - (p_INS - e_lambda E - e_phi N)| + Sagnac + b + T_i.

* EKF: ``navgym/GpsInsFading-v1`` with action -1 (fading factor 1, the plain EKF);
* PF: ``navgym/GpsInsResample-v0`` (bootstrap PF, no roughening: seed 000's a priori filter),
  resampling by seed 000's redistribution rule ("redistribution occurs when the number of
  particles whose weights are smaller than 1/(10N) is higher than 10 % of N"), read from the
  observation's ``redistribution_rule`` column (:class:`agents.baselines.resample.RedistributionRule`).

Both envs get ``critical=True``, ``m_max=8`` and ``true_bias_limit_ug=None`` and are reset with the
same seeds, so they play the same episodes (truth, satellites and pseudo-range noise). The metric
is seed 000's running rms error (§V)::

    e_t^X = sqrt((1/t) sum_{tau=1..t} (X_tau - Xhat_tau)^2)

for X = longitude drift ``e_lambda`` [m east], latitude drift ``e_phi`` [m north] and the clock
(time) error ``b`` [m; 1 m = 3.34 ns]. The truth is the core's ``episodes.ins_err`` and
``episodes.clock``; the estimate the filter mean (the particle mean for the PF). The env's
divergence bound is lifted (``divergence_m`` = 1e12) so that every episode plays the full
3600 s; the default rule (health flag, error above 2000 m, or horizontal sigma above 100 x
2000 m) is evaluated on the same steps and reported as "diverged". Seeds: the tuning range
(``agents.seeds``) from offset 200 000, never the held-out evaluation seeds.
"""

from __future__ import annotations

import argparse
import csv
import json
import platform as _platform
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import navgym  # noqa: F401  (registers the ids)
from agents.baselines.resample import RedistributionRule
from agents.seeds import seeds
from filters.particle import estimates
from navgym.envs.core import SIGMA_DIVERGENCE
from navgym.envs.gps_ins import GpsInsPlatform
from navgym.envs.registration import superseded_ids_quiet
from navgym.geo import C_LIGHT
from navgym.gnss import default_critical_window

#: Where the study's seeds start inside the tuning range (divergence_penalty uses 100 000).
SEED_OFFSET = 200_000
#: Steps of seed 000's run (3600 s at 1 Hz).
STEPS = 3600
#: The env's default divergence bound [m] (reported, not enforced: see the module docstring).
DEFAULT_DIVERGENCE_M = 2000.0
#: ``divergence_m`` passed to the envs: every episode plays the full run.
NO_DIVERGENCE_M = 1e12
#: Same episodes for both filters: the Resample ids are registered with 8 satellite rows, and the
#: pseudo-range noise buffers are 3 m_max wide, so the EKF gets m_max = 8 too.
COMMON_KWARGS = {"critical": True, "m_max": 8, "true_bias_limit_ug": None, "divergence_m": NO_DIVERGENCE_M}
#: The three drifts of seed 000 Figs. 13-18: (state index, label, unit).
VARIABLES = (
    (0, "longitude drift e_lambda", "m east"),
    (1, "latitude drift e_phi", "m north"),
    (6, "clock bias b", "m"),
)
#: Times [s] of the table besides the 3 -> 2 transition.
TABLE_TIMES = (1000, STEPS)


def play(
    kind: str,
    episodes: int,
    seed: int,
    particles: int = 1000,
    steps: int = STEPS,
    pbar=None,
    **pf_kwargs,
) -> dict[str, np.ndarray]:
    """Play ``episodes`` critical-scenario episodes (seeds ``seed + i``) with the EKF or the PF.

    Args:
        kind: ``"ekf"`` or ``"pf"``.
        episodes: number of episodes (one native vector env).
        seed: reset seed of the first episode.
        particles: PF particle count.
        steps: steps played (1 s each).
        pbar: optional tqdm bar advanced by one per step.
        **pf_kwargs: other ``GpsInsResample`` keyword arguments (e.g. ``roughening``; the study's
            default is none: seed 000's a priori filter).

    Returns:
        ``err (B, steps, 3)`` estimate minus truth of the three drifts [m] at t = 1..steps (NaN
        after a health-flag termination), ``truth (B, steps, 3)`` the true drifts [m], ``used
        (B, steps)`` satellites used, ``diverged_at (B,)`` first step at which the env's default
        divergence rule fires (-1: never), ``terminated_at (B,)`` first step the env terminated
        (health flag; -1: never), ``resamples (B,)`` (PF).
    """
    kw = dict(COMMON_KWARGS, max_episode_steps=steps)
    if kind == "pf":
        with superseded_ids_quiet():
            env = gym.make_vec(
                "navgym/GpsInsResample-v0", num_envs=episodes, n_particles=particles, **kw, **pf_kwargs
            )
        policy = RedistributionRule(env)
    elif kind == "ekf":
        env = gym.make_vec("navgym/GpsInsFading-v1", num_envs=episodes, **kw)
        policy = None
    else:
        raise ValueError(f"kind must be 'ekf' or 'pf'; got {kind!r}")
    core = env.unwrapped.core
    obs, _ = env.reset(seed=seed)
    B, idx = episodes, [v[0] for v in VARIABLES]
    err = np.full((B, steps, 3), np.nan)
    truth_out = np.full((B, steps, 3), np.nan)
    used = np.zeros((B, steps), dtype=np.int64)
    diverged_at = np.full(B, -1)
    terminated_at = np.full(B, -1)
    resamples = np.zeros(B)
    alive = np.ones(B, dtype=bool)
    rows = np.arange(B)
    for k in range(steps):
        if policy is None:
            action = np.full((B, 1), -1.0, np.float32)
        else:
            action, _ = policy.predict(obs)
        obs, _, term, _, info = env.step(action)
        mean = core.state.m if policy is None else estimates.mean(core.state.particles)
        t = core.t  # = k + 1 for the episodes still in their first run
        truth = np.concatenate(
            [core.episodes.ins_err[rows, t], C_LIGHT * core.episodes.clock[rows, t]], axis=1
        )
        e = mean[:, idx] - truth[:, idx]
        err[alive, k] = e[alive]
        truth_out[alive, k] = truth[alive][:, idx]
        used[alive, k] = info["n_meas"][alive]
        sigma_h = np.sqrt(np.abs(np.trace(info["cov_ne"], axis1=1, axis2=2)))
        rule = (
            ~info["healthy"]
            | ~(info["pos_err_m"] <= DEFAULT_DIVERGENCE_M)
            | ~(sigma_h <= SIGMA_DIVERGENCE * DEFAULT_DIVERGENCE_M)
        )
        diverged_at = np.where(alive & rule & (diverged_at < 0), k + 1, diverged_at)
        if policy is not None:
            resamples = np.where(alive, info["resamples"], resamples)
        ended = alive & term
        terminated_at[ended] = k + 1
        alive &= ~ended  # the vector env autoresets these rows: later records are not theirs
        if pbar is not None:
            pbar.update(1)
    env.close()
    return {
        "err": err,
        "truth": truth_out,
        "used": used,
        "diverged_at": diverged_at,
        "terminated_at": terminated_at,
        "resamples": resamples,
    }


def running_rms(err: np.ndarray) -> np.ndarray:
    """Seed 000's ``e_t = sqrt((1/t) sum_{tau<=t} err_tau^2)`` along axis 1 (NaN once err is NaN)."""
    t = np.arange(1, err.shape[1] + 1).reshape((1, -1) + (1,) * (err.ndim - 2))
    return np.sqrt(np.cumsum(np.square(err), axis=1) / t)


def _quartiles(x: np.ndarray) -> tuple[float, float, float]:
    q = np.nanpercentile(x, [25, 50, 75]) if np.isfinite(x).any() else [np.nan] * 3
    return float(q[1]), float(q[0]), float(q[2])


def _plot(res: dict, window, switch_s: float, path: Path, title: str) -> None:
    """Satellites over time, then the running rms of the three drifts (median, 25-75 % band)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 1, figsize=(8, 11), sharex=True)
    steps = res["ekf"]["err"].shape[1]
    t = np.arange(1, steps + 1)
    ax = axes[0]
    vis = np.asarray(window.counts[: steps + 1])
    ax.step(
        np.arange(vis.size), vis, where="post", color="k", lw=1.5, label="visible (50 deg, reference point)"
    )
    for name, style in (("ekf", "tab:blue"), ("pf", "tab:orange")):
        u = res[name]["used"].astype(float)
        ax.plot(t, np.median(u, axis=0), color=style, lw=1, ls="--", label=f"used by {name.upper()} (median)")
    ax.set_ylim(0, 4)
    ax.set_ylabel("satellites")
    ax.legend(loc="lower left", fontsize=8)
    ax.set_title(title, fontsize=10)
    colors = {"ekf": "tab:blue", "pf": "tab:orange"}
    labels = {"ekf": "EKF", "pf": res["pf_label"]}
    for j, (_, name, unit) in enumerate(VARIABLES):
        ax = axes[j + 1]
        for f in ("ekf", "pf"):
            r = running_rms(res[f]["err"][..., j])
            with np.errstate(all="ignore"):
                q25, q50, q75 = (np.nanpercentile(r, q, axis=0) for q in (25, 50, 75))
            ax.plot(t, q50, color=colors[f], lw=1.5, label=f"{labels[f]} median")
            ax.fill_between(t, q25, q75, color=colors[f], alpha=0.25, lw=0, label=f"{labels[f]} 25-75 %")
        ax.set_yscale("log")
        ax.set_ylabel(f"running rms [{unit}]")
        ax.set_title(f"running rms error, {name}", fontsize=9)
        ax.legend(loc="upper left", fontsize=8)
    for ax in axes:
        ax.axvline(switch_s, color="k", ls=":", lw=1)
    axes[0].text(switch_s, 3.6, f" 3 -> 2 at {switch_s:.0f} s", fontsize=8)
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def summarize(res: dict, switch_s: float) -> list[dict]:
    """One row per (filter, drift): running rms median [q25, q75] at 1000 s, the switch, the end."""
    steps = res["ekf"]["err"].shape[1]
    times = [("1000 s", 1000), (f"switch ({switch_s:.0f} s)", int(switch_s)), (f"{steps} s", steps)]
    times = [(lab, k) for lab, k in times if k <= steps]
    rows = []
    for f in ("ekf", "pf"):
        r = res[f]
        B = r["err"].shape[0]
        for j, (_, name, unit) in enumerate(VARIABLES):
            rms = running_rms(r["err"][..., j])
            other = running_rms(res["pf" if f == "ekf" else "ekf"]["err"][..., j])
            row = {"filter": res["pf_label"] if f == "pf" else "EKF", "variable": name, "unit": unit}
            for lab, k in times:
                med, lo, hi = _quartiles(rms[:, k - 1])
                row[f"rms {lab} median"] = round(med, 2)
                row[f"rms {lab} q25"] = round(lo, 2)
                row[f"rms {lab} q75"] = round(hi, 2)
            k0 = int(switch_s)
            if k0 < steps:  # rms over the 2-satellite phase alone, (switch, end]
                post = np.sqrt(np.mean(np.square(r["err"][:, k0:, j]), axis=1))
                med, lo, hi = _quartiles(post)
                row["rms 2-satellite phase median"] = round(med, 2)
                row["rms 2-satellite phase q25"] = round(lo, 2)
                row["rms 2-satellite phase q75"] = round(hi, 2)
            with np.errstate(invalid="ignore"):
                row[f"better than the other at {steps} s %"] = round(
                    100.0 * float(np.mean(rms[:, -1] < other[:, -1])), 1
                )
            row["episodes"] = B
            row["diverged (default rule)"] = int((r["diverged_at"] > 0).sum())
            row["diverged after the switch"] = int((r["diverged_at"] > switch_s).sum())
            row["terminated (health flag)"] = int((r["terminated_at"] > 0).sum())
            row["mean resamplings"] = round(float(r["resamples"].mean()), 1) if f == "pf" else "-"
            rows.append(row)
    return rows


def _markdown(rows: list[dict], times: list[str]) -> str:
    cols = ["filter", "variable", *[f"rms {t}" for t in times], "episodes diverged (after switch)"]
    out = "| " + " | ".join(cols) + " |\n|" + "---|" * len(cols) + "\n"
    for r in rows:
        cells = [r["filter"], f"{r['variable']} [{r['unit']}]"]
        for t in times:
            cells.append(f"{r[f'rms {t} median']:.2f} [{r[f'rms {t} q25']:.2f}, {r[f'rms {t} q75']:.2f}]")
        cells.append(f"{r['diverged (default rule)']} ({r['diverged after the switch']}) / {r['episodes']}")
        out += "| " + " | ".join(cells) + " |\n"
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.critical_scenario", description=__doc__)
    p.add_argument("--episodes", type=int, default=64, help="64: about 50 s on one core")
    p.add_argument("--particles", type=int, default=1000)
    p.add_argument("--steps", type=int, default=STEPS, help="seconds played (seed 000: 3600)")
    p.add_argument("--quick", action="store_true", help="2 episodes, 200 particles, the full 3600 s")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--out", default="results/critical_scenario")
    args = p.parse_args(argv)
    episodes, particles, steps = args.episodes, args.particles, args.steps
    if args.quick:
        episodes, particles = 2, 200
    if not 1 <= steps <= STEPS:
        raise SystemExit(f"--steps must lie in [1, {STEPS}]; got {steps}")
    seed = seeds("tune", episodes, offset=SEED_OFFSET)[0]
    window = default_critical_window(GpsInsPlatform().almanac)
    switch_s = float(window.switch_s)
    res: dict = {"pf_label": f"PF (N = {particles})"}
    timing = {}
    bar = None
    if not args.no_progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=2 * steps, desc="EKF then PF (steps)", leave=False)
    for kind in ("ekf", "pf"):
        t0 = time.perf_counter()
        res[kind] = play(kind, episodes, seed, particles, steps, pbar=bar)
        timing[kind] = round(time.perf_counter() - t0, 1)
        if bar is None:
            print(f"{kind}: {episodes} episodes x {steps} s in {timing[kind]} s", flush=True)
    if bar is not None:
        bar.close()
    rows = summarize(res, switch_s)
    times = [k.removeprefix("rms ").removesuffix(" median") for k in rows[0] if k.endswith(" median")]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "table.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    table = _markdown(rows, times)
    after = res["ekf"]["used"][:, int(switch_s) + 60 :]
    before = res["ekf"]["used"][:, : int(switch_s) - 60]
    paired = np.array_equal(res["ekf"]["truth"], res["pf"]["truth"], equal_nan=True) and np.array_equal(
        res["ekf"]["used"], res["pf"]["used"]
    )
    sats = (
        f"Paired episodes (same truth and satellites used by both filters): {paired}. "
        f"Satellites used: before the switch {np.unique(before).tolist()}, "
        f"from 60 s after it {np.unique(after).tolist()} "
        f"(visible at the reference point: 3 until {switch_s:.0f} s, then 2)."
        if after.size and before.size
        else ""
    )
    better = {r["variable"]: r[f"better than the other at {steps} s %"] for r in rows if r["filter"] != "EKF"}
    (out / "report.md").write_text(
        "# Seed 000 §V: the critical scenario (50 deg mask, 3 -> 2 satellites)\n\n"
        f"{episodes} episodes x {steps} s, tuning seeds from {seed}; EKF = GpsInsFading-v1 with "
        f"fading factor 1; PF = GpsInsResample-v0 (bootstrap, no roughening, N = {particles}) with "
        "seed 000's redistribution rule. Running rms error e_t (seed 000 §V), median [25 %, 75 %] "
        "over the episodes; '2-satellite phase': the rms over the steps after the switch alone "
        "(not a running rms). Clock bias in metres (1 m = 3.34 ns). 'Diverged': the env's default "
        "rule (health flag, horizontal error > 2000 m or sigma > 2e5 m) fired at some step; the "
        "study lifts the bound, so every episode is played and scored over all its steps.\n\n"
        f"{table}\n{sats}\n\nEpisodes where the PF's running rms at {steps} s is below the EKF's: "
        + ", ".join(f"{k} {v:.0f} %" for k, v in better.items())
        + f".\n\nMean PF resamplings per episode: {res['pf']['resamples'].mean():.1f}. "
        f"Wall time: EKF {timing['ekf']} s, PF {timing['pf']} s.\n\n![running rms](running_rms.png)\n"
    )
    _plot(res, window, switch_s, out / "running_rms.png", f"seed 000 critical scenario, {episodes} episodes")
    commit = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True).stdout.strip()
    (out / "manifest.json").write_text(
        json.dumps(
            {
                "command": " ".join(
                    ["python -m experiments.critical_scenario", *(sys.argv[1:] if argv is None else argv)]
                ),
                "episodes": episodes,
                "particles": particles,
                "steps": steps,
                "seeds": [seed, seed + episodes - 1],
                "seed_kind": "tune",
                "env_ids": {"ekf": "navgym/GpsInsFading-v1", "pf": "navgym/GpsInsResample-v0"},
                "env_kwargs": {**COMMON_KWARGS, "max_episode_steps": steps, "n_particles (pf)": particles},
                "switch_s": switch_s,
                "wall_s": timing,
                "git_commit": commit,
                "python": _platform.python_version(),
                "numpy": np.__version__,
                "gymnasium": gym.__version__,
            },
            indent=1,
        )
    )
    print(table)
    print(f"wrote {out}/ (table.csv, report.md, running_rms.png, manifest.json)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
