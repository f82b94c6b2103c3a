"""Rendering of a :class:`~navgym.envs.base.NavEnv`: ``render_mode="rgb_array"`` and ``"human"``.

A frame shows the episode so far: for the map platforms the truth and estimated tracks
(north/east metres), the 2-sigma covariance ellipse and the steps without GNSS; for
SignalTracking (one-dimensional) the range error and the Doppler term over time. Below, the
position error over time with the scenario's active events shaded, and a text line with the
step, the knob, the reward, the active events and the row's context (fading, NIS, ESS...).

The axes stay readable after divergence: the map is scaled to the truth track; an estimate far
outside it is drawn as a marker on the border with its distance, and the ellipse is clipped.
The events come from the episode's scenario (truth: rendering may use it, the observation never
does). Rendering reads the recorded rows only: it draws no random number and changes no state.
:class:`FrameRenderer` keeps one figure and its artists between frames.
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: The scenario's event fields and their labels in a frame.
EVENT_FIELDS = (
    ("outages", "outage"),
    ("partial_outages", "partial outage"),
    ("impulsive", "impulsive"),
    ("jamming", "jamming"),
    ("outliers", "outliers"),
    ("bursts", "motion burst"),
    ("multipath", "multipath"),
    ("canyons", "canyon"),
)

#: Scalar info keys shown as the row's context when the platform reports them.
CONTEXT_KEYS = ("fading", "nis", "n_meas", "jump_probability", "ess_frac", "lock_indicator")

#: Keys of an info row kept for the frames.
ROW_KEYS = ("truth_pos", "est_pos", "gnss_available", "pos_err_m", "cov_ne", "knob", "t", "extra_err")

_NON_INTERACTIVE = {
    "agg",
    "pdf",
    "ps",
    "svg",
    "pgf",
    "cairo",
    "template",
    "module://matplotlib_inline.backend_inline",
}


def history_row(info: dict[str, Any], reward: float) -> dict[str, Any]:
    """The part of a step's info row that the frames use (copied: no reference into the core)."""
    row: dict[str, Any] = {k: np.array(info[k], copy=True) for k in ROW_KEYS if k in info}
    row["reward"] = float(reward)
    row["context"] = {k: float(info[k]) for k in CONTEXT_KEYS if k in info and np.ndim(info[k]) == 0}
    return row


def active_events(scenario: Any, t: float) -> list[str]:
    """Labels of the scenario's events active at time ``t`` [s] (``start <= t < end``)."""
    names = []
    for field, label in EVENT_FIELDS:
        for ev in getattr(scenario, field, ()) or ():
            start, end = getattr(ev, "start", None), getattr(ev, "end", None)
            if start is not None and end is not None and start <= t < end:
                names.append(label)
                break
    return names


def _ellipse(cov: np.ndarray) -> np.ndarray | None:
    if cov.shape != (2, 2) or not np.all(np.isfinite(cov)):
        return None
    w, V = np.linalg.eigh(0.5 * (cov + cov.T))
    a = np.linspace(0, 2 * np.pi, 60)
    return V @ (np.sqrt(np.maximum(w, 0))[:, None] * 2.0 * np.stack([np.cos(a), np.sin(a)]))


def _limits(truth: np.ndarray) -> tuple[float, float, float, float]:
    """(east_lo, east_hi, north_lo, north_hi) around the truth track with a margin."""
    lo, hi = truth.min(axis=0), truth.max(axis=0)
    half = max(float(np.max(hi - lo)) / 2 * 1.3, 25.0)
    c = (lo + hi) / 2
    return c[1] - half, c[1] + half, c[0] - half, c[0] + half


