"""Failures that come at ``make`` or ``reset``, not at a later step (issue 38 items 8-11, issue 39 item 7).

Memory of the particle clouds x parallel envs, filters against the platform's state size, the
clairvoyant on platforms without truth, absurd noise figures, integers too large for a float,
pinned scenarios bounded like the keywords and restricted to the events a platform models,
``reset(options)`` validated, bytes recordings, and the error texts of unknown keywords and of a
single env's action shape.
"""

from __future__ import annotations

import warnings

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401  (registers the ids)
from navgym.envs import ENVIRONMENTS
from navgym.envs.tasks import task_spec
from navgym.scenarios import (
    ImpulsiveNoise,
    Jamming,
    MotionBurst,
    Multipath,
    OutlierSatellites,
    Scenario,
    UrbanCanyon,
)

warnings.filterwarnings("ignore", category=DeprecationWarning)

STEPS = 50


def _make(env_id: str, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return gym.make(env_id, **kwargs)


# --------------------------------------------------------------------- 8: particles x envs


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("navgym/SignalTrackingJumps-v2", {"num_envs": 1000, "n_particles": 4096}),
        ("navgym/Robot2dResample-v2", {"num_envs": 64, "n_particles": 10**6}),
        ("navgym/GpsInsResample-v2", {"num_envs": 32, "n_particles": 10**6, "particle_dtype": "float64"}),
    ],
)
def test_particle_memory_of_a_batch_is_refused_at_make(env_id, kwargs):
    with pytest.raises(
        ValueError, match=r"n_particles=.* with num_envs=.*MAX_EPISODE_BYTES.*lower n_particles"
    ):
        gym.make_vec(env_id, **kwargs)


def test_particle_memory_estimate_follows_the_task_state():
    """The estimate grows with particles, the state size and the cloud's precision."""
    single = gym.make_vec("navgym/Robot2dResample-v2", num_envs=2, n_particles=10**5).unwrapped.core
    spec = task_spec("resample")
    assert spec.state_bytes is not None
    f32 = spec.state_bytes(single.task, single.platform)
    assert f32 == 10**5 * ((4 * 4 + 16) * single.platform.n + 64)
    f64 = gym.make_vec(
        "navgym/Robot2dResample-v2", num_envs=2, n_particles=10**5, particle_dtype="float64"
    ).unwrapped.core
    assert spec.state_bytes(f64.task, f64.platform) > f32
    # a batch the estimate allows still makes
    gym.make_vec("navgym/SignalTrackingJumps-v2", num_envs=8, n_particles=4096)


# --------------------------------------------------------------------- 9: filters and state size


@pytest.mark.parametrize(
    "env_id", ["navgym/QuadrotorFading-v2", "navgym/PedestrianMixture-v2", "navgym/ReplayFading-v2"]
)
@pytest.mark.parametrize(("name", "points"), [("ghkf", "14348907"), ("ghkf5", "30517578125")])
def test_gauss_hermite_on_15_states_is_refused_at_make(env_id, name, points):
    with pytest.raises(
        ValueError, match=rf"filter='{name}' on a 15-state problem needs .* = {points} sigma points"
    ):
        _make(env_id, filter=name)


def test_gauss_hermite_still_makes_on_small_states():
    _make("navgym/GpsInsFading-v2", filter="ghkf", episode_steps=STEPS)
    _make("navgym/Robot2dNoiseScale-v2", filter="ghkf5", episode_steps=STEPS)


def test_cards_list_only_the_filters_that_run():
    from navgym.quadrotor.env import QuadrotorEnv
    from navgym.robot2d.env import Robot2dEnv

    quad = " ".join(str(QuadrotorEnv.__doc__).split())
    robot = " ".join(str(Robot2dEnv.__doc__).split())
    assert '``"ckf"``' in quad and '``"ghkf"``' not in quad and '``"ghkf5"``' not in quad
    assert '``"ghkf"``' in robot and '``"ghkf5"``' in robot


# --------------------------------------------------------------------- 10: pinned scenarios


def _pinned(env, **events) -> Scenario:
    core = env.unwrapped.core
    return Scenario(duration=core.T * core.platform.dt, **events)


