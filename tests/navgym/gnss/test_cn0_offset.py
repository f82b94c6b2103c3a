"""``cn0_offset_db`` of the v3 ids: another receiver's C/N0 calibration changes its report only.

Issue #36 asks for a distribution shift "a C/N0 model offset by a few dB: a receiver other than
the one trained on". The receiver then reports ``round(C/N0 + cn0_offset_db + n)`` per satellite
(per row on GpsIns; :mod:`navgym.gnss.receiver_report`). What holds, and is tested here, with
the same seed and the same actions:

* an integer offset shifts each satellite's report by exactly the offset, so ``row_cn0`` on a
  received row is the offset-0 value plus the offset, clipped into [0, 60] (equal to 1e-4 dB-Hz:
  a mean of integer reports in a float32 observation), and rows not received stay 0; a
  non-integer offset moves it by the offset within 0.5 dB-Hz (the 1 dB-Hz rounding per
  satellite), and GpsIns' per-row reports stay on the 1 dB-Hz grid;
* ``row_reported_sigma`` follows the report: ``sqrt(10^(-offset/10))`` times the offset-0 value
  on the SIGMA-epsilon platforms (Robot2d, Quadrotor, Pedestrian), between ``10^(-offset/10)``
  and ``10^(-offset/20)`` of it on GpsIns (the DLL jitter law's squaring loss);
* every other observation column, the rewards, ``info["pos_err_m"]`` and the episodes (truth,
  measurements, the true noise, the receiver's other reports) are bit-identical;
* offset 0 is the default bit for bit; values outside [-10, 10] are refused naming the argument,
  and the v2 ids do not know it.
"""

from __future__ import annotations

import functools
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401  (registers the ids)
from navgym.envs.base import navigation_env
from navgym.envs.registration import superseded_ids_quiet
from navgym.gnss import receiver_report
from navgym.gps_ins.env_v3 import GPS_INS_V3_CARD
from navgym.gps_ins.platform import GpsInsPlatform
from navgym.pedestrian.env_v3 import PEDESTRIAN_V3_CARD
from navgym.pedestrian.platform import PedestrianPlatform
from navgym.quadrotor import context as quad_cx
from navgym.quadrotor.env_v3 import QUADROTOR_V3_CARD
from navgym.quadrotor.platform import QuadrotorPlatform
from navgym.robot2d import context as robot_cx
from navgym.robot2d.env_v3 import ROBOT2D_V3_CARD
from navgym.robot2d.platform import Robot2dPlatform
from navgym.scenarios import Jamming, Multipath, Scenario, UrbanCanyon, stack_scenarios

V3_IDS = [
    "navgym/GpsInsRowScale-v3",
    "navgym/QuadrotorRowScale-v3",
    "navgym/Robot2dRowScale-v3",
    "navgym/PedestrianRowScale-v3",
]
V2_IDS = [
    "navgym/GpsInsFading-v2",
    "navgym/QuadrotorFading-v2",
    "navgym/Robot2dFading-v2",
    "navgym/PedestrianFading-v2",
]
#: Platforms whose accuracy figure is ``DOP sigma_nom sqrt(u_rep)`` (SIGMA-epsilon: exact ratios).
SIGMA_EPSILON = ("Quadrotor", "Robot2d", "Pedestrian")
NUM_ENVS = 2
STEPS = 40
SEED = 5
REPORT = ("row_cn0", "row_reported_sigma")
CN0_HIGH = 60.0
SIGMA_HIGH = 100.0


class Run(NamedTuple):
    obs: np.ndarray  # (STEPS + 1, B, dim)
    reward: np.ndarray
    pos_err: np.ndarray
    cols: dict[str, slice]
    episodes: Any


@functools.cache
def _run(env_id: str, offset: float | None) -> Run:
    """``STEPS`` steps of the native vector env under seeded random actions (``None``: no kwarg)."""
    kw = {} if offset is None else {"cn0_offset_db": offset}
    env = gym.make_vec(
        env_id, num_envs=NUM_ENVS, vectorization_mode="vector_entry_point", episode_steps=60, **kw
    )
    nav = navigation_env(env)
    obs, _ = env.reset(seed=SEED)
    env.action_space.seed(SEED)
    out, rew, err = [obs], [], []
    for _ in range(STEPS):
        obs, r, _, _, info = env.step(env.action_space.sample())
        out.append(obs)
        rew.append(r)
        err.append(info["pos_err_m"])
    cols = {name: nav.observation_features.index(name) for name in REPORT}
    episodes = nav.core.episodes
    env.close()
    return Run(np.stack(out), np.stack(rew), np.stack(err), cols, episodes)


def _platform(env_id: str) -> str:
    return env_id.removeprefix("navgym/").removesuffix("RowScale-v3")


def _report(run: Run, name: str) -> np.ndarray:
    return run.obs[..., run.cols[name]].astype(np.float64)


