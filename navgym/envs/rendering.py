"""``render_mode="rgb_array"``: truth and estimated tracks, covariance ellipse, GNSS availability."""

from __future__ import annotations

from typing import Any

import numpy as np


def render_track(history: list[dict[str, Any]], title: str) -> np.ndarray:
    """Draw the episode so far (north/east metres) and return an RGB array ``(H, W, 3)``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.4, 4.8), dpi=80)
    canvas = FigureCanvasAgg(fig)
    ax, ax_err = fig.subplots(2, 1, gridspec_kw={"height_ratios": [3, 1]})
    if history:
        truth = np.array([h["truth_pos"] for h in history], dtype=float)
        est = np.array([h["est_pos"] for h in history], dtype=float)
        ok = np.array([bool(h["gnss_available"]) for h in history])
        err = np.array([h["pos_err_m"] for h in history], dtype=float)
        ax.plot(truth[:, 1], truth[:, 0], "k-", lw=1.5, label="truth")
        ax.plot(est[:, 1], est[:, 0], "C1--", lw=1.0, label="estimate")
        ax.plot(est[~ok, 1], est[~ok, 0], "r.", ms=2, label="no GNSS")
        cov = np.asarray(history[-1]["cov_ne"])  # (north, east) covariance of the estimate
        if np.all(np.isfinite(cov)):
            w, V = np.linalg.eigh(0.5 * (cov + cov.T))
            a = np.linspace(0, 2 * np.pi, 60)
            ell = V @ (np.sqrt(np.maximum(w, 0))[:, None] * 2.0 * np.stack([np.cos(a), np.sin(a)]))
            ax.plot(est[-1, 1] + ell[1], est[-1, 0] + ell[0], "C0-", lw=1, label="2-sigma")
        steps = np.arange(1, len(err) + 1)
        ax_err.plot(steps, err, "C1-")
        for k in np.flatnonzero(~ok):
            ax_err.axvspan(k + 0.5, k + 1.5, color="r", alpha=0.15, lw=0)
        ax_err.set_ylabel("error [m]")
        ax_err.set_xlabel("step")
        ax.legend(loc="best", fontsize=7)
    ax.set_title(title)
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_aspect("equal", adjustable="datalim")
    fig.tight_layout()
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
