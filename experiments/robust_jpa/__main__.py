"""``python -m experiments.robust_jpa [--runs 100] [--quick] [--out results/robust_jpa]``.

Belles et al. 2022, §5: iterated ESKF (ideal and plain) against the robust Huber and Tukey iterated ESKFs
(Algorithm 1) on GNSS joint position and attitude, without outliers (efficiency, eq. 29) and with
cycle slips on 2 of 10 satellites (20 % outliers). See README.md for the set-up and the results.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from agents.reporting import markdown_table, write_csv
from experiments.outputs import write_manifest
from filters import GaussianState, kalman, robust
from filters.core.linalg import symmetrize
from navgym.ins.attitude import rotation_matrix, rotation_vector, skew
from navgym.jpa.models import (
    DEG,
    Geometry,
    JpaConfig,
    JpaObservation,
    Truth,
    dd_operator,
    initial_covariance,
    make_geometry,
    observation_covariance,
    process_noise,
    simulate,
    slices,
    transition,
)

FILTERS = ("ideal I-ESKF", "I-ESKF", "Huber I-ESKF", "Tukey I-ESKF")
#: Filters run on the outlier-free runs (the ideal filter is the I-ESKF there).
NOMINAL_FILTERS = ("I-ESKF", "Huber I-ESKF", "Tukey I-ESKF")
CONVERGED_S = 100.0  # errors are summarized from this time on (initial convergence excluded)
#: A run has lost its attitude when its mean error over the last LOST_WINDOW_S exceeds LOST_DEG.
LOST_DEG, LOST_WINDOW_S = 2.0, 100.0
#: Algorithm 1 stops when no weight moved more than this (Belles et al. 2022: "until convergence").
WEIGHT_TOL = 1e-4


class JpaTransition:
    """Mean and error-state transition of one prediction (eq. 9-10) for :func:`kalman.predict`.

    The mean of the attitude error stays zero (the nominal rotation absorbs the bias-corrected
    gyro increment); ``a``, ``v``, ``b`` are kept and ``p += dt v``. The covariance uses ``F``
    of eq. 10.
    """

    def __init__(self, cfg: JpaConfig, w_hat: np.ndarray, Q: np.ndarray):
        self.cfg, self.sl, self.Q = cfg, slices(cfg), Q
        self._F = transition(cfg, w_hat)

    def f(self, x, u=None, dt=None):
        out = x.copy()
        out[:, self.sl["psi"]] = 0.0
        out[:, self.sl["p"]] += self.cfg.dt * x[:, self.sl["v"]]
        return out

    def F(self, x, u=None, dt=None):
        return self._F


def reset(cfg: JpaConfig, state: GaussianState, R_nom: np.ndarray) -> tuple[GaussianState, np.ndarray]:
    """ESKF reset (eq. 13): the attitude error moves into the nominal rotation, ``dpsi`` becomes 0.

    ``R_nom <- R_nom Exp(dpsi)``; the covariance is carried to the new tangent space with the
    reset Jacobian ``G = I - [dpsi / 2 x]`` on the attitude block (Sola, "Quaternion kinematics
    for the error-state Kalman filter", 2017, eq. 287), ``P <- G P G^T``.
    """
    sl = slices(cfg)
    dpsi = state.m[:, sl["psi"]]
    R_nom = R_nom @ rotation_matrix(dpsi)
    m = state.m.copy()
    m[:, sl["psi"]] = 0.0
    G = np.broadcast_to(np.eye(cfg.n_states), state.P.shape).copy()
    G[:, sl["psi"], sl["psi"]] -= skew(0.5 * dpsi)
    return GaussianState(m, symmetrize(G @ state.P @ np.swapaxes(G, 1, 2))), R_nom


def initial_estimates(cfg: JpaConfig, truth: Truth, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Shared starting points of every filter: truth plus Table 1's initial errors."""
    rng = np.random.default_rng(seed)
    sl = slices(cfg)
    B = truth.p.shape[1]
    x = np.zeros((B, cfg.n_states))
    x[:, sl["a"]] = truth.a + rng.normal(0.0, cfg.sigma0_ambiguity, truth.a.shape)
    x[:, sl["p"]] = truth.p[0] + rng.normal(0.0, cfg.sigma0_position, (B, 3))
    x[:, sl["v"]] = truth.v[0] + rng.normal(0.0, 1.0, (B, 3)) * np.asarray(cfg.sigma0_velocity)
    x[:, sl["b"]] = truth.b[0] + rng.normal(0.0, cfg.sigma0_bias, (B, 3))
    R0 = truth.R[0] @ rotation_matrix(rng.normal(0.0, cfg.sigma0_attitude, (B, 3)))
    return x, R0


def run_filter(
    name: str,
    cfg: JpaConfig,
    geom: Geometry,
    truth: Truth,
    x0: np.ndarray,
    R0: np.ndarray,
    callback: Callable[[int, GaussianState, np.ndarray], None] | None = None,
) -> dict[str, np.ndarray]:
    """Errors ``(T, B)`` of one filter over the runs: position [m], attitude [deg], bias [deg/h].

    ``callback(k, state, R_nom)``, if given, sees the filtered state after each reset.
    """
    sl = slices(cfg)
    T, B = truth.z.shape[:2]
    D = dd_operator(cfg.n_satellites, len(cfg.baselines))
    Q = process_noise(cfg)
    x, P, R_nom = x0.copy(), np.broadcast_to(initial_covariance(cfg), (B, cfg.n_states, cfg.n_states)), R0
    state = GaussianState(x, P.copy())
    err = {"position": np.empty((T, B)), "attitude": np.empty((T, B)), "bias": np.empty((T, B))}
    iters = np.zeros(T)
    for k in range(T):
        if k:
            w_hat = truth.gyro[k - 1] - state.m[:, sl["b"]]
            R_nom = R_nom @ rotation_matrix(w_hat * cfg.dt)
            state = kalman.predict(state, JpaTransition(cfg, w_hat, Q), None, cfg.dt)
        obs = JpaObservation(cfg, R_nom, geom.U[k], observation_covariance(cfg, geom.elevation[k], D))
        z = truth.z[k]
        if name == "ideal I-ESKF":  # knows which rows are outliers and drops them
            mask = np.broadcast_to(~truth.outlier[k], z.shape)
            state, _ = kalman.iterated_update(state, z, obs, mask=mask)
        elif name == "I-ESKF":
            state, _ = kalman.iterated_update(state, z, obs)
        else:
            weight = name.split()[0].lower()
            state, info = robust.iterated_update(state, z, obs, weight=weight, tol=WEIGHT_TOL)
            iters[k] = info.iterations.mean()
        state, R_nom = reset(cfg, state, R_nom)
        if callback is not None:
            callback(k, state, R_nom)
        m = state.m
        err["position"][k] = np.linalg.norm(m[:, sl["p"]] - truth.p[k], axis=1)
        dR = np.swapaxes(R_nom, 1, 2) @ truth.R[k]
        err["attitude"][k] = np.linalg.norm(rotation_vector(dR), axis=1) / DEG
        err["bias"][k] = np.linalg.norm(m[:, sl["b"]] - truth.b[k], axis=1) / DEG * 3600.0
    err["iterations"] = iters
    return err


def rmse(e: np.ndarray) -> np.ndarray:
    """RMSE over the runs at each time ``(T,)`` (a diverged run counts as NaN)."""
    return np.sqrt(np.mean(e * e, axis=1))


def periods(cfg: JpaConfig, t: np.ndarray) -> dict[str, np.ndarray]:
    """Time masks: converged before the first outlier zone, inside the zones, after each zone."""
    inside = np.zeros(t.size, dtype=bool)
    for t0, t1 in cfg.outlier_zones:
        inside |= (t >= t0) & (t < t1)
    first = min(t0 for t0, _ in cfg.outlier_zones) if cfg.outlier_zones else np.inf
    return {
        "before": (t >= CONVERGED_S) & (t < first),
        "outliers": inside,
        "after": (t >= first) & ~inside,
    }


def run(cfg: JpaConfig, runs: int, seed: int = 2004, progress: bool = True) -> dict:
    """Both scenarios on the same runs (truth, noise and initial errors shared by the filters)."""
    geom = make_geometry(cfg)
    out: dict = {"geometry": geom, "t": np.arange(geom.U.shape[0]) * cfg.dt}
    for scenario, names in (("nominal", NOMINAL_FILTERS), ("outliers", FILTERS)):
        truth = simulate(cfg, geom, runs, seed, outliers=scenario == "outliers")
        x0, R0 = initial_estimates(cfg, truth, seed + 1)
        for name in names:
            t0 = time.perf_counter()
            out[scenario, name] = run_filter(name, cfg, geom, truth, x0, R0)
            if progress:
                print(f"  {scenario:8s} {name:13s} {time.perf_counter() - t0:6.1f} s", flush=True)
    return out


def summarize(cfg: JpaConfig, res: dict) -> list[dict]:
    t = res["t"]
    per = periods(cfg, t)
    conv = t >= CONVERGED_S
    rows = []
    nominal = {name: rmse(res["nominal", name]["position"]) for name in NOMINAL_FILTERS}
    for name in FILTERS:
        e = res["outliers", name]
        pos = rmse(e["position"])
        row = {
            "filter": name,
            "pos RMSE before [m]": f"{np.mean(pos[per['before']]):.3f}",
            "pos RMSE in outlier zones [m]": f"{np.mean(pos[per['outliers']]):.3f}",
            "pos RMSE after zones [m]": f"{np.mean(pos[per['after']]):.3f}",
            "attitude RMSE [deg]": f"{np.mean(rmse(e['attitude'])[conv]):.3f}",
            "attitude median [deg]": f"{np.median(e['attitude'][conv]):.3f}",
            "runs with attitude lost": int(
                (e["attitude"][t >= t[-1] - LOST_WINDOW_S].mean(axis=0) > LOST_DEG).sum()
            ),
            "bias RMSE [deg/h]": f"{np.mean(rmse(e['bias'])[conv]):.2f}",
        }
        if name in nominal and name != "I-ESKF":
            eff = nominal["I-ESKF"][conv] ** 2 / nominal[name][conv] ** 2
            row["efficiency (no outliers, eq. 29)"] = f"{np.mean(eff):.3f}"
        elif name == "I-ESKF":
            row["efficiency (no outliers, eq. 29)"] = "1 (reference)"
        else:
            row["efficiency (no outliers, eq. 29)"] = "-"
        row["pos RMSE no outliers [m]"] = f"{np.mean(nominal[name][conv]):.3f}" if name in nominal else "-"
        rows.append(row)
    return rows


def plots(cfg: JpaConfig, res: dict, out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = res["t"]
    fig, axes = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    for name in FILTERS:
        e = res["outliers", name]
        for ax, key in zip(axes, ("position", "attitude", "bias"), strict=True):
            ax.semilogy(t, rmse(e[key]), label=name, lw=1)
    labels = ("position RMSE [m]", "attitude RMSE [deg]", "gyro bias RMSE [deg/h]")
    for ax, lab in zip(axes, labels, strict=True):
        for t0, t1 in cfg.outlier_zones:
            ax.axvspan(t0, t1, color="0.85")
        ax.set_ylabel(lab)
    axes[0].legend(fontsize=8)
    axes[0].set_title("Belles et al. 2022, §5: 20 % outliers (cycle slips on 2 of 10 satellites, grey)")
    axes[-1].set_xlabel("time [s]")
    fig.tight_layout()
    fig.savefig(out / "rmse.png", dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5, 4))
    conv = t >= CONVERGED_S
    for name in FILTERS:
        e = np.sort(res["outliers", name]["position"][conv].ravel())
        ax.semilogx(e, np.arange(1, e.size + 1) / e.size, label=name)
    ax.set_xlabel("position error [m]")
    ax.set_ylabel("empirical CDF")
    ax.legend(fontsize=8)
    ax.set_title("float position errors (t >= 100 s), with outliers")
    fig.tight_layout()
    fig.savefig(out / "cdf.png", dpi=100)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 3.5))
    ref = rmse(res["nominal", "I-ESKF"]["position"]) ** 2
    for name in NOMINAL_FILTERS[1:]:
        ax.plot(t, ref / rmse(res["nominal", name]["position"]) ** 2, label=name, lw=1)
    ax.axhline(1.0, color="k", lw=0.5)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("efficiency (eq. 29), position")
    ax.set_title("no outliers: MSE of the I-ESKF / MSE of the robust filter")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "efficiency.png", dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.robust_jpa", description=__doc__)
    p.add_argument("--runs", type=int, default=100, help="Monte Carlo runs (Belles et al. 2022: 100)")
    p.add_argument("--seed", type=int, default=2004)
    p.add_argument("--quick", action="store_true", help="6 runs of 200 s, one outlier zone [120, 170) s")
    p.add_argument("--out", default="results/robust_jpa")
    args = p.parse_args(argv)
    cfg = JpaConfig()
    runs = args.runs
    if args.quick:
        cfg = replace(cfg, duration=200.0, outlier_zones=((120.0, 170.0),))
        runs = 6
    t0 = time.perf_counter()
    res = run(cfg, runs, args.seed)
    rows = summarize(cfg, res)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "table.csv", rows)
    geom = res["geometry"]
    table = markdown_table(rows)
    zones = ", ".join(f"[{a:g}, {b:g})" for a, b in cfg.outlier_zones)
    (out / "report.md").write_text(
        f"# Belles et al. 2022, §5: robust JPA, {runs} runs x {cfg.duration:g} s\n\n"
        f"Satellites (PRN, reference first): {geom.prn.tolist()}; outliers on PRN "
        f"{geom.prn[1:][geom.outlier_rows].tolist()} in {zones} s. Errors from t >= {CONVERGED_S:g} s;"
        " 'before' is [100 s, first zone), 'after' every time after the first zone outside the zones;"
        f" a run has lost its attitude when its mean error over the last {LOST_WINDOW_S:g} s exceeds"
        f" {LOST_DEG:g} deg.\n\n"
        f"{table}\n"
        "Mean robust iterations (Algorithm 1 reweightings) per epoch with outliers: "
        + ", ".join(f"{n} {res['outliers', n]['iterations'].mean():.2f}" for n in FILTERS[2:])
        + "\n\n![rmse](rmse.png) ![cdf](cdf.png) ![efficiency](efficiency.png)\n"
    )
    plots(cfg, res, out)
    np.savez_compressed(
        out / "errors.npz",
        t=res["t"],
        **{
            f"{scenario}/{name}/{key}": res[scenario, name][key].astype(np.float32)
            for scenario, names in (("nominal", NOMINAL_FILTERS), ("outliers", FILTERS))
            for name in names
            for key in ("position", "attitude", "bias")
        },
    )
    write_manifest(
        out,
        "experiments.robust_jpa",
        argv,
        runs=runs,
        seed=args.seed,
        config={k: v for k, v in cfg.__dict__.items()},
        wall_time_s=round(time.perf_counter() - t0, 1),
    )
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
