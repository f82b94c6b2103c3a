"""One episode, step by step: each policy's knob and error beside the regimes of the episode.

The evaluation tables average over episodes; this answers "what did the agent *do*?". Every
policy plays the same seeded episode (an episode is fixed by env id, keyword arguments and seed)
in a one-row native vector env; the trace keeps the knob the filter applied at every step
(``info["knob"]``, in filter units: a fading factor, per-row outlier weights, Q/R scales) and the
horizontal error, and the episode's :class:`~navgym.scenarios.Scenario` (from ``reset``'s info)
gives the regimes: outages, jamming, urban canyons, multipath on one row, process-noise bursts.
The scenario is the simulator's truth: it is drawn for the reader, never shown to a policy.
Where the observation carries per-row context (the v3 ids' ``row_cn0``: the C/N0 the receiver
reports for each row), the trace keeps it too: it is what a policy could read, unlike the regimes.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from agents.evaluation.runner import make_vector_env, native_vector_env
from agents.policy_runner import PredictRunner
from navgym.scenarios import Scenario

__all__ = ["CONTEXT_FEATURES", "EpisodeTrace", "REGIME_FIELDS", "episode_trace", "plot_episode_trace"]

#: Observed per-row context features a trace keeps where the observation has them.
CONTEXT_FEATURES = ("row_cn0",)

#: Scenario fields drawn as regime bars, in drawing order: ``(field, label, colour)``.
REGIME_FIELDS = (
    ("outages", "GNSS outage", "0.45"),
    ("partial_outages", "partial outage", "0.65"),
    ("canyons", "urban canyon", "tab:brown"),
    ("jamming", "jamming", "tab:purple"),
    ("impulsive", "impulsive noise", "tab:pink"),
    ("bursts", "process-noise burst", "tab:orange"),
    ("multipath", "multipath", "tab:red"),
)


class EpisodeTrace(NamedTuple):
    """Per-step records of one episode played by several policies.

    Attributes:
        env_id: the environment.
        seed: the episode's reset seed.
        t: ``(T,)`` time of each step [s] (the shortest episode's length if one diverged).
        knob: ``{policy: (T_p, K)}`` the knob the filter applied at each step.
        pos_err_m: ``{policy: (T_p,)}`` horizontal position error [m].
        scenario: the episode's :class:`~navgym.scenarios.Scenario` (truth: for the plot only).
        context: ``{feature: (T, m)}`` observed per-row context of :data:`CONTEXT_FEATURES`
            (the first policy's episode; sensor outputs, the same whatever the filter does).
        knob_labels: a name per knob component (:func:`knob_labels`).
    """

    env_id: str
    seed: int
    t: np.ndarray
    knob: dict[str, np.ndarray]
    pos_err_m: dict[str, np.ndarray]
    scenario: Any
    context: dict[str, np.ndarray] = {}
    knob_labels: tuple[str, ...] = ()


def knob_labels(task: Any, size: int) -> tuple[str, ...]:
    """Names of a task's knob components, for plot legends.

    ``s_q, s_r`` (NoiseScale), ``row 0 .. row m-1, s_q`` (RowScale), ``row k`` for other vectors,
    ``knob`` for a scalar.
    """
    from navgym.envs.tasks import NoiseScaleTask, RowScaleTask

    if isinstance(task, NoiseScaleTask) and size == 2:
        return ("s_q", "s_r")
    if isinstance(task, RowScaleTask) and size == task.m_max + 1:
        return (*(f"row {j}" for j in range(task.m_max)), "s_q")
    return ("knob",) if size == 1 else tuple(f"row {j}" for j in range(size))


def episode_trace(
    env_id: str,
    policies: Mapping[str, Any],
    seed: int,
    env_kwargs: Mapping[str, Any] | None = None,
) -> EpisodeTrace:
    """Play episode ``seed`` of ``env_id`` once per policy and record knob and error per step.

    Args:
        env_id: registered id whose info carries ``knob`` and ``pos_err_m``.
        policies: ``{label: policy}``, anything with SB3's ``predict`` (state carried per step).
        seed: the reset seed (the same episode for every policy).
        env_kwargs: env keyword arguments.
    """
    if not policies:
        raise ValueError("policies is empty: give at least one {label: policy}")
    env = make_vector_env(env_id, 1, env_kwargs)
    nav = native_vector_env(env)
    features = nav.observation_features
    columns = {n: features.index(n) for n in CONTEXT_FEATURES if n in features.names}
    knob: dict[str, np.ndarray] = {}
    err: dict[str, np.ndarray] = {}
    context: dict[str, list[np.ndarray]] = {n: [] for n in columns}
    scenario = None
    for i, (label, policy) in enumerate(policies.items()):
        obs, info = env.reset(seed=[int(seed)])
        scenario = info["scenario"][0]
        runner = PredictRunner(policy, deterministic=True)
        runner.reset()
        stepper = nav.episode_stepper()
        k_rows, e_rows = [], []
        for _ in range(nav.horizon):
            obs, _, term, trunc, info = stepper.step(runner.act(obs))
            for feature, cols in columns.items():
                if i == 0:
                    context[feature].append(np.asarray(obs, dtype=np.float64)[0, cols])
            if "knob" not in info or "pos_err_m" not in info:
                raise ValueError(f"{env_id}: its info has no 'knob' / 'pos_err_m' to trace")
            k_rows.append(np.asarray(info["knob"], dtype=np.float64).reshape(1, -1)[0])
            e_rows.append(float(np.asarray(info["pos_err_m"]).reshape(-1)[0]))
            if bool(np.asarray(term).reshape(-1)[0]) or bool(np.asarray(trunc).reshape(-1)[0]):
                break
        knob[label], err[label] = np.array(k_rows), np.array(e_rows)
    env.close()
    n = max(len(e) for e in err.values())
    t = (np.arange(n) + 1) * float(nav.platform.dt)
    observed = {k: np.array(v) for k, v in context.items()}
    labels = knob_labels(nav.task, next(iter(knob.values())).shape[1])
    return EpisodeTrace(env_id, int(seed), t, knob, err, scenario, observed, labels)


def _regime_rows(scenario: Any) -> list[tuple[str, str, list[tuple[float, float]]]]:
    """``(label, colour, [(start, end), ...])`` per regime lane; multipath: one lane per row.

    Anything but a :class:`~navgym.scenarios.Scenario` has no lanes.
    """
    if not isinstance(scenario, Scenario):
        return []
    lanes = []
    for field, label, colour in REGIME_FIELDS:
        events = tuple(getattr(scenario, field))  # a field of Scenario, named in REGIME_FIELDS
        if field == "multipath":
            for row in sorted({int(e.row) for e in events}):
                spans = [(float(e.start), float(e.end)) for e in events if int(e.row) == row]
                lanes.append((f"multipath row {row}", colour, spans))
        elif events:
            lanes.append((label, colour, [(float(e.start), float(e.end)) for e in events]))
    return lanes


def plot_episode_trace(trace: EpisodeTrace, path: str | Path, title: str = "") -> Path:
    """Knob of each policy over time, the regimes beneath, then the errors; writes ``path`` (PNG).

    One knob panel per policy (a line per knob component: ``row k`` for per-row weights; a log
    axis where the knob spans more than two decades, as RowScale's multipliers), the observed
    per-row C/N0 where the trace has it, a lane per regime of the scenario (multipath: a lane per
    affected row), and the horizontal error of every policy on a log axis.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(trace.knob)
    lanes = _regime_rows(trace.scenario)
    cn0 = trace.context.get("row_cn0")
    heights = [1.6] * len(names) + ([1.4] if cn0 is not None else []) + [0.35 * max(len(lanes), 1) + 0.4, 1.8]
    fig, axes = plt.subplots(
        len(heights),
        1,
        figsize=(9.5, sum(heights) + 0.8),
        sharex=True,
        gridspec_kw={"height_ratios": heights},
    )
    for ax, name in zip(axes, names, strict=False):
        k = trace.knob[name]
        t = trace.t[: k.shape[0]]
        labels = trace.knob_labels or knob_labels(None, k.shape[1])
        for j in range(k.shape[1]):
            ax.step(t, k[:, j], where="post", lw=1.0, label=labels[j])
        positive = k[np.isfinite(k)]
        if positive.size and positive.min() > 0 and positive.max() / positive.min() > 100.0:
            ax.set_yscale("log")
        ax.set_ylabel("knob", fontsize=8)
        ax.set_title(f"{name}: knob applied by the filter", fontsize=9, loc="left")
        ax.grid(alpha=0.3)
        if k.shape[1] > 1:
            ax.legend(fontsize=6, ncol=min(k.shape[1], 13), loc="upper right")
    end = float(trace.t[-1]) if trace.t.size else 0.0
    if cn0 is not None:
        ax = axes[len(names)]
        t = trace.t[: cn0.shape[0]]
        for j in range(cn0.shape[1]):
            ax.step(t, np.where(cn0[:, j] > 0, cn0[:, j], np.nan), where="post", lw=0.9, label=f"row {j}")
        ax.set_ylabel("dB-Hz", fontsize=8)
        ax.set_title(
            "C/N0 the receiver reports per row (observed; blank: row not received)", fontsize=9, loc="left"
        )
        ax.grid(alpha=0.3)
    ax = axes[len(names) + (cn0 is not None)]
    for i, (_, colour, spans) in enumerate(lanes):
        clipped = [(a, min(b, end) - a) for a, b in spans if a < end]
        ax.broken_barh(clipped, (i - 0.4, 0.8), color=colour)
    ax.set_yticks(range(len(lanes)), [lane[0] for lane in lanes], fontsize=7)
    ax.set_ylim(-0.6, max(len(lanes), 1) - 0.4)
    ax.invert_yaxis()
    ax.set_title("regimes of the episode (the simulator's truth, never observed)", fontsize=9, loc="left")
    ax.grid(alpha=0.3, axis="x")
    ax = axes[-1]
    for name in names:
        e = trace.pos_err_m[name]
        ax.plot(trace.t[: e.size], e, lw=1.0, label=f"{name} (RMSE {np.sqrt(np.mean(e**2)):.2f} m)")
    ax.set_yscale("log")
    ax.set_ylabel("horizontal error [m]", fontsize=8)
    ax.set_xlabel("time [s]")
    ax.set_xlim(0.0, end)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.suptitle(title or f"{trace.env_id}, episode seed {trace.seed}", fontsize=10)
    fig.tight_layout()
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=110)
    plt.close(fig)
    return p
