"""The Resample task: a bootstrap particle filter's decision to resample now.

``Discrete(2)``: resample the particles as they stand after the last update (whose ESS the agent
observes), before this step's prediction; each resampling costs ``resample_cost``. With
``roughening = K > 0`` the resampled particles are roughened (Gordon, Salmond & Smith 1993:
``x_ij += K E_j N^(-1/n) e_ij``, ``E_j`` the spread of component j), so resampling both restores
diversity and adds noise: the decision has a real trade-off.
"""

from __future__ import annotations

import inspect
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from gymnasium import spaces

from filters import GaussianState
from filters.core.compiled import compiled_enabled
from filters.core.resampling import RESAMPLERS
from filters.core.types import ParticleState, UpdateInfo
from filters.particle import bootstrap, estimates, regularization
from filters.particle.triggers import redistribution_trigger
from navgym.envs.arguments import Argument, Choice, Flag, Integer, Real
from navgym.envs.features import Feature
from navgym.envs.protocols import ReducibleObservation, StepModels, TaskStep
from navgym.envs.tasks.actions import check_action
from navgym.envs.tasks.registry import TaskSpec, register_task

#: Largest particle count of the Resample task: a batch holds B x N x n particle entries, so N is
#: bounded to keep one sub-env's cloud at most 10**6 particles (8 MB per state dimension).
MAX_PARTICLES = 10**6
#: Largest roughening constant K of the Resample task (Gordon, Salmond & Smith 1993 use K ~ 0.2;
#: beyond a few spreads the jitter swamps the cloud and the arithmetic degenerates).
MAX_ROUGHENING = 10.0


class ParticleBelief(NamedTuple):
    """Particle filter state, the resampling count of the episode and the linear weights."""

    particles: ParticleState
    resamples: np.ndarray  # (B,) resamplings so far
    #: (B, N) the normalized linear weights exp(particles.log_w), as the update computed them:
    #: the compiled path resamples, weighs, takes moments and applies the redistribution rule
    #: with them instead of exponentiating the log-weights again in each of those steps
    weights: np.ndarray


class FilterStep(NamedTuple):
    """:meth:`ResampleTask.filter_step`'s result."""

    state: ParticleState  #: the filtered particles
    info: UpdateInfo  #: the update's diagnostics
    weights: np.ndarray | None  #: ``(B, N)`` ``exp(state.log_w)`` if the step computed them


class ResampleDiagnostics(NamedTuple):
    """The Resample task's diagnostics of a step (keys of ``info``; ESS feeds the features)."""

    ess_frac: np.ndarray  #: (B,) effective sample size after the update / N
    resampled: np.ndarray  #: (B,) the decision (bool)
    redistribution_rule: np.ndarray  #: (B,) Carvalho et al. 1997's redistribution rule fires
    resamples: np.ndarray  #: (B,) resamplings of the episode so far


#: The Resample task's keyword arguments.
ARGUMENTS = (
    Argument("n_particles", 1000, Integer(1, MAX_PARTICLES), "particles N of the bootstrap filter"),
    Argument("resample_cost", 0.05, Real(0.0), "reward cost of one resampling"),
    Argument("method", "systematic", Choice(tuple(RESAMPLERS)), "the resampling scheme"),
    Argument(
        "roughening", 0.0, Real(0.0, MAX_ROUGHENING), "roughening constant K after a resampling (0: none)"
    ),
    Argument("log_ess_feature", False, Flag(), "also observe log10(ESS / N)"),
    Argument(
        "particle_dtype",
        "float32",
        Choice(("float32", "float64")),
        "the cloud's precision (weights, moments and diagnostics stay float64)",
    ),
)
_N, _COST, _METHOD, _ROUGHENING, _LOG_ESS, _DTYPE = ARGUMENTS


