"""Rao-Blackwellized PF: exact KF equivalence when the sampled part is known, convergence to the
KF when it is not, masking, batching, resampling."""

import numpy as np
import pytest

from filters import GaussianState, LinearGaussianModel, kalman
from filters.particle import rao_blackwell as rb

from .problems import simulate_linear
from .tolerances import EXACT_ATOL, EXACT_RTOL, MASK_ATOL, SLOPE_TOL


class KnownParameterModel:
    """x^n = theta (constant, known exactly), x^l = [p, v] linear given theta.

    ``A_l(theta)``, ``f_l(theta)`` and ``C(theta)`` are nonlinear functions of theta, one per
    filter: a meaningful conditionally linear model whose RBPF must equal the KF on the linear
    model evaluated at the true theta.
    """

    def __init__(self, B):
        self.Q_n = np.zeros((1, 1))
        self.Q_l = np.array([[0.05, 0.01], [0.01, 0.2]])
        self.R = np.array([[0.4, 0.1], [0.1, 0.9]])
        self.B = B

    def f_n(self, xn, u, dt):
        return xn.copy()

    def A_n(self, xn, u, dt):
        return np.zeros((1, 2))

    def A_l(self, xn, u, dt):
        th = xn[..., 0]
        A = np.zeros((*xn.shape[:-1], 2, 2))
        A[..., 0, 0] = 1.0
        A[..., 0, 1] = dt * np.cos(th)
        A[..., 1, 1] = 0.9 + 0.05 * np.sin(th)
        return A

    def f_l(self, xn, u, dt):
        th = xn[..., 0]
        return np.stack([0.1 * th**2, np.tanh(th)], axis=-1)

    def h(self, xn):
        return np.stack([np.sin(xn[..., 0]), np.zeros(xn.shape[:-1])], axis=-1)

    def C(self, xn):
        th = xn[..., 0]
        C = np.zeros((*xn.shape[:-1], 2, 2))
        C[..., 0, 0] = 1.0
        C[..., 1, 0] = np.exp(-th)
        C[..., 1, 1] = 1.0 + th**2
        return C

    def linear_at(self, theta, dt):
        """The LinearGaussianModel on [p, v] for per-filter theta (B,), control u = f_l(theta)."""
        xn = theta[:, None]
        return (
            LinearGaussianModel(self.A_l(xn, None, dt), self.C(xn), self.Q_l, self.R, np.eye(2)),
            self.f_l(xn, None, dt),
            self.h(xn),
        )


def test_rbpf_equals_kf_when_the_nonlinear_part_is_known():
    B, N, T, dt = 5, 7, 15, 0.5
    rng = np.random.default_rng(0)
    theta = rng.uniform(-1.0, 1.0, B)
    model = KnownParameterModel(B)
    lin, ctrl, hoff = model.linear_at(theta, dt)
    m0 = np.concatenate([theta[:, None], rng.standard_normal((B, 2))], axis=1)
    P0 = np.zeros((B, 3, 3))
    P0[:, 1:, 1:] = np.array([[2.0, 0.3], [0.3, 1.0]])
    st = rb.from_gaussian(m0, P0, 1, N, rng)
    kf = GaussianState(m0[:, 1:], P0[:, 1:, 1:])
    masks = rng.random((T, B, 2)) < 0.7
    for k in range(T):
        z = rng.standard_normal((B, 2)) * 3
        z[~masks[k]] = np.nan
        st = rb.predict(st, model, None, dt, rng)
        kf = kalman.predict(kf, lin, u=ctrl, dt=dt)
        st, info = rb.update(st, z, model, masks[k], decision=rng.random(B) < 0.5, rng=rng)
        kf, kinfo = kalman.update(kf, np.where(masks[k], z - hoff, np.nan), lin, masks[k])
        np.testing.assert_allclose(st.xn[..., 0], np.broadcast_to(theta[:, None], (B, N)), rtol=0, atol=0)
        for i in range(N):
            np.testing.assert_allclose(st.m[:, i], kf.m, rtol=EXACT_RTOL, atol=EXACT_ATOL)
            np.testing.assert_allclose(st.P[:, i], kf.P, rtol=EXACT_RTOL, atol=EXACT_ATOL)
        np.testing.assert_allclose(
            info.log_likelihood, kinfo.log_likelihood, rtol=EXACT_RTOL, atol=EXACT_ATOL
        )
        np.testing.assert_allclose(info.nis, kinfo.nis, rtol=EXACT_RTOL, atol=EXACT_ATOL)
        np.testing.assert_allclose(st.log_w, -np.log(N), atol=EXACT_ATOL)
        g = rb.mean_and_covariance(st)
        np.testing.assert_allclose(g.m[:, 1:], kf.m, rtol=EXACT_RTOL, atol=EXACT_ATOL)
        np.testing.assert_allclose(g.P[:, 1:, 1:], kf.P, rtol=EXACT_RTOL, atol=EXACT_ATOL)
        assert info.healthy.all()


