"""The skeleton's checks at ``make``: render_mode of the vector env, declared platform arguments,
horizon and step bounds, and the memory bound of a batch's episodes (``MAX_EPISODE_BYTES``)."""

from __future__ import annotations

import time
import tracemalloc
import warnings

import gymnasium as gym
import numpy as np
import pytest

from navgym.envs import build as skeleton
from navgym.envs import register_all
from navgym.envs.platform import MAX_EPISODE_STEPS, PlatformSpec, build_core
from navgym.gps_ins.env import GPS_INS, GpsInsEnv
from navgym.iridium.env import IRIDIUM_V2, IridiumEnv
from navgym.jpa.env import JPA, JpaEnv
from navgym.pedestrian.env import PEDESTRIAN_V2, PedestrianEnv
from navgym.quadrotor.env import QUADROTOR, QuadrotorEnv
from navgym.robot2d.env import ROBOT2D, Robot2dEnv
from navgym.signal_tracking.env import SIGNAL_TRACKING, SignalTrackingEnv

SPECS = {
    "GpsIns": GPS_INS, "Iridium": IRIDIUM_V2, "Pedestrian": PEDESTRIAN_V2, "Quadrotor": QUADROTOR,
    "Robot2d": ROBOT2D,
}  # fmt: skip
CARDS = {
    "GpsIns": GpsInsEnv, "Iridium": IridiumEnv, "Pedestrian": PedestrianEnv, "Quadrotor": QuadrotorEnv,
    "Robot2d": Robot2dEnv,
}  # fmt: skip

SPECS["Jpa"], CARDS["Jpa"] = JPA, JpaEnv
SPECS["SignalTracking"], CARDS["SignalTracking"] = SIGNAL_TRACKING, SignalTrackingEnv


@pytest.fixture(autouse=True)
def _registered():
    register_all()


# ------------------------------------------------------------------------------- render_mode
@pytest.mark.parametrize("mode", ["bogus", "rgb_array", "human", 1])
def test_the_vector_env_refuses_any_render_mode(mode):
    """It renders nothing: gym.make_vec(render_mode=...) was silently dropped."""
    with pytest.raises(ValueError, match=r"render_mode must be None .*; got"):
        gym.make_vec("navgym/Robot2dFading-v1", num_envs=2, render_mode=mode)


def test_the_vector_env_takes_render_mode_none():
    venv = gym.make_vec("navgym/Robot2dFading-v1", num_envs=2, render_mode=None)
    assert venv.num_envs == 2 and venv.render_mode is None


# -------------------------------------------------------------------------- declared arguments
@pytest.mark.parametrize("name", sorted(SPECS))
def test_every_declared_argument_is_read_and_documented_in_the_card(name):
    spec = SPECS[name]
    card = CARDS[name].__doc__
    for k in spec.keyword_arguments:
        assert f"``{k}" in card, f"{name}'s card does not document {k}"
    assert "MAX_EPISODE_BYTES" in card
    assert set(spec.platform_arguments) <= set(spec.keyword_arguments)
    assert ("dt" in spec.keyword_arguments) == spec.dt_argument


def test_build_sees_only_the_declared_platform_arguments():
    seen = {}

    def build(a):
        seen.update(a.kwargs)
        a.kwargs.pop("sigma_gps", None)
        return ROBOT2D.build(a._replace(kwargs={}))

    spec = PlatformSpec(**{**ROBOT2D.__dict__, "build": build, "platform_arguments": ("sigma_gps",)})
    build_core(spec, "fading", 1, {"sigma_gps": 2.0, "filter": "ekf", "reward_clip": 5.0})
    assert seen == {"sigma_gps": 2.0}


def test_a_declared_argument_build_does_not_read_is_a_bug_of_the_platform():
    spec = PlatformSpec(**{**ROBOT2D.__dict__, "platform_arguments": (*ROBOT2D.platform_arguments, "extra")})
    with pytest.raises(RuntimeError, match=r"declares \['extra'\] in platform_arguments"):
        spec.platform("fading", {"extra": 1})


