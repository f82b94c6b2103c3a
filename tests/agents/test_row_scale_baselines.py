"""The RowScale baselines (v3): their rules on hand-made observations, and as policies on a toy.

The toy is :mod:`tests.navgym.envs.toy_v2`'s linear platform (two fix rows) with a context of
its own (:class:`ContextToy`): per-row C/N0, elevation and reported sigma and an IMU statistic,
deterministic functions of the step, so each rule's scales have a known answer.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from agents.baselines.registry import BASELINES, baseline_specs, make_baseline, make_baselines
from agents.baselines.row_scale import (
    CN0_FEATURE,
    ELEVATION_FEATURE,
    IMU_FEATURE,
    REPORTED_SIGMA_FEATURE,
)
from navgym.envs.features import Feature
from navgym.envs.platform import PlatformArgs, PlatformEnv, PlatformVectorEnv
from tests.navgym.envs import toy_v2

CN0 = np.array([45.0, 30.0])
ELEVATION = np.array([90.0, 30.0])
SIGMA = np.array([2.0, 10.0])


@dataclass(frozen=True)
class ContextToy(toy_v2.ToyPlatform):
    """The toy with a fixed context: C/N0 (45, 30) dB-Hz, elevation (90, 30) deg, sigma (2, 10) m."""

    imu: float = 1.0

    def features(self):
        return [
            *super().features(),
            Feature(CN0_FEATURE, 0.0, 60.0, "dB-Hz", "C/N0", 2),
            Feature(ELEVATION_FEATURE, 0.0, 90.0, "deg", "elevation", 2),
            Feature(REPORTED_SIGMA_FEATURE, 0.0, 100.0, "m", "reported sigma", 2),
            Feature(IMU_FEATURE, 0.0, 100.0, "-", "IMU activity"),
        ]

    def _context(self, B: int) -> dict[str, np.ndarray]:
        return {
            CN0_FEATURE: np.tile(CN0, (B, 1)),
            ELEVATION_FEATURE: np.tile(ELEVATION, (B, 1)),
            REPORTED_SIGMA_FEATURE: np.tile(SIGMA, (B, 1)),
            IMU_FEATURE: np.full(B, self.imu),
        }

    def initial_feature_values(self, belief, ep):
        return {**super().initial_feature_values(belief, ep), **self._context(belief.m.shape[0])}

    def feature_values(self, belief, info, models, ep, t):
        return {**super().feature_values(belief, info, models, ep, t), **self._context(belief.m.shape[0])}


def _build(a: PlatformArgs) -> ContextToy:
    imu = float(a.kwargs.pop("imu", 1.0))
    return ContextToy(**{**vars(toy_v2.build_toy(a)), "imu": imu})


SPEC = replace(
    toy_v2.TOY, name="ContextToy", build=_build, platform_arguments=(*toy_v2.TOY.platform_arguments, "imu")
)


class ContextEnv(PlatformEnv, spec=SPEC):
    """A point in the plane with a context."""


class ContextVectorEnv(PlatformVectorEnv, spec=SPEC):
    """Native batched ContextToy environment."""


def _scales(baseline, env, obs):
    """The scales ``(B, 3)`` a baseline's action maps to."""
    a, _ = baseline.predict(obs)
    return env.unwrapped.core.task.knob_of(np.asarray(a, dtype=np.float64))


def test_the_family_lists_the_context_baselines_only_where_the_env_has_the_context():
    plain = toy_v2.ToyEnv(task="rowscale")
    assert set(baseline_specs(plain)) == {"plain", "constant", "chi_square", "row_iae"}
    assert set(baseline_specs(ContextEnv(task="rowscale"))) == set(BASELINES["RowScale"])
    with pytest.raises(ValueError, match="context features"):
        BASELINES["RowScale"]["cn0_weighting"].cls(plain)