HUGE_EVENTS = {
    "jam_sigma": {"jamming": (Jamming(1.0, 3.0, jam_sigma=1e300),)},
    "multipath bias": {"multipath": (Multipath(1.0, 3.0, row=0, bias=1e300),)},
    "negative multipath bias": {"multipath": (Multipath(1.0, 3.0, row=0, bias=-1e300),)},
    "multipath sigma": {"multipath": (Multipath(1.0, 3.0, row=0, sigma=1e300),)},
    "burst velocity": {"bursts": (MotionBurst(1.0, 3.0, velocity_sigma=1e300),)},
    "burst yaw rate": {"bursts": (MotionBurst(1.0, 3.0, yaw_rate_sigma=1e300),)},
    "canyon noise scale": {"canyons": (UrbanCanyon(1.0, 3.0, max_satellites=4, noise_scale=1e300),)},
}


@pytest.mark.parametrize("case", sorted(HUGE_EVENTS))
def test_pinned_values_are_bounded_like_the_keywords_at_reset(case):
    env = gym.make_vec("navgym/Robot2dFading-v2", num_envs=3, episode_steps=STEPS)
    env.reset(seed=0)
    pinned = _pinned(env, **HUGE_EVENTS[case])
    with pytest.raises(
        ValueError, match=r"options\['scenario'\]\.\w+\[0\]\.\w+ must be within .*keyword argument"
    ):
        env.reset(seed=1, options={"scenario": [None, pinned, None]})
    for _ in range(STEPS + 2):  # the vector env steps on, every sub-env healthy, across autoresets
        obs, reward, *_ = env.step(env.action_space.sample())
        assert np.isfinite(obs).all() and np.isfinite(reward).all()


@pytest.mark.parametrize(
    "events",
    [
        {"outliers": (OutlierSatellites(1.0, 3.0, prns=(1,), scale=1e300),)},
        {"impulsive": (ImpulsiveNoise(1.0, 3.0, var_ratio=1e300),)},
    ],
)
def test_pinned_outliers_and_impulsive_noise_are_bounded(events):
    env = _make("navgym/GpsInsFading-v1", episode_steps=STEPS)
    with pytest.raises(ValueError, match=r"must be within"):
        env.reset(seed=0, options={"scenario": _pinned(env, **events)})


def test_reasonable_pinned_values_still_run():
    env = _make("navgym/Robot2dFading-v2", episode_steps=STEPS)
    pinned = _pinned(
        env, jamming=(Jamming(1.0, 3.0, jam_sigma=50.0),), multipath=(Multipath(1.0, 3.0, bias=-30.0),)
    )
    env.reset(seed=0, options={"scenario": pinned})
    for _ in range(5):
        env.step(env.action_space.sample())


@pytest.mark.parametrize(
    ("env_id", "events", "keyword"),
    [
        ("navgym/SignalTrackingJumps-v2", {"jamming": (Jamming(0.01, 0.02),)}, "jamming_probability"),
        ("navgym/SignalTrackingJumps-v2", {"multipath": (Multipath(0.01, 0.02),)}, "multipath_probability"),
        ("navgym/JpaRobust-v2", {"bursts": (MotionBurst(1.0, 2.0),)}, "burst_probability"),
        ("navgym/JpaRobust-v2", {"jamming": (Jamming(1.0, 2.0),)}, "jamming_probability"),
    ],
)
def test_unmodelled_pinned_events_are_refused_as_their_keywords_are(env_id, events, keyword):
    env = _make(env_id)
    with pytest.raises(TypeError, match=keyword):  # the keyword: unknown on this platform
        _make(env_id, **{keyword: 0.5})
    with pytest.raises(ValueError, match=rf"does not model .*{keyword}"):
        env.reset(seed=0, options={"scenario": _pinned(env, **events)})


# --------------------------------------------------------------------- 11: make-time arguments


V01 = [e[0] for e in ENVIRONMENTS if e[0].endswith(("-v0", "-v1")) and "Resample" not in e[0]]


@pytest.mark.parametrize("env_id", V01)
def test_clairvoyant_on_platforms_without_truth_is_refused_at_make(env_id):
    with pytest.raises(ValueError, match=r"clairvoyant=True .* use a v2 id"):
        _make(env_id, clairvoyant=True)


