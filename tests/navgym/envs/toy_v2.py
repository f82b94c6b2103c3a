"""A linear toy platform for the v2 task tests: ``test_platform_skeleton``'s Toy with a truth.

A constant-velocity point in the plane, GNSS position fixes (2 rows) and outages. Unlike the
skeleton's Toy it declares every task (``noisescale`` and ``rowscale`` included) and, unless
``gives_truth=False``, fills ``StepModels.truth``: ``Q_true = truth_q_scale Q``,
``R_true = truth_r_scale R`` and a constant measurement ``bias`` that the simulated fixes carry.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from navgym.envs import arguments
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformSpec, PlatformVectorEnv
from navgym.envs.protocols import StepModels, TrueNoise
from tests.navgym.envs import toy
from tests.navgym.envs.toy import ToyEpisodes


@dataclass(frozen=True)
class ToyPlatform(toy.ToyPlatform):
    """:class:`tests.navgym.envs.toy.ToyPlatform` whose fixes carry ``truth_r_scale`` and ``bias``."""

    truth_q_scale: float = 1.0
    truth_r_scale: float = 1.0
    bias: tuple[float, float] = (0.0, 0.0)
    gives_truth: bool = True
    name: str = "ToyV2"

    def simulate(self, rngs, scenarios, T) -> ToyEpisodes:
        ep = super().simulate(rngs, scenarios, T)
        p = ep.x[..., :2]
        z = p + (ep.z - p) * np.sqrt(self.truth_r_scale) + np.asarray(self.bias)
        return ep._replace(z=z)

    def true_noise(self, B: int) -> TrueNoise:
        model = self.model
        return TrueNoise(
            np.broadcast_to(self.truth_q_scale * model.Q, (B, 4, 4)).copy(),
            np.broadcast_to(self.truth_r_scale * model.R, (B, 2, 2)).copy(),
            np.broadcast_to(np.asarray(self.bias, dtype=float), (B, 2)).copy(),
        )

    def step_models(self, ep: ToyEpisodes, t: np.ndarray) -> StepModels:
        truth = self.true_noise(t.shape[0]) if self.gives_truth else None
        return super().step_models(ep, t)._replace(truth=truth)


def build_toy(a: PlatformArgs) -> ToyPlatform:
    kw = a.kwargs
    sigma = arguments.real("sigma", kw.pop("sigma", 3.0), 0.0, low_open=True)
    q = arguments.real("truth_q_scale", kw.pop("truth_q_scale", 1.0), 0.0)
    r = arguments.real("truth_r_scale", kw.pop("truth_r_scale", 1.0), 0.0, low_open=True)
    bias = arguments.reals("bias", kw.pop("bias", (0.0, 0.0)))  # one per row
    gives = arguments.flag("gives_truth", kw.pop("gives_truth", True))
    return ToyPlatform(
        a.scenarios, a.dt, sigma, a.error_scale_m, a.divergence_m,
        truth_q_scale=q, truth_r_scale=r, bias=bias, gives_truth=gives,
    )  # fmt: skip


TOY = PlatformSpec(
    name="ToyV2",
    build=build_toy,
    tasks={
        "fading": {"outage_probability": 0.5, "outage_duration": (5.0, 20.0)},
        "mixture": {},
        "noisescale": {"outage_probability": 0.5, "outage_duration": (5.0, 20.0)},
        "resample": {},
        "rowscale": {"outage_probability": 0.5, "outage_duration": (5.0, 20.0)},
    },
    scenario_arguments=("outage_probability", "outage_duration"),
    episode_steps=40,
    dt=1.0,
    error_scale_m=5.0,
    divergence_m=500.0,
    platform_arguments=("sigma", "truth_q_scale", "truth_r_scale", "bias", "gives_truth"),
)


class ToyEnv(PlatformEnv, spec=TOY):
    """A point in the plane, with a truth.

    ## Action Space
    {action_space}

    ## Observation Space
    {observation_table}

    ## Rewards
    {rewards}

    ## Episode End
    {episode_end}

    ## Arguments
    ``sigma=3.0`` [m], ``truth_q_scale=1``, ``truth_r_scale=1``, ``bias=(0, 0)``, ``gives_truth=True``.
    {common_arguments}

    ## Version History
    {version_history}
    """


class ToyVectorEnv(PlatformVectorEnv, spec=TOY):
    """Native batched ToyV2 environment."""