def test_the_context_rules_give_their_textbook_scales():
    env = ContextEnv(task="rowscale", imu=5.0)
    obs, _ = env.reset(seed=0)
    obs = obs[None]
    cn0 = make_baseline(env, "cn0_weighting", cn0_ref=45.0)
    np.testing.assert_allclose(_scales(cn0, env, obs)[0, :2], [1.0, 10**1.5], rtol=1e-5)
    el = make_baseline(env, "elevation_weighting", k=1.0, c=1.0)
    np.testing.assert_allclose(_scales(el, env, obs)[0, :2], [1.0, (1 + 4.0) / 2.0], rtol=1e-5)
    acc = make_baseline(env, "reported_accuracy", c=0.25)
    np.testing.assert_allclose(_scales(acc, env, obs)[0, :2], [1.0, 25.0], rtol=1e-5)
    mask = make_baseline(env, "cn0_mask_fde", mask_dbhz=35.0, s_excl=100.0)
    np.testing.assert_allclose(_scales(mask, env, obs)[0, :2], [1.0, 100.0], rtol=1e-5)
    # the IMU rule (threshold a fraction of the feature's bound 100): activity 5 above 3 ->
    # s_q_high; below 6 -> s_q_low
    hi = make_baseline(env, "cn0_weighting", imu_threshold=0.03, s_q_low=10.0, s_q_high=1000.0)
    np.testing.assert_allclose(_scales(hi, env, obs)[0, 2], 1000.0, rtol=1e-5)
    lo = make_baseline(env, "cn0_weighting", imu_threshold=0.06, s_q_low=10.0, s_q_high=1000.0)
    np.testing.assert_allclose(_scales(lo, env, obs)[0, 2], 10.0, rtol=1e-5)


def test_plain_is_every_scale_one_and_constant_its_two_values():
    env = toy_v2.ToyEnv(task="rowscale")
    obs, _ = env.reset(seed=0)
    plain = make_baseline(env, "plain")
    np.testing.assert_array_equal(plain.predict(obs)[0], env.unwrapped.core.task.neutral_action())
    const = make_baseline(env, "constant", s_r=3.0, s_q=100.0)
    np.testing.assert_allclose(_scales(const, env, obs[None])[0], [3.0, 3.0, 100.0], rtol=1e-5)


def test_chi_square_excludes_a_row_with_a_gross_error_and_row_iae_raises_its_scale():
    env = toy_v2.ToyEnv(task="rowscale", bias=(0.0, 60.0))  # row 1 carries a 20-sigma bias
    chi = make_baseline(env, "chi_square", alpha=0.01, s_excl=1e4)
    iae = make_baseline(env, "row_iae", b=0.5, beta=1.0)
    obs, _ = env.reset(seed=1)
    flagged, scales = [], []
    for _ in range(15):
        s_chi = _scales(chi, env, obs[None])[0]
        s_iae = _scales(iae, env, obs[None])[0]
        obs, *_ = env.step(chi.predict(obs)[0])
        flagged.append(s_chi[1] > 1.0 and s_chi[0] == 1.0)
        scales.append(s_iae[:2])
    assert np.mean(flagged[1:]) > 0.5
    assert np.mean([s[1] > 10 * s[0] for s in scales[3:]]) > 0.5


def test_every_baseline_runs_as_a_batched_policy_with_parameter_arrays():
    venv = ContextVectorEnv(num_envs=4, task="rowscale")
    obs, _ = venv.reset(seed=3)
    grids = {n: s.grid for n, s in BASELINES["RowScale"].items()}
    policies = make_baselines(venv)
    for name in BASELINES["RowScale"]:
        params = {k: np.resize(np.asarray(v, dtype=float), 4) for k, v in grids[name].items()}
        policies[f"{name}/grid"] = make_baseline(venv, name, **params)
    for _ in range(5):
        for p in policies.values():
            a, _ = p.predict(obs)
            assert a.shape == (4, 3) and np.isfinite(a).all() and (np.abs(a) <= 1).all()
        obs, *_ = venv.step(policies["plain"].predict(obs)[0])


@pytest.mark.parametrize(
    ("name", "params", "match"),
    [
        ("constant", {"s_q": 0.0}, "s_q"),
        ("chi_square", {"alpha": 1.5}, "alpha"),
        ("row_iae", {"b": 1.0}, "b"),
    ],
)
def test_bad_parameters_are_refused_naming_them(name, params, match):
    with pytest.raises(ValueError, match=match):
        make_baseline(toy_v2.ToyEnv(task="rowscale"), name, **params)