# ------------------------------------------------------------------------------- horizon, dt
@pytest.mark.parametrize("steps", [MAX_EPISODE_STEPS + 1, 10**30])
def test_a_horizon_beyond_max_episode_steps_is_refused(steps):
    """10**30 steps made the scenario's duration overflow (an OverflowError naming nothing)."""
    with pytest.raises(ValueError, match=r"episode_steps must be an integer in \[1, 100000000\]"):
        gym.make("navgym/GpsInsFading-v1", episode_steps=steps)


@pytest.mark.parametrize(
    ("env_id", "dt", "message"),
    [
        # 3.16 ** 1e9 (the Fading task's default lambda_max) was an OverflowError at make
        ("navgym/QuadrotorFading-v1", 1e9, r"dt must be a finite number in \(0, 1\]; got 1000000000.0"),
        ("navgym/QuadrotorMixture-v1", 1.5, r"dt must be a finite number in \(0, 1\]"),
        # the vehicle plan of a 3e11 s episode hung the first reset
        ("navgym/GpsInsFading-v1", 1e9, r"dt must be a finite number in \(0, 60\]; got 1000000000.0"),
        # named the scenario's duration ("duration must be > 0, got -300.0")
        ("navgym/GpsInsFading-v1", -1.0, r"dt must be a finite number in \(0, 60\]; got -1.0"),
    ],
)
def test_dt_is_bounded_per_platform(env_id, dt, message):
    with pytest.raises(ValueError, match=message):
        gym.make(env_id, dt=dt)


# ------------------------------------------------------------------------------------ memory
@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("navgym/Robot2dFading-v1", {"episode_steps": 10**7}),  # a MemoryError at reset
        ("navgym/GpsInsFading-v1", {"episode_steps": 10**7}),
        ("navgym/QuadrotorFading-v1", {"episode_steps": 10**7}),
        ("navgym/QuadrotorMixture-v1", {"episode_steps": 3 * 10**6, "imu_rate_hz": 2000.0}),
    ],
)
def test_episodes_beyond_the_memory_bound_are_refused_before_anything_is_allocated(env_id, kwargs):
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        with pytest.raises(ValueError, match=r"episode_steps=\d+ with num_envs=1 .* = 4 GiB"):
            gym.make(env_id, **kwargs)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert time.perf_counter() - t0 < 2.0 and peak < 2**24


def test_a_batch_beyond_the_memory_bound_is_refused_naming_num_envs():
    with pytest.raises(
        ValueError, match=r"episode_steps=600 with num_envs=100000 .* lower episode_steps or num_envs"
    ):
        gym.make_vec("navgym/QuadrotorFading-v1", num_envs=100_000)
    assert gym.make_vec("navgym/QuadrotorFading-v1", num_envs=1000).num_envs == 1000


def test_the_memory_bound_is_read_when_an_env_is_made(monkeypatch):
    gym.make("navgym/Robot2dFading-v1")
    monkeypatch.setattr(skeleton, "MAX_EPISODE_BYTES", 2**20)
    with pytest.raises(ValueError, match=r"MAX_EPISODE_BYTES = 0.000977 GiB"):
        gym.make("navgym/Robot2dFading-v1", episode_steps=10_000)
    gym.make("navgym/Robot2dFading-v1", episode_steps=1000)


@pytest.mark.parametrize("name", sorted(SPECS))
def test_episode_bytes_estimates_the_peak_of_a_reset(name):
    """The estimate lies between the measured peak of a reset and four times it (T = 1000)."""
    spec, T, B = SPECS[name], 1000, 2
    task = "fading" if "fading" in spec.tasks else next(iter(spec.tasks))  # Iridium: no Fading
    core = spec.core(task, B, {"episode_steps": T})
    rngs = [np.random.default_rng(i) for i in range(B)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        core.reset(np.arange(B), rngs, [None] * B)  # compile and cache first
        core = spec.core(task, B, {"episode_steps": T})
        tracemalloc.start()
        try:
            core.reset(np.arange(B), rngs, [None] * B)
            _, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
    estimate = B * core.platform.episode_bytes(T)
    assert peak <= estimate <= 4 * peak, (name, peak, estimate)