class ResampleTask:
    """The agent decides when a bootstrap particle filter resamples; each resampling costs."""

    name = "Resample"
    baseline_family = "Resample"

    def __init__(
        self,
        n_particles: int = 1000,
        resample_cost: float = 0.05,
        method: str = "systematic",
        roughening: float = 0.0,
        log_ess_feature: bool = False,
        particle_dtype: str = "float32",
    ) -> None:
        if isinstance(particle_dtype, np.dtype) or (
            isinstance(particle_dtype, type) and issubclass(particle_dtype, np.generic)
        ):
            particle_dtype = np.dtype(particle_dtype).name  # as ``options`` gives it back
        particle_dtype = _DTYPE.check(particle_dtype)
        n_particles = _N.check(n_particles)
        resample_cost = _COST.check(resample_cost)
        method = _METHOD.check(method)
        roughening = _ROUGHENING.check(roughening)
        log_ess_feature = _LOG_ESS.check(log_ess_feature)
        self.filter_name = (
            f"pf{n_particles}"
            + ("/f32" if particle_dtype == "float32" else "")
            + (f"+rough{roughening:g}" if roughening else "")
        )
        self.n_particles = n_particles
        self.resample_cost = resample_cost
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
        self.action_space: spaces.Space = spaces.Discrete(2)

    @property
    def options(self) -> dict[str, Any]:
        """The keyword arguments that rebuild this task (every parameter of ``__init__``)."""
        names = [p for p in inspect.signature(ResampleTask.__init__).parameters if p != "self"]
        return {p: getattr(self, p) for p in names}

    def knob(self, action: np.ndarray, B: int) -> tuple[np.ndarray, np.ndarray]:
        d, clipped = check_action(action, self.action_space, B)
        return d.astype(bool), clipped

    def neutral_action(self) -> np.ndarray:
        return np.array(0, dtype=np.int64)

    def init_state(self, belief: GaussianState, rngs: Sequence[np.random.Generator]) -> ParticleBelief:
        # "structure of arrays": every element-wise pass of the filter runs along the particles
        particles = bootstrap.from_gaussian(belief.m, belief.P, self.n_particles, list(rngs), layout="soa")
        particles = particles._replace(x=particles.x.astype(self.particle_dtype))  # keeps the layout
        B = belief.m.shape[0]
        return ParticleBelief(particles, np.zeros(B), np.full((B, self.n_particles), 1.0 / self.n_particles))

    def step(
        self,
        state: ParticleBelief,
        knob: np.ndarray,
        models: StepModels,
        rngs: Sequence[np.random.Generator],
    ) -> TaskStep[ParticleBelief, ResampleDiagnostics]:
        rngs = list(rngs)
        # The compiled path carries the update's linear weights (ParticleBelief.weights) into the
        # moments, the rule, the next resampling and the next update; the NumPy path, which the
        # recorded traces hold, computes each from the log-weights as before.
        carried = compiled_enabled()
        # "Resample now": the decision applies to the particles as the agent last saw them
        # (after the previous update, whose ESS is in the observation), then predict + update.
        particles = bootstrap.resample(
            state.particles, knob, rngs, self.method, weights=state.weights if carried else None
        )
        prior_weights = None
        if carried:
            prior_weights = state.weights.copy()
            prior_weights[knob] = 1.0 / self.n_particles  # resampled rows: log_w = -log N
        if self.roughening > 0:
            particles = regularization.roughen(particles, rngs, K=self.roughening, decision=knob)
        post, info, weights = self.filter_step(particles, models, rngs, prior_weights)
        if weights is None:
            weights = estimates.weights(post.log_w)
        info = info._replace(resampled=knob)
        belief = estimates.mean_and_covariance(post, weights=weights if carried else None)
        cost = self.resample_cost * knob.astype(np.float64)
        new = ParticleBelief(post, state.resamples + knob, weights)
        rule = redistribution_trigger(post.log_w, weights=weights if carried else None)
        diagnostics = ResampleDiagnostics(np.asarray(info.ess) / self.n_particles, knob, rule, new.resamples)
        # The predicted particle covariance is not computed (one more weighted covariance pass
        # over B x N particles); particle tasks publish no info["predicted_cov"].
        return TaskStep(new, belief, info, None, cost, knob, diagnostics)

    def filter_step(
        self,
        particles: ParticleState,
        models: StepModels,
        rngs: Sequence[np.random.Generator],
        prior_weights: np.ndarray | None = None,
    ) -> FilterStep:
        """Bootstrap predict + update of the (resampled) cloud: Touil & Ghadi 2012, eq. 15-16.

        Pseudo-range models with a ``reduced`` form are weighed "observed minus computed" for
        float32 clouds (the same likelihood in metres-sized numbers). ``prior_weights``: the
        normalized linear weights of ``particles.log_w`` if the caller has them (None: computed).
        A subclass may replace the filter step (e.g. ``experiments.critical_scenario``'s
        n-conditional exploration) and return ``weights=None``.
        """
        pred = bootstrap.predict(particles, models.transition, None, models.dt, rng=rngs)
        obs, z = self.observation(models)
        return FilterStep(
            *bootstrap.update_weighted(pred, z, obs, mask=models.mask, prior_weights=prior_weights)
        )

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

    def feature_values(self, step: TaskStep[ParticleBelief, ResampleDiagnostics]) -> dict[str, np.ndarray]:
        d = step.diagnostics
        return {
            "ess_frac": d.ess_frac,
            "redistribution_rule": d.redistribution_rule,
            **(
                {"log_ess_frac": np.log10(np.clip(d.ess_frac, 1.0 / self.n_particles, 1.0))}
                if self.log_ess_feature
                else {}
            ),
        }