class FrameRenderer:
    """One figure reused between frames; :meth:`draw` updates the artists and returns RGB."""

    def __init__(self, title: str, one_dimensional: bool = False, human: bool = False) -> None:
        self.title = title
        self.one_dimensional = one_dimensional
        self.human = human
        if human:
            import matplotlib.pyplot as plt

            self.fig = plt.figure(figsize=(6.4, 4.8), dpi=80)
            self.interactive = plt.get_backend().lower() not in _NON_INTERACTIVE
            if self.interactive:
                plt.show(block=False)
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.fig = Figure(figsize=(6.4, 4.8), dpi=80)
            FigureCanvasAgg(self.fig)
            self.interactive = False
        self.ax, self.ax_err = self.fig.subplots(2, 1, gridspec_kw={"height_ratios": [3, 1]})
        ax, ax_err = self.ax, self.ax_err
        if one_dimensional:
            (self.l_truth,) = ax.plot([], [], "C1-", lw=1.0, label="range error [m]")
            self.ax2 = ax.twinx()
            (self.l_est,) = self.ax2.plot([], [], "C2-", lw=1.0, label="Doppler term [m]")
            (self.l_nognss,) = ax.plot([], [], "r.", ms=2, label="no signal")
            (self.l_ell,) = ax.plot([], [], "C0:", lw=1, label="2-sigma")
            (self.l_ell2,) = ax.plot([], [], "C0:", lw=1)
            ax.set_xlabel("t [s]")
            ax.set_ylabel("range error [m]")
            self.ax2.set_ylabel("Doppler term [m]")
        else:
            (self.l_truth,) = ax.plot([], [], "k-", lw=1.5, label="truth")
            (self.l_est,) = ax.plot([], [], "C1--", lw=1.0, label="estimate")
            (self.l_nognss,) = ax.plot([], [], "r.", ms=2, label="no GNSS")
            (self.l_ell,) = ax.plot([], [], "C0-", lw=1, label="2-sigma")
            (self.l_off,) = ax.plot([], [], "C1>", ms=8, clip_on=False)
            self.t_off = ax.text(0.02, 0.02, "", transform=ax.transAxes, fontsize=7, color="C1")
            ax.set_xlabel("east [m]")
            ax.set_ylabel("north [m]")
            ax.set_aspect("equal", adjustable="box")
        handles = [self.l_truth, self.l_est, self.l_nognss, self.l_ell]
        ax.legend(handles=handles, loc="upper right", fontsize=7)
        (self.l_err,) = ax_err.plot([], [], "C1-")
        self.spans: list[Any] = []
        ax_err.set_ylabel("error [m]")
        ax_err.set_xlabel("step")
        self.status = self.fig.text(0.01, 0.99, "", fontsize=7, va="top", family="monospace")
        ax.set_title(title, fontsize=9)
        self.fig.subplots_adjust(left=0.12, right=0.88, bottom=0.09, top=0.86, hspace=0.35)

    def draw(self, history: list[dict[str, Any]], scenario: Any) -> np.ndarray:
        """Update the artists to ``history`` and return the frame ``(H, W, 3)`` uint8."""
        if history:
            err = np.array([h["pos_err_m"] for h in history], dtype=float)
            steps = np.arange(1, len(err) + 1)
            ok = np.array([bool(h["gnss_available"]) for h in history])
            if self.one_dimensional:
                self._draw_range(history, ok)
            else:
                self._draw_map(history, ok)
            fin = np.where(np.isfinite(err), err, np.nan)
            self.l_err.set_data(steps, fin)
            self._shade(history, scenario, ok)
            top = np.nanmax(fin) if np.any(np.isfinite(fin)) else 1.0
            self.ax_err.set_xlim(0.5, len(err) + 0.5)
            self.ax_err.set_ylim(0, max(float(top), 1e-6) * 1.1)
            self.status.set_text(self._status(history[-1], len(history), scenario))
        self.fig.canvas.draw()
        if self.human and self.interactive:
            self.fig.canvas.flush_events()
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()  # type: ignore[attr-defined]

    def _draw_map(self, history: list[dict[str, Any]], ok: np.ndarray) -> None:
        truth = np.array([h["truth_pos"] for h in history], dtype=float)
        est = np.array([h["est_pos"] for h in history], dtype=float)
        e0, e1, n0, n1 = _limits(truth)
        self.l_truth.set_data(truth[:, 1], truth[:, 0])
        self.l_est.set_data(est[:, 1], est[:, 0])
        self.l_nognss.set_data(est[~ok, 1], est[~ok, 0])
        self.ax.set_xlim(e0, e1)
        self.ax.set_ylim(n0, n1)
        ell = _ellipse(np.asarray(history[-1]["cov_ne"], dtype=float))
        last = est[-1]
        if ell is not None and np.all(np.isfinite(last)):
            self.l_ell.set_data(last[1] + ell[1], last[0] + ell[0])  # clipped to the axes
        else:
            self.l_ell.set_data([], [])
        inside = np.all(np.isfinite(last)) and e0 <= last[1] <= e1 and n0 <= last[0] <= n1
        if inside:
            self.l_off.set_data([], [])
            self.t_off.set_text("")
            return
        c = np.array([(n0 + n1) / 2, (e0 + e1) / 2])
        d = np.where(np.isfinite(last), last - c, 0.0)
        half = (n1 - n0) / 2
        scale = half / max(float(np.max(np.abs(d))), 1e-9)
        edge = c + d * min(scale, 1.0)
        self.l_off.set_data([edge[1]], [edge[0]])
        self.l_off.set_marker((3, 0, float(np.degrees(np.arctan2(d[0], d[1]))) - 90))
        dist = float(np.linalg.norm(last - truth[-1])) if np.all(np.isfinite(last)) else float("inf")
        self.t_off.set_text(f"estimate off-scale: {dist / 1e3:.3g} km from truth")

    def _draw_range(self, history: list[dict[str, Any]], ok: np.ndarray) -> None:
        t = np.array([float(h.get("t", i)) for i, h in enumerate(history)])
        rng = np.array([h["est_pos"][0] - h["truth_pos"][0] for h in history], dtype=float)
        dop = np.array([float(h.get("extra_err", np.nan)) for h in history])
        sig = np.array([2 * np.sqrt(max(float(h["cov_ne"][0, 0]), 0.0)) for h in history])
        self.l_truth.set_data(t, rng)
        self.l_est.set_data(t, dop)
        self.l_nognss.set_data(t[~ok], rng[~ok])
        self.l_ell.set_data(t, sig)
        self.l_ell2.set_data(t, -sig)
        span = (t[0] - 1e-3, t[-1] + 1e-3) if t[-1] > t[0] else (t[0] - 1, t[0] + 1)
        self.ax.set_xlim(*span)
        self.ax2.set_xlim(*span)
        finite = rng[np.isfinite(rng)]
        lim = max(float(np.percentile(np.abs(finite), 98)) * 1.3, 1.0) if finite.size else 1.0
        self.ax.set_ylim(-lim, lim)  # a diverged tail leaves the plot readable (clipped)
        d = dop[np.isfinite(dop)]
        self.ax2.set_ylim(0, max(float(np.percentile(d, 98)) * 1.3, 1e-3) if d.size else 1.0)

    def _shade(self, history: list[dict[str, Any]], scenario: Any, ok: np.ndarray) -> None:
        for s in self.spans:
            s.remove()
        self.spans = []
        events = np.array([bool(active_events(scenario, float(h.get("t", 0.0)))) for h in history])
        for mask, color in ((~ok, "r"), (events & ok, "C4")):
            idx = np.flatnonzero(mask)
            if idx.size == 0:
                continue
            breaks = np.flatnonzero(np.diff(idx) > 1)
            for a, b in zip(np.r_[idx[0], idx[breaks + 1]], np.r_[idx[breaks], idx[-1]], strict=True):
                self.spans.append(self.ax_err.axvspan(a + 0.5, b + 1.5, color=color, alpha=0.15, lw=0))

    @staticmethod
    def _status(row: dict[str, Any], step: int, scenario: Any) -> str:
        t = float(row.get("t", np.nan))
        knob = np.asarray(row.get("knob", np.nan), dtype=float).reshape(-1)
        knob_s = ", ".join(f"{k:.3g}" for k in knob[:3])
        events = ", ".join(active_events(scenario, t)) or "none"
        ctx = "  ".join(f"{k}={v:.3g}" for k, v in row.get("context", {}).items())
        return (
            f"step {step}  t={t:.4g}s  knob={knob_s}  reward={row['reward']:.3g}  "
            f"err={float(row['pos_err_m']):.3g}m\nevents: {events}  {ctx}"
        )

    def close(self) -> None:
        if self.human:
            import matplotlib.pyplot as plt

            plt.close(self.fig)


def render_track(history: list[dict[str, Any]], title: str, scenario: Any = None) -> np.ndarray:
    """Draw the episode so far on a new figure (one-off; envs reuse a :class:`FrameRenderer`)."""
    return FrameRenderer(title, one_dimensional=title == "SignalTracking").draw(history, scenario)
