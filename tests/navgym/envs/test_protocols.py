import numpy as np
import pytest

from navgym.gps_ins.env import GpsInsPlatform
from navgym.quadrotor.env import QuadrotorPlatform
from navgym.robot2d.env import Robot2dPlatform

PLATFORMS = {
    "gps_ins": GpsInsPlatform,
    "gps_ins_critical": lambda: GpsInsPlatform(critical=True),
    "quadrotor": QuadrotorPlatform,
    "robot2d": Robot2dPlatform,
}


@pytest.mark.parametrize("name", sorted(PLATFORMS))
def test_sample_scenarios_equals_one_draw_per_episode(name):
    plat = PLATFORMS[name]()
    B = 80
    gens = [np.random.default_rng(7 + i) for i in range(B)]
    refs = [np.random.default_rng(7 + i) for i in range(B)]
    assert plat.sample_scenarios(gens) == [plat.sample_scenario(r) for r in refs]
    assert [g.integers(1 << 60) for g in gens] == [r.integers(1 << 60) for r in refs]


class _WithoutBatchedScenarios:
    """A platform that only implements the per-episode ``sample_scenario``."""

    def __init__(self, platform) -> None:
        self._platform = platform

    def __getattr__(self, name):
        if name == "sample_scenarios":
            raise AttributeError(name)
        return getattr(self._platform, name)


def test_core_falls_back_to_one_scenario_draw_per_episode():
    import gymnasium as gym

    import navgym  # noqa: F401

    ref = gym.make_vec("navgym/Robot2dFading-v1", num_envs=3)
    env = gym.make_vec("navgym/Robot2dFading-v1", num_envs=3)
    env.unwrapped.core.platform = _WithoutBatchedScenarios(env.unwrapped.core.platform)
    obs_ref, _ = ref.reset(seed=4)
    obs, _ = env.reset(seed=4)
    np.testing.assert_array_equal(obs, obs_ref)
    assert env.unwrapped.core.scenarios == ref.unwrapped.core.scenarios
