"""The compiled sigma-point predict and update (filters.core.sigma_point_kernels) equal the NumPy path.

Same inputs on both paths, the NumPy path forced by ``filters.core.compiled.numpy_only``; each
test checks that the kernels ran (or did not, where they must not apply), so a silent
fallback cannot make an equality pass.
"""

from contextlib import nullcontext

import numpy as np
import pytest

from filters import sigma_point
from filters.core import gaussian_kernels, sigma_point_kernels
from filters.core.compiled import numpy_only
from filters.core.conditioning import condition
from filters.core.linalg import is_positive_definite
from filters.core.models import ElementwiseModel
from filters.core.quadrature import Cubature, GaussHermite, Unscented
from filters.core.types import GaussianState
from filters.examples import RangeTracking
from tests.filters.compiled_paths import both_paths, count_calls

RTOL, ATOL = 1e-9, 1e-9
RULES = [Cubature(), Unscented(), Unscented(0.5, 2.0, 1.0)]
NAMES = ["points_pass", "predict_pass", "moments_pass"]


@pytest.fixture
def calls(monkeypatch):
    return count_calls(monkeypatch, sigma_point_kernels, NAMES)


def _close(a, b, name):
    scale = max(np.abs(b).max(), 1.0)
    np.testing.assert_allclose(a, b, rtol=RTOL, atol=ATOL * scale, err_msg=name)


def _assert_step_equal(a, b):
    (sa, ia), (sb, ib) = a, b
    _close(sa.m, sb.m, "m")
    _close(sa.P, sb.P, "P")
    np.testing.assert_array_equal(sa.P, np.swapaxes(sa.P, 1, 2))  # exactly symmetric
    for f in ("innovation", "S", "nis", "log_likelihood"):
        _close(getattr(ia, f), getattr(ib, f), f)
    np.testing.assert_array_equal(ia.healthy, ib.healthy)
    np.testing.assert_array_equal(ia.n_meas, ib.n_meas)


def _setup(B, seed=0):
    problem = RangeTracking()
    rng = np.random.default_rng(seed)
    _, m0, P0 = problem.initial_state(B, rng)
    A = rng.standard_normal((B, 9, 9)) * 0.3
    P0 = P0 + A @ np.swapaxes(A, 1, 2)  # full, different per filter
    z = problem.h(m0) + rng.standard_normal((B, problem.m))
    return problem, GaussianState(m0, P0), z, rng


@pytest.mark.parametrize("rule", RULES, ids=["ckf", "ukf", "ukf-scaled"])
@pytest.mark.parametrize("B", [1, 7, 64])
def test_predict_and_update_equal_the_numpy_path(calls, rule, B):
    problem, st, z, rng = _setup(B)
    mask = rng.random(z.shape) > 0.3
    mask[0, 1] = True
    if B > 3:
        mask[3] = False  # an outage
    z = np.where(mask, z, np.nan)
    fading = 1.0 + rng.random(B)

    def step():
        pred = sigma_point.predict(st, problem, dt=0.1, rule=rule, fading=fading)
        return pred, sigma_point.update(pred, z, problem, mask=mask, rule=rule)

    (pa, a), (pb, b) = both_paths(step)
    assert calls == {"points_pass": 2, "predict_pass": 1, "moments_pass": 1}
    _close(pa.m, pb.m, "predicted m")
    _close(pa.P, pb.P, "predicted P")
    np.testing.assert_array_equal(pa.P, np.swapaxes(pa.P, 1, 2))
    _assert_step_equal(a, b)
    assert a[1].healthy.all()
    np.testing.assert_array_equal(a[1].innovation[~mask], 0.0)
    if B > 3:
        np.testing.assert_allclose(a[0].m[3], pa.m[3], atol=1e-12)  # outage: prior kept


def test_non_contiguous_inputs_and_per_filter_noise(calls):
    problem, st, z, rng = _setup(64, seed=3)
    big_m = np.zeros((64, 12))
    big_m[:, 1:10] = st.m
    m = big_m[:, 1:10]  # strided rows
    P = np.ascontiguousarray(np.swapaxes(st.P, 1, 2)).swapaxes(1, 2)  # a transposed view
    assert not m.flags.c_contiguous and not P.flags.c_contiguous
    A = rng.standard_normal((64, 4, 4))
    R = A @ np.swapaxes(A, 1, 2) + 4 * np.eye(4)
    Q = np.broadcast_to(problem.Q, (64, 9, 9)) * (1 + rng.random(64))[:, None, None]
    state = GaussianState(m, P)

    def step():
        pred = sigma_point.predict(state, problem, dt=0.1, Q=Q)
        return sigma_point.update(pred, z, problem, R=R)

    _assert_step_equal(*both_paths(step))
    assert calls == {"points_pass": 2, "predict_pass": 1, "moments_pass": 1}