def _others(run: Run) -> np.ndarray:
    keep = np.ones(run.obs.shape[-1], bool)
    for s in run.cols.values():
        keep[s] = False
    return run.obs[..., keep]


# ---------------------------------------------------------------------------- the report shifts
@pytest.mark.parametrize("env_id", V3_IDS)
@pytest.mark.parametrize("offset", [3.0, -3.0])
def test_an_integer_offset_shifts_row_cn0_exactly(env_id, offset):
    base, moved = _run(env_id, None), _run(env_id, offset)
    b, m = _report(base, "row_cn0"), _report(moved, "row_cn0")
    received = b > 0
    assert received.sum() >= 20, "too few received rows to test"
    np.testing.assert_allclose(m[received], np.clip(b[received] + offset, 0.0, CN0_HIGH), rtol=0, atol=1e-4)
    np.testing.assert_array_equal(m[~received], 0.0)  # rows not received stay 0
    if _platform(env_id) == "GpsIns":  # per-row reports: on the 1 dB-Hz grid
        np.testing.assert_array_equal(m, np.round(m))


@pytest.mark.parametrize("env_id", V3_IDS)
def test_a_fractional_offset_moves_row_cn0_within_the_resolution(env_id):
    base, moved = _run(env_id, None), _run(env_id, 2.5)
    b, m = _report(base, "row_cn0"), _report(moved, "row_cn0")
    inside = (b > 0) & (b + 3.0 < CN0_HIGH)
    assert inside.sum() >= 20
    shift = m[inside] - b[inside]
    assert np.all(np.abs(shift - 2.5) <= 0.5 + 1e-4), shift
    assert not np.allclose(shift, 2.5)  # the rounding acts after the offset, per satellite
    np.testing.assert_array_equal(m[b == 0], 0.0)
    if _platform(env_id) == "GpsIns":
        np.testing.assert_array_equal(m, np.round(m))


@pytest.mark.parametrize("env_id", V3_IDS)
@pytest.mark.parametrize("offset", [3.0, -3.0])
def test_reported_sigma_follows_the_reported_cn0(env_id, offset):
    """A higher reported C/N0 gives a smaller sigma: ``10^(-offset/20)`` times it (SIGMA-epsilon)."""
    base, moved = _run(env_id, None), _run(env_id, offset)
    b, m = _report(base, "row_reported_sigma"), _report(moved, "row_reported_sigma")
    np.testing.assert_array_equal(m == 0, b == 0)  # the same rows carry a figure
    ok = (b > 0) & (b < 0.5 * SIGMA_HIGH) & (m < 0.5 * SIGMA_HIGH)  # neither clipped
    assert ok.sum() >= 20
    ratio = m[ok] / b[ok]
    if _platform(env_id) in SIGMA_EPSILON:
        np.testing.assert_allclose(ratio, 10.0 ** (-offset / 20.0), rtol=1e-5)
    else:  # DLL jitter: sigma^2 ~ u (1 + a u), u = 10^(-C/N0/10)
        lo, hi = sorted((10.0 ** (-offset / 10.0), 10.0 ** (-offset / 20.0)))
        assert np.all((ratio >= lo * (1 - 1e-5)) & (ratio <= hi * (1 + 1e-5))), ratio
    assert np.all(ratio < 1.0) if offset > 0 else np.all(ratio > 1.0)


@pytest.mark.parametrize("env_id", V3_IDS)
def test_truth_measurements_and_errors_are_unchanged(env_id):
    """Only the report moves: the rest of the observation, rewards, errors and episodes are equal."""
    base, moved = _run(env_id, None), _run(env_id, 3.0)
    np.testing.assert_array_equal(_others(moved), _others(base))
    np.testing.assert_array_equal(moved.reward, base.reward)
    np.testing.assert_array_equal(moved.pos_err, base.pos_err)
    eb, em = base.episodes, moved.episodes
    compared = 0
    for f in eb._fields:
        a, c = getattr(eb, f), getattr(em, f)
        if f == "context":
            for g in a._fields:
                if g not in ("row_cn0", "row_sigma"):  # the receiver's other reports / the draws
                    np.testing.assert_array_equal(getattr(c, g), getattr(a, g), err_msg=f"context.{g}")
            if "row_cn0" in a._fields:
                assert not np.array_equal(c.row_cn0, a.row_cn0)
        elif isinstance(a, np.ndarray) and a.dtype == object:  # generators: no extra draws
            assert [g.bit_generator.state for g in c] == [g.bit_generator.state for g in a], f
        elif isinstance(a, np.ndarray):
            np.testing.assert_array_equal(c, a, err_msg=f)
            compared += 1
    assert compared >= 8


@pytest.mark.parametrize("env_id", V3_IDS)
def test_offset_zero_is_the_default(env_id):
    base, zero = _run(env_id, None), _run(env_id, 0.0)
    np.testing.assert_array_equal(zero.obs, base.obs)
    np.testing.assert_array_equal(zero.pos_err, base.pos_err)
    np.testing.assert_array_equal(zero.reward, base.reward)