def test_rbpf_with_everything_linear_equals_kf():
    """n_n = 0: the whole state is in the Kalman part; every particle is the KF."""
    F = np.array([[1.0, 0.3], [0.0, 0.95]])
    model = LinearGaussianModel(F, np.array([[1.0, 0.5]]), np.diag([0.1, 0.2]), np.array([[0.3]]))
    split = rb.split_linear_model(model, 0)
    B, N, T = 3, 4, 10
    rng = np.random.default_rng(1)
    _, zs = simulate_linear(model, B, T, rng)
    m0, P0 = rng.standard_normal((B, 2)), np.broadcast_to(np.eye(2), (B, 2, 2))
    st = rb.from_gaussian(m0, P0, 0, N, rng)
    kf = GaussianState(m0, P0)
    for k in range(T):
        st = rb.predict(st, split, None, 1.0, rng)
        st, info = rb.update(st, zs[k], split)
        kf = kalman.predict(kf, model)
        kf, kinfo = kalman.update(kf, zs[k], model)
        g = rb.mean_and_covariance(st)
        np.testing.assert_allclose(g.m, kf.m, rtol=EXACT_RTOL, atol=EXACT_ATOL)
        np.testing.assert_allclose(g.P, kf.P, rtol=EXACT_RTOL, atol=EXACT_ATOL)
        np.testing.assert_allclose(info.log_likelihood, kinfo.log_likelihood, rtol=EXACT_RTOL)


def test_rbpf_converges_to_kf_with_a_random_nonlinear_part():
    """x = [p, v, a]: p sampled (its transition depends on v, which it therefore informs through
    the pseudo-measurement of eq. 23), [v, a] in the Kalman part. Error ~ 1/sqrt(N)."""
    dt = 1.0
    F = np.array([[1.0, dt, 0.5 * dt**2], [0.0, 1.0, dt], [0.0, 0.0, 0.9]])
    model = LinearGaussianModel(F, np.array([[1.0, 0.0, 0.0]]), np.diag([0.1, 0.05, 0.2]), np.array([[0.5]]))
    split = rb.split_linear_model(model, 1)
    B, T = 32, 10
    _, zs = simulate_linear(model, B, T, np.random.default_rng(2))
    m0, P0 = np.zeros((B, 3)), np.broadcast_to(np.eye(3), (B, 3, 3))
    errs = []
    Ns = (100, 400, 1600, 6400)
    for N in Ns:
        rng = np.random.default_rng(3)
        st = rb.from_gaussian(m0, P0, 1, N, rng)
        kf = GaussianState(m0, P0)
        e = []
        for k in range(T):
            st = rb.predict(st, split, None, dt, rng)
            st, _ = rb.update(st, zs[k], split, decision=True, rng=rng)
            kf = kalman.predict(kf, model)
            kf, _ = kalman.update(kf, zs[k], model)
            g = rb.mean_and_covariance(st)
            e.append((g.m - kf.m) / np.sqrt(np.diagonal(kf.P, axis1=1, axis2=2)))
        errs.append(np.sqrt(np.mean(np.square(e))))
    slope, _ = np.polyfit(np.log(Ns), np.log(errs), 1)
    print(f"\nRBPF vs KF: N={Ns} errors {np.round(errs, 4)} slope {slope:.3f}")
    assert abs(slope + 0.5) < SLOPE_TOL
    assert errs[-1] < 0.05