def test_model_output_in_batch_first_order_is_accepted(calls):
    """A model returning C-ordered arrays (not the state-major order of its input) is copied."""
    problem, st, z, _ = _setup(16, seed=4)

    class Contiguous:
        Q, R = problem.Q, problem.R

        def f(self, x, u=None, dt=None):
            return np.ascontiguousarray(problem.f(x, u, dt))

        def h(self, x):
            return np.ascontiguousarray(problem.h(x))

    model = Contiguous()
    _assert_step_equal(*both_paths(lambda: sigma_point.update(sigma_point.predict(st, model), z, model)))
    assert calls["predict_pass"] == 1 and calls["moments_pass"] == 1


def test_indefinite_prior_takes_the_numpy_jitter_points_in_its_own_row_only(calls):
    """The indefinite filter gets the NumPy path's jittered points and its flag; the others keep
    the numbers of a batch without it, bit for bit (a neighbour's failure changes nothing)."""
    problem, st, z, _ = _setup(8)
    P = st.P.copy()
    P[5] = -np.eye(9)  # not positive definite: the NumPy path jitters it and flags it
    state = GaussianState(st.m, P)
    a, b = both_paths(lambda: sigma_point.update(state, z, problem))
    assert calls["points_pass"] == 1 and calls["moments_pass"] == 1
    _assert_step_equal(a, b)
    assert not a[1].healthy[5] and a[1].healthy[:5].all()
    clean = sigma_point.update(st, z, problem)
    keep = [i for i in range(8) if i != 5]
    np.testing.assert_array_equal(a[0].m[keep], clean[0].m[keep])
    np.testing.assert_array_equal(a[0].P[keep], clean[0].P[keep])
    pa, pb = both_paths(lambda: sigma_point.predict(state, problem))
    assert calls["predict_pass"] == 1
    _close(pa.m, pb.m, "m")
    _close(pa.P, pb.P, "P")
    np.testing.assert_array_equal(pa.m[keep], sigma_point.predict(st, problem).m[keep])


def test_the_model_sees_the_numpy_paths_layout(calls):
    """A model's reductions round by memory layout: f and h get C-contiguous (B, S, n) points."""
    problem, st, z, _ = _setup(4)
    seen = []

    class Recording:
        Q, R = problem.Q, problem.R

        def f(self, x, u=None, dt=None):
            seen.append(x.flags.c_contiguous)
            return problem.f(x, u, dt)

        def h(self, x):
            seen.append(x.flags.c_contiguous)
            return problem.h(x)

    sigma_point.update(sigma_point.predict(st, Recording()), z, Recording())
    assert seen == [True, True] and calls["predict_pass"] == 1 and calls["moments_pass"] == 1


def test_an_elementwise_model_sees_the_state_major_points(calls):
    """An ElementwiseModel gets the kernels' state-major points as a (B, S, n) view, no copy."""
    problem, st, z, _ = _setup(4)
    seen = []

    class Recording(ElementwiseModel):
        Q, R = problem.Q, problem.R

        def f(self, x, u=None, dt=None):
            seen.append((x.flags.c_contiguous, x.transpose(2, 0, 1).flags.c_contiguous))
            return problem.f(x, u, dt)

        def h(self, x):
            seen.append((x.flags.c_contiguous, x.transpose(2, 0, 1).flags.c_contiguous))
            return problem.h(x)

    sigma_point.update(sigma_point.predict(st, Recording()), z, Recording())
    assert seen == [(False, True), (False, True)]
    assert calls["predict_pass"] == 1 and calls["moments_pass"] == 1