# ---------------------------------------------------------------------------- the argument
def _make(env_id: str, **kw: Any) -> None:
    with superseded_ids_quiet():
        gym.make(env_id, episode_steps=20, **kw).close()


@pytest.mark.parametrize("env_id", V3_IDS)
def test_the_range_is_enforced_naming_the_argument(env_id):
    for bad in (10.5, -10.01, float("nan"), float("inf"), 1e9):
        with pytest.raises(ValueError, match="cn0_offset_db"):
            _make(env_id, cn0_offset_db=bad)
    for bad in ("3 dB", None, True):
        with pytest.raises(TypeError, match="cn0_offset_db"):
            _make(env_id, cn0_offset_db=bad)
    for good in (-10.0, 10.0, 1, np.float32(2.5)):
        _make(env_id, cn0_offset_db=good)


@pytest.mark.parametrize("env_id", V2_IDS)
def test_v2_ids_refuse_it(env_id):
    with pytest.raises(TypeError, match="cn0_offset_db"):
        _make(env_id, cn0_offset_db=1.0)


@pytest.mark.parametrize("cls", [GpsInsPlatform, QuadrotorPlatform, Robot2dPlatform, PedestrianPlatform])
def test_platforms_refuse_an_offset_without_context_or_out_of_range(cls):
    with pytest.raises(ValueError, match="cn0_offset_db.*context=True"):
        cls(cn0_offset_db=2.0)
    with pytest.raises(ValueError, match="cn0_offset_db"):
        cls(context=True, cn0_offset_db=-12.0)
    assert cls(context=True, cn0_offset_db=-4.0).cn0_offset_db == -4.0
    assert cls().cn0_offset_db == 0.0


@pytest.mark.parametrize("card", [GPS_INS_V3_CARD, QUADROTOR_V3_CARD, ROBOT2D_V3_CARD, PEDESTRIAN_V3_CARD])
def test_the_cards_document_it(card):
    assert "``cn0_offset_db`` [dB] in [-10, 10]" in card


# ---------------------------------------------------------------------------- the chains
def _scenarios() -> list[Scenario]:
    return [
        Scenario(duration=60.0),
        Scenario(duration=60.0, jamming=(Jamming(10.0, 40.0, jam_sigma=30.0),)),
        Scenario(duration=60.0, canyons=(UrbanCanyon(5.0, 30.0, max_satellites=6, noise_scale=3.0),)),
        Scenario(duration=60.0, multipath=(Multipath(10.0, 50.0, row=0, bias=20.0),)),
    ]


def test_the_shared_chain_shifts_the_report_and_keeps_the_truth():
    scen = _scenarios()
    batch = stack_scenarios(scen)
    tt = np.broadcast_to(np.arange(601) * 0.1, (len(scen), 601))
    cap = np.full(tt.shape, 12)
    seeds = np.arange(len(scen)) + 3
    a = receiver_report.receiver_physics(quad_cx.RECEIVER, seeds, batch, tt, cap, 2.0)
    b = receiver_report.receiver_physics(quad_cx.RECEIVER, seeds, batch, tt, cap, 2.0, cn0_offset_db=4.0)
    for f in ("n_sv", "hdop", "cn0_true", "uere_factor"):
        np.testing.assert_array_equal(getattr(b, f), getattr(a, f), err_msg=f)
    np.testing.assert_allclose(b.cn0_reported, a.cn0_reported + 4.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.reported_factor, a.reported_factor * 10.0**-0.4, rtol=1e-12)


def test_robot2d_chain_shifts_both_receivers_reports_and_keeps_the_truth():
    scen = _scenarios()
    batch = stack_scenarios(scen)
    tt = np.broadcast_to(np.arange(601) * 0.1, (len(scen), 601))
    seeds = np.arange(len(scen)) + 3
    a = robot_cx.receiver_physics(seeds, batch, tt, (3.0, 5.0))
    b = robot_cx.receiver_physics(seeds, batch, tt, (3.0, 5.0), cn0_offset_db=-2.0)
    for f in ("n_sv", "hdop", "cn0_true", "fix_var"):
        np.testing.assert_array_equal(getattr(b, f), getattr(a, f), err_msg=f)
    np.testing.assert_allclose(b.cn0_reported, a.cn0_reported - 2.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.reported_sigma, a.reported_sigma * 10.0**0.1, rtol=1e-12)


def test_check_cn0_offset():
    receiver_report.check_cn0_offset(0.0, False)
    receiver_report.check_cn0_offset(receiver_report.CN0_OFFSET_MAX_DB, True)
    for bad in (10.000001, float("nan"), "x", True):
        with pytest.raises(ValueError, match="cn0_offset_db must be a finite number in"):
            receiver_report.check_cn0_offset(bad, True)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="needs context=True"):
        receiver_report.check_cn0_offset(1.0, False)