def state_bytes(task: ResampleTask, platform: Any) -> int:
    """Bytes of one episode's particle cloud at its peak in a step (``TaskSpec.state_bytes``).

    Per particle, with ``n`` the state size and ``s`` the cloud's item size (4 or 8): the cloud
    as the step holds it four times over (before and after the resampling, after the roughening
    and after the prediction; ``4 n s``), two float64 draws of the state's size (the roughening's
    and the prediction's normals; ``16 n``) and eight float64 values per particle (log-weights,
    weights, their normalization, ancestors and the likelihood terms; 64).
    """
    n = int(platform.n)
    return int(task.n_particles) * ((4 * task.particle_dtype.itemsize + 16) * n + 64)


#: The Version History lines of the cards of platforms with a Resample task.
RESAMPLE_VERSION_HISTORY = """\
* v1 (Resample): the same remaining-steps penalty; the particles are roughened after each
  resampling (Gordon, Salmond & Smith 1993, ``roughening=0.2``): without it, states with almost
  no process noise collapse onto a few particles and every resampling policy loses to "never";
  the observation adds ``log_ess_frac = log10(ESS/N)`` (``log_ess_feature=True``).
* navgym 0.2.0 (no version bump: the distributions are unchanged): the Resample envs' particle
  filter draws its normals by Box-Muller from raw 64-bit words (``filters.core.normal``),
  component-major, into a float32 cloud (``particle_dtype``), so a given seed yields other
  particle draws than in navgym 0.1.0 (figures published with 0.1.0 are not bit-reproducible;
  ``particle_dtype="float64"`` restores the precision, not the draws).
"""

#: The Resample task's declaration.
RESAMPLE = register_task(
    TaskSpec(
        name="resample",
        title="Resample",
        cls=ResampleTask,
        arguments=ARGUMENTS,
        action_text="``Resample``: ``Discrete(2)``, 1 = resample the particles now.",
        argument_text=(
            '``Resample``: ``n_particles=1000``, ``resample_cost=0.05``, ``method="systematic"``, '
            "``roughening=0.0`` (v1: 0.2), ``log_ess_feature=False`` (v1: True), "
            '``particle_dtype="float32"`` '
            "(the cloud's precision; weights, moments and diagnostics stay float64)"
        ),
        baseline="Resample",
        cost_text=" - resample_cost * resampled",
        version_history=RESAMPLE_VERSION_HISTORY,
        state_bytes=state_bytes,
        memory_arguments=("n_particles", "particle_dtype"),
    )
)
