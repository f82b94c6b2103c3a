"""What the agent controls, shared across platforms: fading, mixture weights, resampling.

A task owns the filter state, maps the agent's action to the filter's knob, runs one filter
step with that knob, and adds its own observation features and reward cost.

* :class:`FadingTask` — fading factor ``lambda >= 1`` of any Gaussian filter of
  :mod:`filters.registry`, applied at each prediction (``P- = lambda F P F^T + Q``; Benzerrouk
  2014, eq. 63-70, gives the classical formulas). Action ``a in [-1, 1]`` maps log-linearly:
  ``lambda = lambda_max ** ((a + 1) / 2)`` (``a = -1`` is the plain filter).
* :class:`MixtureTask` — prior weight ``eps`` of the outlier component of a two-component
  Gaussian-mixture measurement noise ``(1 - eps) N(0, R) + eps N(0, ratio R)`` (Benzerrouk
  2014, eq. 71) in a Gaussian-sum filter (eq. 72-76). ``eps = eps_max (a + 1) / 2``.
* :class:`ResampleTask` — a bootstrap particle filter's decision to resample now
  (``Discrete(2)``), i.e. the particles as they stand after the last update (whose ESS the
  agent observes), before this step's prediction; each resampling costs ``resample_cost``.
  With ``roughening = K > 0`` the resampled particles are roughened (Gordon, Salmond & Smith
  1993: ``x_ij += K E_j N^(-1/n) e_ij``, ``E_j`` the spread of component j), so resampling both
  restores diversity and adds noise: the decision has a real trade-off.
"""

from __future__ import annotations

import inspect
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from filters import GaussianState, gaussian_sum
from filters import get as get_filter
from filters.core.types import ParticleState, UpdateInfo
from filters.particle import bootstrap, estimates, regularization
from filters.particle.triggers import redistribution_trigger
from navgym.envs.features import Feature
from navgym.envs.protocols import ReducibleObservation, StepModels, TaskStep


def _check_box_action(action: np.ndarray, B: int, dim: int) -> tuple[np.ndarray, np.ndarray]:
    a = np.asarray(action, dtype=np.float64).reshape(B, dim)
    if not np.isfinite(a).all():
        raise ValueError("action must be finite (got NaN or inf)")
    clipped = (a < -1.0) | (a > 1.0)
    return np.clip(a, -1.0, 1.0), clipped.any(axis=1)


class FadingTask:
    """The agent sets the fading factor of a Gaussian filter each step."""

    name = "Fading"

    def __init__(self, filter: str = "ekf", lambda_max: float = 10.0) -> None:  # noqa: A002
        if not lambda_max > 1.0:
            raise ValueError(f"lambda_max must be > 1; got {lambda_max}")
        self.filter_name = filter
        self.filter = get_filter(filter)
        self.lambda_max = float(lambda_max)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        a, clipped = _check_box_action(action, B, 1)
        return self.lambda_max ** ((a[:, 0] + 1.0) / 2.0), clipped

    def neutral_action(self) -> np.ndarray:
        return np.array([-1.0], dtype=np.float32)

    def init_state(self, belief: GaussianState, rngs: Sequence[np.random.Generator]) -> GaussianState:
        return belief

    def step(self, state: GaussianState, knob: np.ndarray, models: StepModels, rngs) -> TaskStep:
        pred = self.filter.predict(state, models.transition, None, models.dt, fading=knob)
        H = models.observation.H(pred.m)  # once: for the update and for the traces
        observation = JacobianAt(models.observation, pred.m, H)
        post, info = self.filter.update(pred, models.z, observation, mask=models.mask)
        extras = {"fading": knob, **fading_traces(pred, info, models, knob, H)}
        return TaskStep(post, post, info, pred.P, np.zeros(len(knob)), extras)

    def features(self) -> list[Feature]:
        return [
            Feature(name, -8.0, 12.0, "log10", text)
            for name, text in (
                ("log_tr_vv", "log10 |v|^2 over the rows used (innovation energy)"),
                ("log_tr_R", "log10 tr R over the rows used"),
                ("log_tr_HQH", "log10 tr(H Q H^T) over the rows used (Benzerrouk 2014, eq. 68)"),
                ("log_tr_M", "log10 tr(H F P F^T H^T) over the rows used (Benzerrouk 2014, eq. 69)"),
            )
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {f.name: np.zeros(B) for f in self.features()}

    def feature_values(self, step: TaskStep) -> dict[str, np.ndarray]:
        return {
            k: np.log10(np.maximum(step.extras[k[4:]], 1e-8))
            for k in ("log_tr_vv", "log_tr_R", "log_tr_HQH", "log_tr_M")
        }


class JacobianAt:
    """An observation model whose Jacobian at the point ``x`` is already known.

    ``H(x)`` returns the given Jacobian for that very array (``x is self.x``) and asks the model
    otherwise; every other attribute is the model's. The fading task evaluates ``H`` at the
    predicted mean once, for the EKF update and for the traces of :func:`fading_traces`.
    """

    def __init__(self, model: Any, x: np.ndarray, H: np.ndarray) -> None:
        self.model, self.x, self.H_x = model, x, H

    def H(self, x: np.ndarray) -> np.ndarray:
        return self.H_x if x is self.x else self.model.H(x)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.model, name)