@pytest.mark.parametrize("rule", RULES[:2], ids=["ckf", "ukf"])
@pytest.mark.parametrize("B", [1, 7, 64])
def test_an_elementwise_model_gives_the_numbers_of_the_batch_first_copy(calls, rule, B):
    """RangeTracking (element-wise) on the state-major view = the same model on the C-contiguous
    copy (a wrapper that does not declare itself element-wise), bit for bit."""
    problem, st, z, _ = _setup(B, seed=11)
    assert isinstance(problem, ElementwiseModel)

    class Plain:
        Q, R = problem.Q, problem.R

        def f(self, x, u=None, dt=None):
            return problem.f(x, u, dt)

        def h(self, x):
            return problem.h(x)

    def step(model):
        pred = sigma_point.predict(st, model, dt=0.1, rule=rule)
        return pred, sigma_point.update(pred, z, model, rule=rule)

    (pa, (sa, ia)), (pb, (sb, ib)) = step(problem), step(Plain())
    for x, y in zip((*pa, *sa, *ia[:5]), (*pb, *sb, *ib[:5]), strict=True):
        np.testing.assert_array_equal(x, y)
    assert calls["predict_pass"] == 2 and calls["moments_pass"] == 2


def test_indefinite_innovation_covariance_is_left_to_the_numpy_jitter_path(calls):
    problem, st, z, _ = _setup(8)
    R = -np.eye(4) * 1e4  # S = C + R not positive definite
    (sa, ia), (sb, ib) = both_paths(lambda: sigma_point.update(st, z, problem, R=R))
    assert calls["moments_pass"] == 1  # the moments compiled, the conditioning's jitter path
    np.testing.assert_array_equal(ia.healthy, ib.healthy)
    assert not ia.healthy.any()
    _close(ia.S, ib.S, "S")
    # the jittered S is near singular (a shift of ~1e4 leaves eigenvalues ~1e-5): the moments'
    # rounding differences (~1e-13) come out amplified by its condition number
    np.testing.assert_allclose(sa.m, sb.m, rtol=1e-4)
    np.testing.assert_allclose(sa.P, sb.P, rtol=1e-4, atol=1e-4 * np.abs(sb.P).max())


def test_bad_model_shapes_raise_value_errors_on_both_paths(calls):
    problem, st, z, _ = _setup(4)

    class Bad:
        Q, R = problem.Q, problem.R

        def f(self, x, u=None, dt=None):
            return x[..., :8]

        def h(self, x):
            return problem.h(x)[..., :3]

    for ctx in (nullcontext(), numpy_only()):
        with ctx:
            with pytest.raises(ValueError, match="model.f returned shape"):
                sigma_point.predict(st, Bad())
            with pytest.raises(ValueError, match="model.h returned shape"):
                sigma_point.update(st, z, Bad())
            with pytest.raises(ValueError, match="z must have shape"):
                sigma_point.update(st, z[:, :, None], problem)
            with pytest.raises(ValueError, match="non-finite"):
                sigma_point.update(GaussianState(st.m, st.P * np.nan), z, problem)


def test_large_rules_float32_and_large_states_take_the_numpy_path(calls):
    problem, st, z, _ = _setup(4)
    sigma_point.update(st, z, problem, rule=GaussHermite(3))  # 3^9 points
    sigma_point.update(GaussianState(st.m.astype(np.float32), st.P.astype(np.float32)), z, problem)
    with numpy_only():
        sigma_point.update(st, z, problem)
    assert calls == dict.fromkeys(NAMES, 0)
    n = gaussian_kernels.MAX_STATES + 1

    class Big:
        Q, R = np.eye(n), np.eye(2)

        def f(self, x, u=None, dt=None):
            return x

        def h(self, x):
            return x[..., :2]

    s = GaussianState(np.zeros((2, n)), np.broadcast_to(np.eye(n), (2, n, n)).copy())
    sigma_point.update(sigma_point.predict(s, Big()), np.zeros((2, 2)), Big())
    assert calls == dict.fromkeys(NAMES, 0)


def test_small_gauss_hermite_rule_takes_the_kernels(calls):
    problem, st, z, _ = _setup(8, seed=5)

    class Planar:  # 2 states, 3^2 = 9 points
        Q, R = np.eye(2) * 0.1, np.eye(1)

        def f(self, x, u=None, dt=None):
            return np.stack([x[..., 0] + 0.1 * x[..., 1], x[..., 1] - 0.01 * np.sin(x[..., 0])], axis=-1)

        def h(self, x):
            return np.sqrt(1.0 + x[..., :1] ** 2)

    st2 = GaussianState(st.m[:, :2], st.P[:, :2, :2])
    rule = GaussHermite(3)
    model = Planar()
    _assert_step_equal(
        *both_paths(
            lambda: sigma_point.update(sigma_point.predict(st2, model, rule=rule), z[:, :1], model, rule=rule)
        )
    )
    assert calls == {"points_pass": 2, "predict_pass": 1, "moments_pass": 1}


