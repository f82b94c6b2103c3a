"""The replay ids: registered with cards, a user recording, pinned events, no truth in observations."""

from __future__ import annotations

import copy
import re
import shutil

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401 - registers the ids
from navgym.quadrotor.models import euler_dcm
from navgym.recordings.loader import PACKAGED
from navgym.recordings.platform import LeverArmFixModel
from navgym.scenarios import Multipath, Outage, Scenario
from tests.navgym.recordings.synthetic import write_recording

REPLAY_IDS = ["navgym/ReplayFading-v2", "navgym/ReplayNoiseScale-v2"]


@pytest.mark.parametrize("env_id", REPLAY_IDS)
def test_registered_with_a_card_and_the_quadrotor_v2_observation(env_id):
    env = gym.make(env_id)
    doc = type(env.unwrapped).__doc__
    for section in (
        "## Description",
        "## Action Space",
        "## Observation Space",
        "## Rewards",
        "## Arguments",
    ):
        assert section in doc
    assert "walk_0827" in doc and not re.search(r"\{[a-z_]+\}", doc)  # every placeholder filled
    quad = gym.make(env_id.replace("Replay", "Quadrotor")).unwrapped.core
    assert env.unwrapped.core.obs_features.names == quad.obs_features.names
    assert env.observation_space.shape == quad.observation_space.shape


def test_a_user_recording_replays_with_its_lever_arm(tmp_path):
    """Still IMU, fixes at the antenna: the plain filter keeps the antenna within centimetres."""
    d = write_recording(tmp_path / "rec", duration=30.0, yaw_deg=30.0, lever=(0.3, -0.2, 0.0))
    env = gym.make("navgym/ReplayFading-v2", recording=str(d), episode_steps=80, max_episode_steps=80)
    env.reset(seed=0, options={"scenario": Scenario(duration=20.0)})
    core = env.unwrapped.core
    # the prior is the antenna fix (the NED origin: the first fix) minus C_b^n l^b
    m0 = core.platform.initial_belief(core.episodes).m[0]
    c, s = np.cos(np.deg2rad(30.0)), np.sin(np.deg2rad(30.0))
    np.testing.assert_allclose(m0[:3], [-(0.3 * c + 0.2 * s), -(0.3 * s - 0.2 * c), 0.0], atol=2e-3)
    errs = []
    plain = core.task.neutral_action().astype(np.float32)
    for _ in range(80):
        *_, info = env.step(plain)
        errs.append(float(info["pos_err_m"]))
    assert max(errs) < 0.03


def test_lever_arm_model_known_answer():
    lever = np.array([0.0, -0.05, 0.0])
    model = LeverArmFixModel(np.eye(6), lever, np.array([[0.0, 0.0, 2.0]]))
    x = np.zeros((1, 15))
    x[0, 8] = np.pi / 2  # yaw 90 deg: body y (right) points south
    z = model.h(x)[0]
    np.testing.assert_allclose(z[:3], [0.05, 0.0, 0.0], atol=1e-12)
    # omega x l = (0, 0, 2) x (0, -0.05, 0) = (0.1, 0, 0) in the body, east after the yaw
    np.testing.assert_allclose(z[3:], [0.0, 0.1, 0.0], atol=1e-12)
    H = model.H(x)[0]
    eps = 1e-6
    for i in range(3):
        dx = np.zeros((1, 15))
        dx[0, 6 + i] = eps
        np.testing.assert_allclose(H[:, 6 + i], (model.h(x + dx) - model.h(x - dx))[0] / (2 * eps), atol=1e-8)
    assert euler_dcm(x[0, 6:9]).shape == (3, 3)


def test_the_lever_arm_jacobian_is_the_central_differences_of_each_angle_bit_for_bit():
    """H evaluates the six perturbed attitudes in one call: the numbers of one call per perturbation."""
    rng = np.random.default_rng(8)
    B = 37
    model = LeverArmFixModel(np.eye(6), np.array([0.1, -0.2, 0.3]), rng.normal(0, 0.5, (B, 3)))
    x = rng.normal(0, 1, (B, 15))
    H = model.H(x)
    eps = 1e-6
    for i in range(3):
        d = np.zeros(3)
        d[i] = eps
        column = (model._offsets(x[:, 6:9] + d) - model._offsets(x[:, 6:9] - d)) / (2 * eps)
        np.testing.assert_array_equal(H[:, :, 6 + i], column)
    np.testing.assert_array_equal(H[:, :, :6], np.broadcast_to(np.eye(6), (B, 6, 6)))
    assert not H[:, :, 9:].any()


def test_pinned_outage_withholds_fixes_but_scores_them():
    env = gym.make("navgym/ReplayFading-v2")
    s = Scenario(
        duration=60.0, outages=(Outage(10.0, 20.0),), multipath=(Multipath(30.0, 40.0, row=0, bias=2.0),)
    )
    env.reset(seed=1, options={"scenario": s})
    ep = env.unwrapped.core.episodes
    t = np.arange(241) * 0.25
    assert not ep.fix[0, (t >= 10.0) & (t < 20.0)].any() and ep.fix[0, t < 10.0].all()
    inside = (t >= 30.0) & (t < 40.0)
    # the multipath bias is added to the recorded fix (row N) and recorded as the truth's bias
    np.testing.assert_allclose(ep.true_bias[0, inside, 0], 2.0)
    np.testing.assert_allclose(
        ep.z[0, inside, 0] - 2.0,
        env.unwrapped.core.platform.data.z[:, 0][
            np.searchsorted(
                env.unwrapped.core.platform.data.t,
                env.unwrapped.core.platform.data.t[0] + ep.t_start[0] + t[inside],
            )
        ],
        atol=1e-9,
    )
    errs = []
    for _ in range(100):
        *_, info = env.step(env.unwrapped.core.task.neutral_action().astype(np.float32))
        errs.append(float(info["pos_err_m"]))
    assert np.isfinite(errs).all()


