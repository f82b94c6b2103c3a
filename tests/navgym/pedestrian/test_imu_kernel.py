"""The compiled foot IMU of a Pedestrian reset (navgym.pedestrian.imu_kernel): the NumPy form's bits."""

from __future__ import annotations

import numpy as np
import pytest

from filters.core.compiled import numpy_only
from navgym.pedestrian import imu_kernel
from navgym.pedestrian.platform import PedestrianPlatform
from navgym.scenarios import MotionBurst, Scenario
from tests.filters.compiled_paths import count_calls

T = 30
SEEDS = (3, 4, 5)
CLEAN = Scenario(duration=float(T))
#: A shock burst: per-step noise sigmas that differ from step to step.
BURST = MotionBurst(5.0, 13.0, velocity_sigma=0.1, yaw_rate_sigma=0.004)
SHOCK = Scenario(duration=float(T), bursts=(BURST,))


def _reset(platform: PedestrianPlatform, scenario: Scenario):
    rngs = [np.random.default_rng(s) for s in SEEDS]
    return platform.simulate(rngs, [scenario] * len(SEEDS), T)


@pytest.mark.parametrize("context", [False, True], ids=["v2", "v3 context"])
@pytest.mark.parametrize("scenario", [CLEAN, SHOCK], ids=["clean", "shock"])
def test_the_compiled_reset_equals_the_numpy_form_bit_for_bit(monkeypatch, context, scenario):
    platform = PedestrianPlatform(true_noise=True, context=context)
    # several chunks of strides, so that the passes start at c0 > 0
    monkeypatch.setattr(PedestrianPlatform, "chunk_steps", lambda self, B, T: 7)
    calls = count_calls(monkeypatch, imu_kernel, ["foot_angles_pass", "foot_imu_pass"])
    compiled = _reset(platform, scenario)
    assert calls == {"foot_angles_pass": 5, "foot_imu_pass": 5}  # ceil(30 / 7) chunks
    with numpy_only():
        reference = _reset(platform, scenario)
    for name, a in compiled._asdict().items():
        b = getattr(reference, name)
        if isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=name)
        elif a is not None:
            for key in a._fields if hasattr(a, "_fields") else ():
                np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=f"{name}.{key}")
    assert np.abs(compiled.d6).max() > 0.1  # the walk moved the foot
