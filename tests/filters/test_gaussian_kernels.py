"""The compiled KF/EKF predict and update (filters.core.gaussian_kernels) equal the NumPy path.

Same inputs on both paths, the NumPy path forced by ``filters.core.compiled.numpy_only``; each
test checks that the kernel ran (or did not, where it must not apply), so a silent fallback
cannot make an equality pass.
"""

from contextlib import nullcontext

import numpy as np
import pytest

from filters import kalman
from filters.core import gaussian_kernels
from filters.core.compiled import numpy_only
from filters.core.types import GaussianState
from filters.examples import RangeTracking
from tests.filters.compiled_paths import both_paths, count_calls

B = 64
RTOL, ATOL = 1e-9, 1e-9  # rounding of O(100) operations on the problem's numbers


@pytest.fixture
def calls(monkeypatch):
    return count_calls(monkeypatch, gaussian_kernels, ("sandwich_pass", "update_pass"))


def _assert_step_equal(a, b):
    (sa, ia), (sb, ib) = a, b
    scale = np.abs(sb.P).max()
    np.testing.assert_allclose(sa.m, sb.m, rtol=RTOL, atol=ATOL * np.abs(sb.m).max())
    np.testing.assert_allclose(sa.P, sb.P, rtol=RTOL, atol=ATOL * scale)
    np.testing.assert_array_equal(sa.P, np.swapaxes(sa.P, 1, 2))  # exactly symmetric
    for f in ("innovation", "S", "nis", "log_likelihood"):
        np.testing.assert_allclose(getattr(ia, f), getattr(ib, f), rtol=RTOL, atol=ATOL, err_msg=f)
    np.testing.assert_array_equal(ia.healthy, ib.healthy)
    np.testing.assert_array_equal(ia.n_meas, ib.n_meas)


def _setup(linear, seed=0):
    problem = RangeTracking()
    model = problem.linear() if linear else problem
    rng = np.random.default_rng(seed)
    _, m0, P0 = problem.initial_state(B, rng)
    z = model.h(m0) + rng.standard_normal((B, problem.m))
    return model, GaussianState(m0, P0), z, rng


@pytest.mark.parametrize("linear", [True, False], ids=["kf", "ekf"])
def test_predict_and_update_equal_the_numpy_path(calls, linear):
    model, st, z, rng = _setup(linear)
    mask = rng.random(z.shape) > 0.3
    mask[3] = False  # an outage
    z = np.where(mask, z, np.nan)
    fading = 1.0 + rng.random(B)

    def step():
        pred = kalman.predict(st, model, fading=fading)
        return pred, kalman.update(pred, z, model, mask=mask)

    (pa, a), (pb, b) = both_paths(step)
    assert calls == {"sandwich_pass": 1, "update_pass": 1}
    np.testing.assert_allclose(pa.P, pb.P, rtol=RTOL, atol=ATOL * np.abs(pb.P).max())
    np.testing.assert_allclose(pa.m, pb.m, rtol=0, atol=0)
    _assert_step_equal(a, b)
    assert a[1].healthy.all()
    np.testing.assert_array_equal(a[1].innovation[~mask], 0.0)
    np.testing.assert_allclose(a[0].m[3], pa.m[3], atol=1e-12)  # outage: prior kept


def test_batched_noise_and_measurement_matrices(calls):
    model, st, z, rng = _setup(True, seed=1)
    A = rng.standard_normal((B, 4, 4))
    R = A @ np.swapaxes(A, 1, 2) + 4 * np.eye(4)  # full, per filter
    Q = np.broadcast_to(model.Q, (B, 9, 9)) * (1 + rng.random(B))[:, None, None]

    class PerFilterH:
        R = model.R

        def h(self, m):
            return model.h(m)

        def H(self, m):
            return np.broadcast_to(model.observation_matrix, (m.shape[0], 4, 9)).copy()

    def step():
        return kalman.update(kalman.predict(st, model, Q=Q), z, PerFilterH(), R=R)

    _assert_step_equal(*both_paths(step))
    assert calls == {"sandwich_pass": 1, "update_pass": 1}