@pytest.mark.parametrize("env_id", REPLAY_IDS)
def test_observation_carries_no_truth(env_id):
    """Perturb every truth-only array of the episodes in a copy: the observation is unchanged."""
    venv = gym.make_vec(env_id, num_envs=3, vectorization_mode="vector_entry_point")
    venv.reset(seed=5)
    core = venv.unwrapped.core
    act = np.tile(core.task.neutral_action(), (3, 1))
    for _ in range(5):
        core.step(act, venv.unwrapped.rngs)
    twin, twin_rngs = copy.deepcopy((core, venv.unwrapped.rngs))
    ep, g = twin.episodes, np.random.default_rng(0)
    twin.episodes = ep._replace(
        truth=ep.truth + g.normal(0, 20.0, ep.truth.shape),
        t_start=ep.t_start + 3.0,
        origin=ep.origin + 0.1,
        true_q=ep.true_q + 1.0,
        true_r=ep.true_r * 9.0,
        true_bias=ep.true_bias + 30.0,
        exact=~ep.exact,
    )
    for _ in range(4):
        o1, *_, i1 = core.step(act, venv.unwrapped.rngs)
        o2, *_, i2 = twin.step(act, twin_rngs)
        np.testing.assert_array_equal(o1, o2)
    assert not np.allclose(i1["pos_err_m"], i2["pos_err_m"])


def test_bad_recording_and_horizon_are_refused_at_make(tmp_path):
    with pytest.raises(ValueError, match="no recording.toml sidecar"):
        gym.make("navgym/ReplayFading-v2", recording=str(tmp_path))
    with pytest.raises(ValueError, match="nowhere: the recording directory does not exist"):
        gym.make("navgym/ReplayFading-v2", recording=str(tmp_path / "nowhere"))
    with pytest.raises(ValueError, match="longer than the recording's truth span"):
        gym.make("navgym/ReplayFading-v2", episode_steps=2000)
    with pytest.raises(ValueError, match="GNSS epoch interval"):
        gym.make("navgym/ReplayFading-v2", dt=0.1)


def test_the_packaged_walk_without_outages_stays_within_decimetres():
    """Plain EKF over the whole truth span (85 s): measured 0.091 m RMS at the RTK-fixed epochs."""
    env = gym.make("navgym/ReplayFading-v2", episode_steps=340, max_episode_steps=340)
    env.reset(seed=0, options={"scenario": Scenario(duration=85.0)})
    exact = env.unwrapped.core.episodes.exact[0, 1:]
    plain = env.unwrapped.core.task.neutral_action().astype(np.float32)  # lambda = 1
    errs = np.array([float(env.step(plain)[-1]["pos_err_m"]) for _ in range(340)])
    assert exact.sum() > 300
    rms = np.sqrt(np.mean(errs[exact] ** 2))
    assert rms < 0.15, rms


def _walk_copy(tmp_path):
    d = tmp_path / "walk"
    shutil.copytree(PACKAGED, d)
    for p in d.iterdir():
        p.chmod(0o644)
    return d


def test_an_imu_gap_fails_at_make_naming_the_gap_instead_of_being_bridged(tmp_path):
    """Issue 38: a 2 s gap was interpolated over and every window across it replayed invented motion."""
    d = _walk_copy(tmp_path)
    rows = (d / "imu.csv").read_text().splitlines()
    t0 = float(rows[0].split(",")[0])
    (d / "imu.csv").write_text("\n".join(r for r in rows if not 50.0 <= float(r.split(",")[0]) - t0 < 52.0))
    with pytest.raises(
        ValueError, match=r"IMU gap: imu\.csv jumps 2\.0\d\d s from line 7608 .* to line 7609"
    ):
        gym.make("navgym/ReplayFading-v2", recording=str(d))


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("[180.0, 0.0, -90.0]", "[0.0, 0.0, -90.0]", r"mount: the specific force while still"),
        ('gyro_unit = "rad/s"', 'gyro_unit = "deg/s"', r"gyro: the rates about the vertical are 0\.01"),
        (
            "time_offset_s = 0.0",
            "time_offset_s = 18.0",
            r"time: the IMU's turns match the GNSS heading rate 18",
        ),
        ("accel_noise_ug_per_sqrt_hz = 70.0", "accel_noise_ug_per_sqrt_hz = 1e30", r"is not plausible"),
    ],
)
def test_a_wrong_sidecar_fails_at_make_not_at_the_first_step(tmp_path, old, new, message):
    """These made every result worse (or every episode end at step 1) without an error."""
    d = _walk_copy(tmp_path)
    side = d / "recording.toml"
    side.write_text(side.read_text().replace(old, new))
    with pytest.raises(ValueError, match=message):
        gym.make("navgym/ReplayFading-v2", recording=str(d))
