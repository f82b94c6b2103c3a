"""A fourth platform written as docs/add_a_platform.md says: only what differs.

(Its tests are in ``test_platform_skeleton.py``; ``toy_v2.py`` extends it with a truth.)

``Toy`` is a constant-velocity point in the plane with GNSS position fixes and outages. It
declares its problem (on :class:`PlatformBase`), a :class:`PlatformSpec` and a card; the skeleton
gives it keyword arguments, Env / VectorEnv classes, shared features and the card paragraphs,
and the environments pass Gymnasium's checker and the vector = single contract.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from filters import GaussianState, LinearGaussianModel
from navgym.envs import arguments
from navgym.envs.features import (
    CovarianceBlock,
    covariance_values,
    innovation_features,
    innovation_initial_values,
    innovation_values,
)
from navgym.envs.platform import PlatformArgs, PlatformBase, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.envs.protocols import PositionError, StepModels
from navgym.scenarios import ScenarioDistribution, gnss_available, stack_scenarios

BLOCKS = (
    CovarianceBlock("log_sigma_pos", (0, 1), -3.0, 5.0, "log10 m", "log10 sqrt(P_NN + P_EE)"),
    CovarianceBlock("log_sigma_vel", (2, 3), -4.0, 3.0, "log10 m/s", "log10 sqrt(P_vv)"),
)


class ToyEpisodes(NamedTuple):
    x: np.ndarray  # (B, T+1, 4) true state
    z: np.ndarray  # (B, T+1, 2) fixes
    mask: np.ndarray  # (B, T+1, 2)


@dataclass(frozen=True)
class ToyPlatform(PlatformBase):
    scenarios: ScenarioDistribution
    dt: float = 1.0
    sigma: float = 3.0
    error_scale_m: float = 5.0
    divergence_m: float = 500.0
    name: str = "Toy"
    n: int = 4
    m_max: int = 2

    @property
    def model(self) -> LinearGaussianModel:
        F = np.eye(4) + np.diag([self.dt, self.dt], 2)
        H = np.eye(2, 4)
        return LinearGaussianModel(F, H, 0.01 * np.eye(4), self.sigma**2 * np.eye(2))

    def simulate(self, rngs, scenarios, T) -> ToyEpisodes:
        B = len(rngs)
        t = np.broadcast_to(np.arange(T + 1) * self.dt, (B, T + 1))
        ok = gnss_available(stack_scenarios(list(scenarios)), t)
        v = np.cumsum(np.stack([r.normal(0.0, 0.1, (T + 1, 2)) for r in rngs]), axis=1)
        p = np.cumsum(v, axis=1) * self.dt
        z = p + self.sigma * np.stack([r.standard_normal((T + 1, 2)) for r in rngs])
        mask = np.repeat(ok[..., None], 2, axis=-1)
        return ToyEpisodes(np.concatenate([p, v], axis=-1), np.where(mask, z, np.nan), mask)

    def initial_belief(self, ep: ToyEpisodes) -> GaussianState:
        B = ep.x.shape[0]
        return GaussianState(
            ep.x[:, 0].copy(), np.broadcast_to(np.diag([9.0, 9.0, 0.1, 0.1]), (B, 4, 4)).copy()
        )

    def step_models(self, ep: ToyEpisodes, t: np.ndarray) -> StepModels:
        rows = np.arange(t.shape[0])
        return StepModels(self.model, self.model, ep.z[rows, t + 1], ep.mask[rows, t + 1], self.dt)

    def position_error(self, mean, ep: ToyEpisodes, t, P) -> PositionError:
        truth = ep.x[np.arange(t.shape[0]), t]
        d = mean[:, :2] - truth[:, :2]
        return PositionError(
            np.hypot(d[:, 0], d[:, 1]), truth[:, :2], mean[:, :2].copy(), P[:, :2, :2], mean - truth
        )

    def features(self):
        return [*innovation_features(2, "fix innovations / sqrt(S_ii)"), *(b.feature for b in BLOCKS)]

    def initial_feature_values(self, belief, ep) -> dict[str, np.ndarray]:
        return {**innovation_initial_values(belief.m.shape[0], 2), **covariance_values(belief.P, BLOCKS)}

    def feature_values(self, belief, info, models, ep, t) -> dict[str, np.ndarray]:
        return {**innovation_values(info, models.mask, 2), **covariance_values(belief.P, BLOCKS)}


def build_toy(a: PlatformArgs) -> ToyPlatform:
    sigma = arguments.real("sigma", a.kwargs.pop("sigma", 3.0), 0.0, low_open=True)
    return ToyPlatform(a.scenarios, a.dt, sigma, a.error_scale_m, a.divergence_m)


TOY = PlatformSpec(
    name="Toy",
    build=build_toy,
    tasks={"fading": {"outage_probability": 0.5, "outage_duration": (5.0, 20.0)}, "mixture": {}},
    scenario_arguments=("outage_probability", "outage_duration"),
    episode_steps=60,
    dt=1.0,
    error_scale_m=5.0,
    divergence_m=500.0,
)


class ToyEnv(PlatformEnv, spec=TOY):
    """A point in the plane.

    ## Action Space
    {action_space}

    ## Observation Space
    {observation_table}

    ## Rewards
    {rewards}

    ## Episode End
    {episode_end}

    ## Arguments
    ``sigma=3.0`` [m]. {common_arguments}

    ## Version History
    {version_history}
    """


class ToyVectorEnv(PlatformVectorEnv, spec=TOY):
    """Native batched Toy environment."""
