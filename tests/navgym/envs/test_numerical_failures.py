"""A numerical failure in one sub-env ends that episode only; the others do not change a bit.

Each test runs a batch with a row that fails and the same batch without that row (sub-env i
of a vector env reset with a list of seeds is the episode of its own seed), and holds the other
rows' trajectories equal bit for bit.
"""

from __future__ import annotations

import copy
import warnings

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401  (registers the ids)
from navgym.gps_ins.env import GPS_INS

KEYS = ("obs", "reward", "terminated", "truncated", "pos_err_m", "healthy")


def _trace(venv, seeds, actions, setup=None):
    """Per-step arrays of ``KEYS`` (rows = sub-envs) and the divergence reasons."""
    venv.reset(seed=list(seeds))
    if setup is not None:
        setup(venv.unwrapped.core)
    out = {k: [] for k in (*KEYS, "reason")}
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no NumPy overflow noise either
        for a in actions:
            obs, r, term, trunc, info = venv.step(a)
            valid = info["_pos_err_m"]  # False for the sub-envs autoreset at this step
            err = np.where(valid, info["pos_err_m"], -1.0)
            healthy = np.where(valid, info["healthy"], True)
            for k, v in zip(KEYS, (obs, r, term, trunc, err, healthy), strict=True):
                out[k].append(np.array(v))
            out["reason"].append(np.where(valid, info["divergence_reason"], "(reset)"))
    return {k: np.stack(v) for k, v in out.items()}


def _assert_rows_equal(full, without, bad):
    keep = [i for i in range(full["obs"].shape[1]) if i not in bad]
    for k in KEYS:
        np.testing.assert_array_equal(full[k][:, keep], without[k], err_msg=k)


def _compare(env_id, seeds, actions, bad, setup=None, **kwargs):
    """Trace with every row and without the rows ``bad``; the kept rows must be equal."""
    make = lambda n: gym.make_vec(  # noqa: E731
        env_id, num_envs=n, vectorization_mode="vector_entry_point", **kwargs
    )
    full = _trace(make(len(seeds)), seeds, actions, setup)
    keep = [i for i in range(len(seeds)) if i not in bad]
    without = _trace(make(len(keep)), [seeds[i] for i in keep], [a[keep] for a in actions], setup)
    _assert_rows_equal(full, without, bad)
    return full


def test_an_overflowing_fading_prediction_ends_only_its_episode():
    """lambda_max = 1e300: a grown covariance times the largest factor overflows in one row."""
    B, bad, steps, step = 6, 2, 9, 6
    actions = []
    for k in range(steps):
        a = np.full((B, 1), -1.0, np.float32)
        a[1::2] = -0.999  # a mild factor (1.4) for some healthy rows
        a[bad] = -0.97 if k < step else 1.0  # the covariance grows (lambda 3e4), then lambda = 1e300
        actions.append(a)
    full = _compare("navgym/GpsInsFading-v1", [40 + i for i in range(B)], actions, [bad], lambda_max=1e300)
    assert full["terminated"][step, bad] and not full["healthy"][step, bad]
    assert full["reason"][step, bad] == "numerical failure"
    assert np.isnan(full["pos_err_m"][step, bad])
    T = 300
    assert full["reward"][step, bad] == -10.0 - (100.0 + 10.0 * (T - step - 1))  # worst accuracy + penalty
    assert np.isfinite(full["obs"]).all()
    assert not full["terminated"][:, [i for i in range(B) if i != bad]].any()


def test_a_singular_innovation_covariance_ends_only_its_episode():
    """Roughening by 1e9 m (beyond the argument's bound, set on the task to provoke it) makes one
    filter's innovation covariance singular to working precision: it was a LinAlgError."""
    B = 32
    rng = np.random.default_rng(0)
    actions = [rng.integers(0, 2, B) for _ in range(3)]

    def rough(core):
        core.task.roughening = 1e9

    full = _compare(
        "navgym/Robot2dResample-v1", list(range(B)), actions, [27], setup=rough, max_episode_steps=50
    )
    assert full["reason"][1, 27] in ("numerical failure", "health") and full["terminated"][1, 27]
    assert not full["healthy"][1, 27]


def test_a_filter_that_raises_for_one_row_is_isolated_by_bisection():
    """A filter step that raises LinAlgError for one member (here: a test double, after its random
    draws) ends that row's episode; the other rows get the same numbers and random draws."""
    B, bad = 7, 4
    actions = []
    for k in range(6):
        a = np.zeros(B, np.int64)
        a[bad] = int(k == 2)  # the bad row resamples once: roughened by 1e7, then the filter raises
        actions.append(a)

    def raising(core):
        core.task.roughening = 1e7
        plain = core.task.filter_step

        def filter_step(particles, models, rngs, prior_weights=None):
            out = plain(particles, models, rngs, prior_weights)  # draws first, like a failing update would
            if (np.abs(particles.x) > 1e6).any():
                raise np.linalg.LinAlgError("Singular matrix")
            return out

        core.task.filter_step = filter_step

    full = _compare(
        "navgym/Robot2dResample-v1",
        [70 + i for i in range(B)],
        actions,
        [bad],
        setup=raising,
        max_episode_steps=50,
        n_particles=100,
    )
    assert full["reason"][2, bad] == "numerical failure" and full["terminated"][2, bad]
    assert (full["reason"][:, [i for i in range(B) if i != bad]] == "").all()
    assert not full["terminated"][3:, bad].any()  # the autoreset episode goes on