def test_indefinite_innovation_covariance_is_left_to_the_numpy_jitter_path(calls):
    model, st, z, _ = _setup(True)
    R = -np.eye(4) * 1e3  # S = H P H^T + R not positive definite for every filter
    a, b = both_paths(lambda: kalman.update(st, z, model, R=R))
    assert calls["update_pass"] == 1  # ran, found S indefinite, handed over
    _assert_step_equal(a, b)
    assert not a[1].healthy.any()


def test_unhealthy_posterior_is_flagged_as_by_the_numpy_path(calls):
    model, st, z, _ = _setup(True)
    P = st.P.copy()
    P[5] = -np.eye(9)  # an indefinite prior: its posterior is not positive definite
    P[6, 8, 8] = -50.0
    a, b = both_paths(lambda: kalman.update(GaussianState(st.m, P), z, model))
    assert calls["update_pass"] == 1
    _assert_step_equal(a, b)
    assert not a[1].healthy[5] and not a[1].healthy[6] and a[1].healthy[:5].all()


def test_float32_beliefs_and_large_states_take_the_numpy_path(calls):
    model, st, z, _ = _setup(True)
    kalman.update(GaussianState(st.m.astype(np.float32), st.P.astype(np.float32)), z, model)
    assert calls["update_pass"] == 0
    n = gaussian_kernels.MAX_STATES + 1
    from filters.core.models import LinearGaussianModel

    big = LinearGaussianModel(np.eye(n), np.eye(2, n), np.eye(n), np.eye(2))
    s = kalman.predict(GaussianState(np.zeros((2, n)), np.broadcast_to(np.eye(n), (2, n, n)).copy()), big)
    kalman.update(s, np.zeros((2, 2)), big)
    assert calls == {"sandwich_pass": 0, "update_pass": 0}


def test_more_rows_than_states_take_the_numpy_update(calls):
    """12 rows of a 2-state filter: the NumPy path (observed-subspace form), predict compiled."""
    from filters.core.models import LinearGaussianModel

    H = np.random.default_rng(2).standard_normal((12, 2))
    model = LinearGaussianModel(np.eye(2), H, np.eye(2), np.eye(12))
    st = GaussianState(np.zeros((3, 2)), np.broadcast_to(np.eye(2), (3, 2, 2)).copy())
    kalman.update(kalman.predict(st, model), np.ones((3, 12)), model)
    assert calls == {"sandwich_pass": 1, "update_pass": 0}


@pytest.mark.parametrize("Bn", [1, 7])
def test_single_filter_and_non_contiguous_inputs(calls, Bn):
    """B = 1 and a batch not a multiple of the lanes, with strided ``m`` and a transposed-view ``P``."""
    model, st, z, rng = _setup(False, seed=3)
    big = np.zeros((B, 12))
    big[:, 2:11] = st.m
    m = big[:Bn, 2:11]
    P = np.ascontiguousarray(np.swapaxes(st.P[:Bn], 1, 2)).swapaxes(1, 2)
    mask = rng.random((Bn, 4)) > 0.2

    def step():
        pred = kalman.predict(GaussianState(m, P), model, fading=1.5)
        return kalman.update(pred, z[:Bn], model, mask=mask)

    _assert_step_equal(*both_paths(step))
    assert calls == {"sandwich_pass": 1, "update_pass": 1}


def test_bad_input_raises_the_same_value_errors_on_both_paths(calls):
    model, st, z, _ = _setup(True)
    bad_P = GaussianState(st.m, st.P.copy())
    bad_P.P[2, 0, 0] = np.nan
    for ctx in (nullcontext(), numpy_only()):
        with ctx:
            with pytest.raises(ValueError, match="state.P has non-finite entries"):
                kalman.predict(bad_P, model)
            with pytest.raises(ValueError, match="z must have shape"):
                kalman.update(st, z[:, :3, None], model)
            with pytest.raises(ValueError, match="R must have shape"):
                kalman.update(st, z, model, R=np.eye(3))
            with pytest.raises(ValueError, match="Q must have shape"):
                kalman.predict(st, model, Q=np.eye(8))
            with pytest.raises(ValueError, match="fading must be finite and positive"):
                kalman.predict(st, model, fading=-1.0)
            with pytest.raises(ValueError, match="unmasked rows"):
                kalman.update(st, np.where(np.arange(4) == 1, np.nan, z), model)
    assert calls == {"sandwich_pass": 0, "update_pass": 0}