def fading_traces(
    pred: GaussianState, info, models: StepModels, lam: np.ndarray, H: np.ndarray | None = None
) -> dict[str, np.ndarray]:
    """Traces over the used rows that the classical fading formulas need (Benzerrouk 2014, eq. 67-70).

    ``tr_vv = |v|^2``, ``tr_R``, ``tr_HQH = tr(H Q H^T)`` with ``H`` the observation Jacobian at
    the predicted mean, and ``tr_M = tr(H F P F^T H^T) = (tr S - tr R - tr HQH) / lambda`` from
    the innovation covariance ``S = H (lambda F P F^T + Q) H^T + R`` of the applied factor. A
    baseline keeps its own ``V_k`` recursion on ``tr_vv`` (traces are linear), so these four
    numbers per step are all the formulas need; they are published in the observation. ``H``,
    when given, is that Jacobian (else it is evaluated).
    """
    w = models.mask.astype(np.float64)
    R = np.broadcast_to(models.observation.R, info.S.shape)
    tr_R = np.einsum("bii,bi->b", R, w)
    B, m, n = w.shape[0], w.shape[1], pred.m.shape[1]
    H = np.broadcast_to(models.observation.H(pred.m) if H is None else H, (B, m, n))
    Q = np.asarray(models.transition.Q)
    HQ = (H.reshape(B * m, n) @ Q).reshape(B, m, n) if Q.ndim == 2 else H @ Q
    tr_HQH = np.einsum("bjk,bjk,bj->b", HQ, H, w)
    tr_S = np.einsum("bii,bi->b", info.S, w)
    tr_M = np.maximum(tr_S - tr_R - tr_HQH, 0.0) / lam
    return {"tr_vv": (info.innovation**2 * w).sum(axis=1), "tr_R": tr_R, "tr_HQH": tr_HQH, "tr_M": tr_M}


class MixtureTask:
    """The agent sets the outlier weight of a Gaussian-sum filter's noise mixture each step."""

    name = "Mixture"

    def __init__(
        self,
        filter: str = "ckf",  # noqa: A002
        eps_max: float = 0.5,
        variance_ratio: float = 100.0,
        outlier_rows: tuple[int, ...] | None = None,
    ) -> None:
        if not 0.0 < eps_max < 1.0:
            raise ValueError(f"eps_max must lie in (0, 1); got {eps_max}")
        if not variance_ratio > 1.0:
            raise ValueError(f"variance_ratio must be > 1; got {variance_ratio}")
        self.filter_name = filter
        self.base = get_filter(filter)
        self.eps_max = float(eps_max)
        self.variance_ratio = float(variance_ratio)
        #: Rows subject to impulsive noise, the platform's ``outlier_rows`` (None: every row).
        self.outlier_rows = None if outlier_rows is None else tuple(int(r) for r in outlier_rows)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(1,), dtype=np.float32)

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        a, clipped = _check_box_action(action, B, 1)
        return self.eps_max * (a[:, 0] + 1.0) / 2.0, clipped

    def neutral_action(self) -> np.ndarray:
        return np.array([-1.0], dtype=np.float32)

    def init_state(self, belief: GaussianState, rngs) -> GaussianState:
        return belief

    def step(self, state: GaussianState, knob: np.ndarray, models: StepModels, rngs) -> TaskStep:
        B = len(knob)
        pred = self.base.predict(state, models.transition, None, models.dt)
        R = np.asarray(models.observation.R)  # (m, m) shared or (B, m, m)
        # The outlier component inflates the rows the platform declares as impulsive (default:
        # all): R2 = D R D with D = sqrt(ratio) on those rows, 1 elsewhere (Benzerrouk 2014, eq. 71 per row).
        d = np.ones(R.shape[-1])
        rows = self.outlier_rows
        d[slice(None) if rows is None else list(rows)] = np.sqrt(self.variance_ratio)
        # (K, m, m) when R is shared by the batch (no per-step (B, K, m, m) copy), else (B, K, m, m)
        R_components = np.stack([R, d[:, None] * R * d[None, :]], axis=-3)
        weights = np.stack([1.0 - knob, knob], axis=1)
        post, info = gaussian_sum.update(
            pred,
            models.z,
            models.observation,
            models.mask,
            R_components=R_components,
            weights=weights,
            base=self.base,
        )
        outlier_posterior = np.exp(info.log_weights[:, 1])
        return TaskStep(
            post, post, info, pred.P, np.zeros(B), {"eps": knob, "outlier_posterior": outlier_posterior}
        )

    def features(self) -> list[Feature]:
        return [
            Feature(
                "outlier_posterior", 0.0, 1.0, "-", "posterior weight of the outlier noise component (eq. 74)"
            )
        ]

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        return {"outlier_posterior": np.zeros(B)}

    def feature_values(self, step: TaskStep) -> dict[str, np.ndarray]:
        return {"outlier_posterior": step.extras["outlier_posterior"]}


