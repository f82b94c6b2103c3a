import numpy as np
import pytest

from navgym.envs.gps_ins import GpsInsPlatform
from navgym.envs.quadrotor import QuadrotorPlatform
from navgym.envs.robot2d import Robot2dPlatform

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
