"""``python -m experiments.dirac_gauss [--runs 8] [--seconds 4] [--snr 0 -3] [--quick] [--out DIR]``.

Dirac-Gauss DPF n.d.: the deterministic Dirac-Gauss particle filter (N = 144, M_w = 10 jump bins,
overlap threshold 1/3) against the random Dirac-Gauss PF at N = 144, 1000 and 4000 on simulated
correlator outputs of a receiver with acceleration jumps up to 10 g, at 0 and -3 dB. See
README.md for the model, the choices the paper leaves open and the results.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from tqdm import tqdm

from agents.reporting import markdown_table, write_csv
from experiments.dirac_gauss.run import TRANSIENT_S, metrics, prior, run
from experiments.outputs import write_manifest
from navgym.signal_tracking.models import T_CODE, SignalConfig, simulate_truth

#: (filter, N) pairs of the default study (the random PF's N: ``--random-n``); Dirac-Gauss DPF n.d.:
#: deterministic N = 144, random "similar performances only for N = 10000", degraded at ~4000.
FILTERS = (("deterministic", 144), ("random", 144), ("random", 1000), ("random", 4000))
QUICK_FILTERS = (("deterministic", 24), ("random", 24), ("random", 200))


def study(
    snrs: list[float], runs: int, seconds: float, seed: int, filters, jump_rate: float, show: bool = True
) -> tuple[list[dict], dict]:
    """Every filter on the same truth and noise per SNR; returns table rows and the raw results."""
    steps = int(round(seconds / T_CODE))
    rows, raw, per_run = [], {}, []
    total = len(snrs) * len(filters) * steps
    with tqdm(total=total, desc="dirac_gauss", unit="step", disable=not show) as bar:
        for snr in snrs:
            cfg = SignalConfig(snr_db=snr, jump_rate=jump_rate)
            rngs = [np.random.default_rng([seed, int(10 * snr) % 1000, i]) for i in range(runs)]
            truth = simulate_truth(cfg, rngs, steps)
            noise = np.stack([g.standard_normal((steps, 2 * len(cfg.taps))) for g in rngs])
            m0, P0 = prior(cfg, truth, rngs)
            for kind, N in filters:
                frngs = [np.random.default_rng([seed, 7, i]) for i in range(runs)]
                res = run(kind, cfg, truth, noise, m0, P0, N, frngs, pbar=bar)
                mt = metrics(truth, res)
                raw[snr, kind, N] = (truth, res)
                bits = int(mt["bits"].sum())
                pairs = int(mt["transitions"].sum())
                calm_pairs = pairs - int(mt["transient_transitions"].sum())
                calm_err = int(mt["transition_errors"].sum() - mt["transient_transition_errors"].sum())
                for b in range(runs):
                    per_run.append(
                        {"snr_db": snr, "filter": kind, "N": N, "run": b, **{k: v[b] for k, v in mt.items()}}
                    )
                rows.append(
                    {
                        "SNR dB": f"{snr:g}",
                        "filter": kind,
                        "N": N,
                        "range RMSE m (median run)": f"{np.median(mt['range_rmse_m']):.2f}",
                        "Doppler RMSE Hz (median run)": f"{np.median(mt['doppler_rmse_hz']):.2f}",
                        "Doppler RMSE Hz (worst run)": f"{mt['doppler_rmse_hz'].max():.1f}",
                        "bit errors / bits": f"{int(mt['bit_errors'].sum())} / {bits}",
                        "differential errors / transitions": f"{mt['transition_errors'].sum()} / {pairs}",
                        f"the same > {TRANSIENT_S:g} s after any jump": f"{calm_err} / {calm_pairs}",
                        "runs without a bit error": int((mt["transition_errors"] == 0).sum()),
                        "runs lost": int(mt["lost"].sum()),
                        "jumps (all runs)": int(mt["jumps"].sum()),
                        "s per run-second": f"{res.seconds / (runs * seconds):.1f}",
                    }
                )
    return rows, raw, per_run


def plot(raw: dict, out: Path) -> None:
    """Doppler error of run 0 per filter at the first SNR, with the true acceleration."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from navgym.signal_tracking.models import LAMBDA_L1

    snr = next(iter(raw))[0]
    fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(8, 5), sharex=True)
    for (s, kind, N), (truth, res) in raw.items():
        if s != snr:
            continue
        t = np.arange(truth.mode.shape[1]) * T_CODE
        ax1.plot(t, (res.est[0, :, 3] - truth.x[0, :, 3]) / LAMBDA_L1, lw=0.8, label=f"{kind} N={N}")
    ax0.plot(t, truth.x[0, :, 4], "k", lw=1)
    ax0.set_ylabel("true acceleration [m/s^2]")
    ax1.set_ylabel("Doppler error [Hz]")
    ax1.set_xlabel("time [s]")
    ax1.set_ylim(-60, 60)
    ax1.legend(fontsize=8)
    ax0.set_title(f"Dirac-Gauss DPF n.d.: run 0 at {snr:g} dB")
    fig.tight_layout()
    fig.savefig(out / "doppler.png", dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m experiments.dirac_gauss", description=__doc__)
    p.add_argument("--runs", type=int, default=8, help="Monte Carlo runs per SNR")
    p.add_argument("--seconds", type=float, default=4.0, help="run length [s] (1000 steps per s)")
    p.add_argument("--snr", type=float, nargs="+", default=[0.0, -3.0], help="prompt SNR [dB]")
    p.add_argument("--jump-rate", type=float, default=0.5, help="acceleration jumps per second")
    p.add_argument(
        "--random-n", type=int, nargs="+", default=[144, 1000, 4000], help="particle counts of the random PF"
    )
    p.add_argument("--seed", type=int, default=2003)
    p.add_argument("--quick", action="store_true", help="2 runs of 0.4 s at 0 dB, small N")
    p.add_argument("--out", default="results/dirac_gauss")
    args = p.parse_args(argv)
    if args.runs < 1 or not args.seconds > 0.2:
        p.error("--runs must be >= 1 and --seconds > 0.2 (errors are counted after 0.2 s)")
    if min(args.random_n) < 1:
        p.error("--random-n values must be >= 1")
    filters = (FILTERS[0], *(("random", n) for n in args.random_n))
    runs, seconds, snrs = args.runs, args.seconds, args.snr
    if args.quick:
        filters, runs, seconds, snrs = QUICK_FILTERS, 2, 0.4, [0.0]
    t0 = time.perf_counter()
    rows, raw, per_run = study(snrs, runs, seconds, args.seed, filters, args.jump_rate)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "table.csv", rows)
    write_csv(out / "runs.csv", per_run)
    table = markdown_table(rows)
    cfg = replace(SignalConfig(), jump_rate=args.jump_rate)
    (out / "report.md").write_text(
        f"# Dirac-Gauss DPF n.d.: Dirac-Gauss particle filters, {runs} runs x {seconds:g} s per SNR\n\n"
        f"Jumps {cfg.jump_rate:g}/s up to {cfg.jump_max_g:g} g; errors after 0.2 s; medians over runs.\n\n"
        f"{table}\n![doppler](doppler.png)\n"
    )
    plot(raw, out)
    write_manifest(
        out,
        "experiments.dirac_gauss",
        argv,
        runs=runs,
        seconds=seconds,
        snr_db=snrs,
        seed=args.seed,
        filters=[list(f) for f in filters],
        config={k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in cfg.__dict__.items()},
        wall_time_s=round(time.perf_counter() - t0, 1),
    )
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