@pytest.mark.parametrize(
    ("env_id", "name"),
    [
        ("navgym/QuadrotorFading-v2", "sigma_pos"),
        ("navgym/QuadrotorFading-v2", "sigma_vel"),
        ("navgym/ReplayFading-v2", "sigma_pos"),
        ("navgym/PedestrianFading-v2", "sigma_pos"),
        ("navgym/PedestrianFading-v2", "sigma_zupt"),
        ("navgym/Robot2dFading-v2", "sigma_gps"),
        ("navgym/Robot2dFading-v2", "sigma_compass_deg"),
        ("navgym/GpsInsFading-v2", "sigma_pr"),
    ],
)
@pytest.mark.parametrize("value", [5e-324, 1e-300])
def test_denormal_noise_figures_are_refused_at_make(env_id, name, value):
    with pytest.raises(ValueError, match=rf"{name} must be a finite number in \[0\.00"):
        _make(env_id, **{name: value})


@pytest.mark.parametrize(
    ("env_id", "name"),
    [
        ("navgym/JpaRobust-v2", "attitude_weight"),
        ("navgym/Robot2dFading-v2", "lambda_max"),
        ("navgym/QuadrotorFading-v2", "sigma_pos"),
        ("navgym/Robot2dFading-v2", "reward_clip"),
        ("navgym/Robot2dFading-v2", "outage_probability"),
        ("navgym/Robot2dFading-v2", "jamming_sigma"),
    ],
)
def test_integers_too_large_for_a_float_name_the_argument(env_id, name):
    value = (10**400, 10**400) if name == "jamming_sigma" else 10**400
    with pytest.raises(ValueError, match=rf"{name} must be a finite number .*too large for a float"):
        _make(env_id, **{name: value})


@pytest.mark.parametrize("value", [b"/tmp", bytearray(b"/tmp")])
def test_bytes_recording_is_refused_at_make(value):
    with pytest.raises(TypeError, match=r"recording must be a directory path"):
        _make("navgym/ReplayFading-v2", recording=value)


@pytest.mark.parametrize("vector", [False, True])
def test_reset_options_are_validated(vector):
    env = gym.make_vec("navgym/Robot2dFading-v2", num_envs=2) if vector else _make("navgym/Robot2dFading-v2")
    for bad in ([("scenario", None)], "scenario", 3):
        with pytest.raises(TypeError, match=r"options must be a dict"):
            env.reset(seed=0, options=bad)
    with pytest.raises(ValueError, match=r"unknown reset option 'scenaro'.*did you mean 'scenario'\?"):
        env.reset(seed=0, options={"scenaro": None})
    env.reset(seed=0, options={})
    env.reset(seed=0, options={"scenario": None})


# --------------------------------------------------------------------- issue 39 item 7


def test_unknown_keyword_gets_a_close_match():
    with pytest.raises(
        TypeError, match=r"unexpected keyword arguments: \['filtr'\]; 'filtr': did you mean 'filter'\?"
    ):
        _make("navgym/Robot2dFading-v2", filtr="ukf")


def test_another_tasks_argument_names_its_task():
    with pytest.raises(TypeError, match=r"'eps_max' is an argument of the Mixture task, not of Fading"):
        _make("navgym/Robot2dFading-v2", eps_max=0.3)
    with pytest.raises(
        TypeError, match=r"'filter' is an argument of the Fading and Mixture .*not of Resample"
    ):
        _make("navgym/Robot2dResample-v2", filter="ukf")


def test_single_env_action_shape_error_has_no_batch_axis():
    env = _make("navgym/Robot2dFading-v2").unwrapped  # the env itself (no checker wrapper)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2,\), expected \(1,\) or \(\)$") as err:
        env.step(np.zeros(2, dtype=np.float32))
    assert "(1, 2)" not in str(err.value)
    noise = _make("navgym/Robot2dNoiseScale-v2").unwrapped
    noise.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(3,\), expected \(2,\)$"):
        noise.step(np.zeros(3, dtype=np.float32))
    env.step(np.zeros(1, dtype=np.float32))  # nothing changed: a valid action steps