def test_a_core_stepped_on_with_a_non_finite_row_isolates_it():
    """A row whose state became NaN (a core stepped without reset) no longer stops the batch."""
    B, bad = 4, 1
    core = GPS_INS.core("fading", B, {})
    rngs = [np.random.default_rng(i) for i in range(B)]
    core.reset(np.arange(B), rngs, [None] * B)
    ref = copy.deepcopy(core)
    P = core.state.P.copy()
    P[bad, 0, 0] = np.nan
    core.state = core.state._replace(P=P)
    a = np.zeros((B, 1), np.float32)
    for k in range(3):  # then the row goes on from its placeholder (finite)
        obs, r, term, _, info = core.step(a, rngs)
        obs_ref, r_ref, *_ = ref.step(a, rngs)
        keep = [0, 2, 3]
        np.testing.assert_array_equal(obs[keep], obs_ref[keep])
        np.testing.assert_array_equal(r[keep], r_ref[keep])
        assert np.isfinite(obs).all() and np.isfinite(core.state.P).all()
        if k == 0:
            assert term[bad] and info["divergence_reason"][bad] == "numerical failure"
            assert not term[keep].any()


def test_an_exception_that_is_not_numerical_still_raises():
    core = GPS_INS.core("fading", 2, {})
    rngs = [np.random.default_rng(i) for i in range(2)]
    core.reset(np.arange(2), rngs, [None] * 2)
    models = core.platform.step_models

    def broken(episodes, t):
        m = models(episodes, t)
        return m._replace(z=np.full_like(m.z, np.nan))  # unmasked NaN measurements: a bug

    core.platform = copy.copy(core.platform)
    object.__setattr__(core.platform, "step_models", broken)
    with pytest.raises(ValueError, match="non-finite"):
        core.step(np.zeros((2, 1), np.float32), rngs)


def test_single_env_reports_the_reason():
    env = gym.make("navgym/GpsInsFading-v1", divergence_m=1e-3)
    env.reset(seed=0)
    *_, term, _, info = env.step(np.zeros(1, np.float32))
    assert term and info["divergence_reason"] == "error bound"
    env.reset(seed=0)
    env.step(np.zeros(1, np.float32))
    env = gym.make("navgym/GpsInsFading-v1")
    env.reset(seed=0)
    *_, term, _, info = env.step(np.zeros(1, np.float32))
    assert not term and info["divergence_reason"] == ""


@pytest.mark.parametrize("task", ["mixture", "fading"])
def test_an_indefinite_covariance_in_one_sigma_point_row_leaves_the_others_exact(task):
    """A CKF row whose covariance is finite but not positive definite takes the Cholesky
    fallback; the other rows keep the numbers of a batch without it, bit for bit."""
    B, bad = 5, 3
    core = GPS_INS.core(task, B, {"filter": "ckf"})
    rngs = [np.random.default_rng(i) for i in range(B)]
    core.reset(np.arange(B), rngs, [None] * B)
    for _ in range(5):  # full covariances (the prior is diagonal: any factorization is exact)
        core.step(np.zeros((B, 1), np.float32), rngs)
    ref = copy.deepcopy(core)
    P = core.state.P.copy()
    P[bad] = -P[bad]
    core.state = core.state._replace(P=P)
    keep = [i for i in range(B) if i != bad]
    a = np.zeros((B, 1), np.float32)
    for _ in range(3):
        out, out_ref = core.step(a, rngs), ref.step(a, rngs)
        for x, y in zip(out[:4], out_ref[:4], strict=True):
            np.testing.assert_array_equal(x[keep], y[keep])
        np.testing.assert_array_equal(core.state.P[keep], ref.state.P[keep])


def test_nees_of_the_other_rows_does_not_change_with_an_indefinite_row():
    from filters.core.types import GaussianState
    from navgym.envs.core import _nees

    rng = np.random.default_rng(3)
    B, n = 9, 8
    A = rng.standard_normal((B, n, n))
    P = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(n)
    e = rng.standard_normal((B, n))
    bad = P.copy()
    bad[4] = -np.eye(n)
    bad[6] = np.nan
    keep = [i for i in range(B) if i not in (4, 6)]
    out = _nees(GaussianState(np.zeros((B, n)), bad), e)
    ref = _nees(GaussianState(np.zeros((len(keep), n)), P[keep]), e[keep])
    np.testing.assert_array_equal(out[keep], ref)
    assert out[4] == pytest.approx(-(e[4] @ e[4])) and np.isnan(out[6])