def test_rbpf_masked_row_equals_deleted_row():
    model = KnownParameterModel(4)
    rng = np.random.default_rng(4)
    B, N = 4, 6
    m0 = np.concatenate([rng.standard_normal((B, 1)), rng.standard_normal((B, 2))], axis=1)
    P0 = np.broadcast_to(np.eye(3), (B, 3, 3)).copy()
    st = rb.from_gaussian(m0, P0, 1, N, rng)
    z = rng.standard_normal((B, 2))
    mask = np.array([[True, False]] * B)
    a, ia = rb.update(st, np.where(mask, z, np.nan), model, mask)

    class FirstRowOnly(KnownParameterModel):
        def h(self, xn):
            return super().h(xn)[..., :1]

        def C(self, xn):
            return super().C(xn)[..., :1, :]

    sub = FirstRowOnly(B)
    sub.R = model.R[:1, :1]
    b, ib = rb.update(st, z[:, :1], sub)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_allclose(x, y, atol=MASK_ATOL, rtol=1e-12)
    np.testing.assert_allclose(ia.log_likelihood, ib.log_likelihood, atol=MASK_ATOL)
    np.testing.assert_allclose(ia.nis, ib.nis, atol=MASK_ATOL)


def test_rbpf_batch_equals_separate_runs_and_resampling_moves_kalman_moments():
    F = np.array([[1.0, 1.0, 0.0], [0.0, 1.0, 1.0], [0.0, 0.0, 0.8]])
    model = LinearGaussianModel(F, np.array([[1.0, 0.0, 0.0]]), np.diag([0.1, 0.05, 0.2]), np.array([[0.5]]))
    split = rb.split_linear_model(model, 1)
    B, N, T = 3, 30, 5
    _, zs = simulate_linear(model, B, T, np.random.default_rng(5))
    m0, P0 = np.zeros((B, 3)), np.broadcast_to(np.eye(3), (B, 3, 3))
    dec = np.random.default_rng(6).random((T, B)) < 0.6

    def run(idx, gens):
        st = rb.from_gaussian(m0[idx], P0[idx], 1, N, gens)
        for k in range(T):
            st = rb.predict(st, split, None, 1.0, gens)
            st, _ = rb.update(st, zs[k][idx], split, decision=dec[k][idx], rng=gens, method="stratified")
        return st

    together = run(np.arange(B), [np.random.default_rng(70 + b) for b in range(B)])
    for b in range(B):
        alone = run(np.array([b]), np.random.default_rng(70 + b))
        for x, y in zip(together, alone, strict=True):
            np.testing.assert_allclose(x[b], y[0], rtol=1e-12, atol=1e-12)
    # resampling copies (x^n, m, P) together
    st = together._replace(log_w=np.log(np.random.default_rng(0).dirichlet(np.ones(N), B)))
    new = rb.resample(st, True, np.random.default_rng(1))
    for b in range(B):
        for j in range(N):
            i = np.flatnonzero(st.xn[b, :, 0] == new.xn[b, j, 0])[0]
            np.testing.assert_array_equal(new.m[b, j], st.m[b, i])
            np.testing.assert_array_equal(new.P[b, j], st.P[b, i])


def test_split_linear_model_checks():
    model = LinearGaussianModel(np.eye(3), np.eye(3)[:1], np.ones((3, 3)) + np.eye(3), np.eye(1))
    with pytest.raises(ValueError, match="Q"):
        rb.split_linear_model(model, 1)
    with pytest.raises(ValueError, match="n_nonlinear"):
        rb.split_linear_model(model._replace(Q=np.eye(3)), 4)
    with pytest.raises(ValueError, match="N"):
        rb.from_gaussian(np.zeros((1, 3)), np.eye(3)[None], 1, 0, np.random.default_rng(0))
    st = rb.from_gaussian(
        np.zeros((2, 3)), np.broadcast_to(np.eye(3), (2, 3, 3)), 1, 4, np.random.default_rng(0)
    )
    with pytest.raises(ValueError, match="state.P"):
        rb.update(
            st._replace(P=st.P[..., :1, :1]),
            np.zeros((2, 1)),
            rb.split_linear_model(model._replace(Q=np.eye(3)), 1),
        )
    with pytest.raises(ValueError, match="rng"):
        rb.predict(st, rb.split_linear_model(model._replace(Q=np.eye(3)), 1))