class ParticleBelief(NamedTuple):
    """Particle filter state plus the resampling count of the episode."""

    particles: Any  # ParticleState
    resamples: np.ndarray  # (B,) resamplings so far


class ResampleTask:
    """The agent decides when a bootstrap particle filter resamples; each resampling costs."""

    name = "Resample"

    def __init__(
        self,
        n_particles: int = 1000,
        resample_cost: float = 0.05,
        method: str = "systematic",
        roughening: float = 0.0,
        log_ess_feature: bool = False,
        particle_dtype: str = "float32",
    ) -> None:
        if particle_dtype not in ("float32", "float64"):
            raise ValueError(f"particle_dtype must be 'float32' or 'float64'; got {particle_dtype!r}")
        if not isinstance(n_particles, (int, np.integer)) or n_particles < 1:
            raise ValueError(f"n_particles must be an integer >= 1; got {n_particles!r}")
        if not resample_cost >= 0:
            raise ValueError(f"resample_cost must be >= 0; got {resample_cost}")
        if not (np.isfinite(roughening) and roughening >= 0):
            raise ValueError(f"roughening must be a finite number >= 0; got {roughening}")
        self.filter_name = (
            f"pf{n_particles}"
            + ("/f32" if particle_dtype == "float32" else "")
            + (f"+rough{roughening:g}" if roughening else "")
        )
        self.n_particles = int(n_particles)
        self.resample_cost = float(resample_cost)
        self.method = method
        #: Roughening constant K of Gordon, Salmond & Smith (1993) applied after each resampling
        #: (0: none). Without it a filter whose states carry almost no process noise (Carvalho et al. 1997's
        #: INS errors) collapses onto a few distinct particles at every resampling.
        self.roughening = float(roughening)
        #: Also observe ``log10(ESS / N)`` (in ``[-log10 N, 0]``): the collapsed-cloud range
        #: (ESS/N of 1e-3 vs 1e-2) is invisible in the linear ``ess_frac`` once standardized.
        self.log_ess_feature = bool(log_ess_feature)
        #: Precision of the particle cloud (weights, moments and diagnostics stay float64).
        #: float32 halves the memory traffic of every pass over the B x N particles; pseudo-range
        #: models are weighed "observed minus computed" (their ``reduced``), so no innovation
        #: precision is lost.
        self.particle_dtype = np.dtype(particle_dtype)
        self.action_space = spaces.Discrete(2)

    @property
    def options(self) -> dict[str, Any]:
        """The keyword arguments that rebuild this task (every parameter of ``__init__``)."""
        names = [p for p in inspect.signature(ResampleTask.__init__).parameters if p != "self"]
        return {p: getattr(self, p) for p in names}

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        a = np.asarray(action).reshape(B)
        if not np.issubdtype(a.dtype, np.integer):
            if not np.isfinite(a.astype(np.float64)).all():
                raise ValueError("action must be finite (got NaN or inf)")
            if (a != np.round(a)).any():  # 0.9 would silently mean "keep" (and show as 0.9)
                raise ValueError(f"action must be 0 or 1 (Discrete(2)); got {np.unique(a)}")
        d = a.astype(np.int64)
        if ((d != 0) & (d != 1)).any():
            raise ValueError(f"action must be 0 or 1 (Discrete(2)); got {np.unique(d)}")
        return d.astype(bool), np.zeros(B, dtype=bool)

    def neutral_action(self) -> np.ndarray:
        return np.array(0, dtype=np.int64)

    def init_state(self, belief: GaussianState, rngs) -> ParticleBelief:
        # "structure of arrays": every element-wise pass of the filter runs along the particles
        particles = bootstrap.from_gaussian(belief.m, belief.P, self.n_particles, list(rngs), layout="soa")
        particles = particles._replace(x=particles.x.astype(self.particle_dtype))  # keeps the layout
        return ParticleBelief(particles, np.zeros(belief.m.shape[0]))

    def step(self, state: ParticleBelief, knob: np.ndarray, models: StepModels, rngs) -> TaskStep:
        rngs = list(rngs)
        # "Resample now": the decision applies to the particles as the agent last saw them
        # (after the previous update, whose ESS is in the observation), then predict + update.
        particles = bootstrap.resample(state.particles, knob, rngs, self.method)
        if self.roughening > 0:
            particles = regularization.roughen(particles, rngs, K=self.roughening, decision=knob)
        post, info = self.filter_step(particles, models, rngs)
        info = info._replace(resampled=knob)
        belief = estimates.mean_and_covariance(post)
        n_eff = info.ess / self.n_particles
        tiny = redistribution_trigger(post.log_w)
        cost = self.resample_cost * knob.astype(np.float64)
        new = ParticleBelief(post, state.resamples + knob)
        extras = {
            "ess_frac": n_eff,
            "resampled": knob,
            "redistribution_rule": tiny,
            "resamples": new.resamples,
        }
        # The predicted particle covariance is not computed (one more weighted covariance pass
        # over B x N particles); particle tasks publish no info["predicted_cov"].
        return TaskStep(new, belief, info, None, cost, extras)

    def filter_step(
        self, particles: ParticleState, models: StepModels, rngs
    ) -> tuple[ParticleState, UpdateInfo]:
        """Bootstrap predict + update of the (resampled) cloud: Touil & Ghadi 2012, eq. 15-16.

        Pseudo-range models with a ``reduced`` form are weighed "observed minus computed" for
        float32 clouds (the same likelihood in metres-sized numbers). A subclass may replace the
        filter step (e.g. ``experiments.critical_scenario``'s n-conditional exploration).
        """
        pred = bootstrap.predict(particles, models.transition, None, models.dt, rng=rngs)
        obs, z = self.observation(models)
        return bootstrap.update(pred, z, obs, mask=models.mask)

    def observation(self, models: StepModels) -> tuple[Any, np.ndarray]:
        """The observation model and measurements the particles are weighed with."""
        obs, z = models.observation, models.z
        if self.particle_dtype == np.float32 and isinstance(obs, ReducibleObservation):
            obs, z = obs.reduced(z)  # same likelihood, metres-sized numbers
        return obs, z

    def features(self) -> list[Feature]:
        return [
            Feature("ess_frac", 0.0, 1.0, "-", "effective sample size after the update / N"),
            Feature(
                "redistribution_rule",
                0.0,
                1.0,
                "-",
                "1 when Carvalho et al. 1997's redistribution rule fires",
            ),
        ] + (
            [Feature("log_ess_frac", -float(np.log10(self.n_particles)), 0.0, "log10", "log10(ESS / N)")]
            if self.log_ess_feature
            else []
        )

    def initial_feature_values(self, B: int) -> dict[str, np.ndarray]:
        """At reset the particles carry equal weights: ESS/N = 1."""
        return {"ess_frac": np.ones(B), "redistribution_rule": np.zeros(B)} | (
            {"log_ess_frac": np.zeros(B)} if self.log_ess_feature else {}
        )

    def feature_values(self, step: TaskStep) -> dict[str, np.ndarray]:
        return {
            "ess_frac": step.extras["ess_frac"],
            "redistribution_rule": step.extras["redistribution_rule"],
            **(
                {"log_ess_frac": np.log10(np.clip(step.extras["ess_frac"], 1.0 / self.n_particles, 1.0))}
                if self.log_ess_feature
                else {}
            ),
        }


TASKS = {"fading": FadingTask, "mixture": MixtureTask, "resample": ResampleTask}


def make_task(
    task: str, outlier_rows: tuple[int, ...] | None = None, **kwargs: Any
) -> FadingTask | MixtureTask | ResampleTask:
    """Build a task by name (``"fading" | "mixture" | "resample"``).

    ``outlier_rows`` (the platform's rows subject to impulsive noise) is used by the Mixture
    task; the other keyword arguments are the task's own.
    """
    try:
        cls = TASKS[task.lower()]
    except (KeyError, AttributeError):
        raise ValueError(f"task must be one of {sorted(TASKS)}; got {task!r}") from None
    if cls is MixtureTask:
        kwargs["outlier_rows"] = outlier_rows
    return cls(**kwargs)


__all__ = ["FadingTask", "MixtureTask", "ResampleTask", "TaskStep", "make_task"]