def test_measurement_moments_equal_the_numpy_path(calls):
    problem, st, z, rng = _setup(32, seed=6)
    mask = rng.random(z.shape) > 0.3
    a, b = both_paths(lambda: sigma_point.measurement_moments(st, np.where(mask, z, np.nan), problem, mask))
    assert calls["moments_pass"] == 1
    for name, x, y in zip(a._fields, a, b, strict=True):
        _close(x, y, name)
    np.testing.assert_array_equal(a.C, np.swapaxes(a.C, 1, 2))


def test_compiled_steps_do_not_depend_on_the_rest_of_the_batch(calls):
    """A filter's numbers are the same alone and in any batch (banks rely on it, bit for bit)."""
    problem, st, z, _ = _setup(13, seed=8)
    rep = GaussianState(np.repeat(st.m, 3, axis=0), np.repeat(st.P, 3, axis=0))
    zr = np.repeat(z, 3, axis=0)
    whole = sigma_point.update(sigma_point.predict(rep, problem), zr, problem)
    for b in (0, 5, 12):
        one = GaussianState(st.m[b : b + 1], st.P[b : b + 1])
        alone = sigma_point.update(sigma_point.predict(one, problem), z[b : b + 1], problem)
        for x, y in zip((*whole[0], *whole[1][:5]), (*alone[0], *alone[1][:5]), strict=True):
            for r in range(3):
                np.testing.assert_array_equal(x[3 * b + r], y[0])
    assert calls["moments_pass"] == 4


@pytest.mark.parametrize("B", [1, 7, 64])
def test_compiled_condition_equals_the_numpy_condition(B):
    """:func:`gaussian_kernels.condition` against :func:`conditioning.condition`, masks and outages."""
    rng = np.random.default_rng(B)
    n, k = 9, 4
    A = rng.standard_normal((B, n, n))
    P = A @ np.swapaxes(A, 1, 2) + np.eye(n)
    H = rng.standard_normal((B, k, n))
    P_xz = P @ np.swapaxes(H, 1, 2)
    S = H @ P_xz + 2.0 * np.eye(k)
    m, v = rng.standard_normal((B, n)), rng.standard_normal((B, k))
    mask = rng.random((B, k)) > 0.3
    mask[0] = False  # an outage
    P[-1] = -np.eye(n)  # an indefinite prior: a positive S, an indefinite posterior
    S[-1] = np.eye(k) * 3.0
    with numpy_only():  # conditioning.condition itself takes the kernel where it applies
        reference = condition(m, P, v, S, P_xz, mask)
    (sa, ia), (sb, ib) = gaussian_kernels.condition(m, P, v, S, P_xz, mask), reference
    assert condition(m, P, v, S, P_xz, mask)[0].m.tobytes() == sa.m.tobytes()  # the wired path
    _assert_step_equal((sa, ia), (sb, ib))
    assert not ia.healthy[-1] or B == 1
    S_bad = S.copy()
    S_bad[-1] = -np.eye(k)
    assert gaussian_kernels.condition(m, P, v, S_bad, P_xz, np.ones((B, k), bool)) is None
    assert gaussian_kernels.condition(m.astype(np.float32), P.astype(np.float32), v, S, P_xz, mask) is None


def test_positive_definite_kernel_agrees_with_lapack():
    rng = np.random.default_rng(7)
    W = np.empty((9, 9))
    for _ in range(200):
        A = rng.standard_normal((9, 9))
        P = A @ A.T
        P -= rng.uniform(0.0, 2.0) * np.linalg.eigvalsh(P)[0] * np.eye(9)  # some indefinite
        ref = bool(is_positive_definite(P[None])[0])
        if abs(np.linalg.eigvalsh(P)[0]) > 1e-8 * np.abs(P).max():  # not borderline
            assert gaussian_kernels.positive_definite(P, W) == ref
    assert not gaussian_kernels.positive_definite(np.full((3, 3), np.nan), W)
