"""Adaptive fading (Benzerrouk 2014, eq. 63-70), strong tracking (Zhou & Frank 1996), Sage-Husa."""

from __future__ import annotations

import numpy as np
import pytest

from filters import adaptive, kalman, registry, sigma_point
from filters.core.models import LinearGaussianModel
from filters.core.quadrature import Cubature, GaussHermite, Unscented
from filters.core.types import GaussianState

# Tolerances (one place).
ALGEBRA_RTOL = 1e-10  # same algebra, different evaluation order
LINEAR_RTOL = 1e-9  # sigma-point moments vs Jacobians on a linear model


class RangeOnly2D:
    """2D constant-velocity target, ranges to three beacons."""

    def __init__(self, q: float = 0.01, sigma: float = 1.0):
        self.beacons = np.array([[0.0, 0.0], [400.0, 0.0], [200.0, 300.0]])
        F = np.eye(4)
        F[0, 2] = F[1, 3] = 1.0
        self.Fm = F
        G = np.array([[1 / 3, 1 / 2], [1 / 2, 1.0]])
        self.Q = np.zeros((4, 4))
        self.Q[np.ix_([0, 2], [0, 2])] = q * G
        self.Q[np.ix_([1, 3], [1, 3])] = q * G
        self.R = sigma**2 * np.eye(3)

    def f(self, x, u=None, dt=1.0):
        return x @ self.Fm.T

    def F(self, x, u=None, dt=1.0):
        return self.Fm

    def h(self, x):
        d = x[..., None, 0:2] - self.beacons
        return np.sqrt((d * d).sum(-1))

    def H(self, x):
        d = x[..., None, 0:2] - self.beacons
        r = np.sqrt((d * d).sum(-1, keepdims=True))
        J = np.zeros((*x.shape[:-1], 3, 4))
        J[..., 0:2] = d / r
        return J


def _cv_linear(q: float = 0.1, R=None) -> LinearGaussianModel:
    F = np.eye(4)
    F[0, 2] = F[1, 3] = 1.0
    G = np.array([[1 / 3, 1 / 2], [1 / 2, 1.0]])
    Q = np.zeros((4, 4))
    Q[np.ix_([0, 2], [0, 2])] = q * G
    Q[np.ix_([1, 3], [1, 3])] = q * G
    H = np.zeros((2, 4))
    H[0, 0] = H[1, 1] = 1.0
    return LinearGaussianModel(F, H, Q, np.eye(2) if R is None else R)


def _state(B: int, rng: np.random.Generator) -> GaussianState:
    m = np.column_stack(
        [
            rng.normal(100, 10, B),
            rng.normal(50, 10, B),
            rng.normal(1, 0.3, B),
            rng.normal(1, 0.3, B),
        ]
    )
    A = rng.standard_normal((B, 4, 4)) * 0.3
    return GaussianState(m, A @ np.swapaxes(A, -1, -2) + np.diag([20.0, 20.0, 0.5, 0.5]))


# ------------------------------------------------------------------------------------------
# Fading factor 1 is the plain filter, exactly
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(registry.FILTERS))
def test_unit_fading_equals_plain_filter_exactly(name):
    rng = np.random.default_rng(0)
    model = _cv_linear() if name == "kf" else RangeOnly2D()
    B = 6
    s = _state(B, rng)
    flt = registry.get(name)
    plain = flt.predict(s, model)
    for lam in (1.0, np.ones(B)):
        faded = flt.predict(s, model, fading=lam)
        np.testing.assert_array_equal(faded.m, plain.m)
        np.testing.assert_array_equal(faded.P, plain.P)
    z = model.h(plain.m) + rng.standard_normal((B, model.R.shape[0]))
    a, _ = flt.update(plain, z, model)
    b, _ = flt.update(flt.predict(s, model, fading=np.ones(B)), z, model)
    np.testing.assert_array_equal(a.m, b.m)
    np.testing.assert_array_equal(a.P, b.P)


@pytest.mark.parametrize("rule", [Cubature(), Unscented(), GaussHermite(3)])
def test_update_side_unit_fading_equals_sigma_point_update_exactly(rule):
    rng = np.random.default_rng(1)
    model = RangeOnly2D()
    B = 5
    s = _state(B, rng)
    z = model.h(s.m) + rng.standard_normal((B, 3))
    ref, ref_info = sigma_point.update(s, z, model, rule=rule)
    for lam in (None, 1.0, np.ones(B)):
        out, info = adaptive.fading_update(s, z, model, fading=lam, rule=rule)
        np.testing.assert_array_equal(out.m, ref.m)
        np.testing.assert_array_equal(out.P, ref.P)
        np.testing.assert_array_equal(info.log_likelihood, ref_info.log_likelihood)


def test_update_side_fading_is_the_kalman_update_of_the_inflated_prior_on_a_linear_model():
    """Our reading of eq. 62 with eq. 65-66: P+ = lambda P- - W S W^T (PSD for every lambda)."""
    rng = np.random.default_rng(2)
    model = _cv_linear()
    B = 5
    s = _state(B, rng)
    z = s.m @ model.observation_matrix.T + rng.standard_normal((B, 2))
    lam = np.array([1.0, 1.5, 3.0, 10.0, 100.0])
    out, _ = adaptive.fading_update(s, z, model, fading=lam)
    ref, _ = kalman.update(GaussianState(s.m, lam[:, None, None] * s.P), z, model)
    np.testing.assert_allclose(out.m, ref.m, rtol=LINEAR_RTOL)
    np.testing.assert_allclose(out.P, ref.P, rtol=LINEAR_RTOL, atol=1e-12)
    assert (np.linalg.eigvalsh(out.P) > 0).all()


# ------------------------------------------------------------------------------------------
# Formulas: known answers
# ------------------------------------------------------------------------------------------


def test_innovation_covariance_recursion_eq_70():
    rho = 0.6
    mem = adaptive.init_fading_memory(2, 2)
    v0 = np.array([[1.0, 2.0], [0.0, 1.0]])
    v1 = np.array([[3.0, -1.0], [2.0, 2.0]])
    mem = adaptive.innovation_covariance(mem, v0, rho)
    np.testing.assert_allclose(mem.V, np.einsum("bi,bj->bij", v0, v0))
    mem = adaptive.innovation_covariance(mem, v1, rho)
    ref = (rho * np.einsum("bi,bj->bij", v0, v0) + np.einsum("bi,bj->bij", v1, v1)) / (1 + rho)
    np.testing.assert_allclose(mem.V, ref)
    assert mem.k.tolist() == [2, 2]


def test_fading_terms_are_eq_69_on_a_linear_model_for_every_filter():
    """M = H F P F^T H^T and H Q H^T exactly for the EKF; the sigma-point/DD equivalents agree."""
    rng = np.random.default_rng(3)
    model = _cv_linear(q=0.3)
    B = 4
    s = _state(B, rng)
    z = rng.normal(0, 5, (B, 2)) + s.m[:, :2]
    H, F = model.observation_matrix, model.transition_matrix
    M_ref = H @ F @ s.P @ F.T @ H.T
    HQH_ref = np.broadcast_to(H @ model.Q @ H.T, (B, 2, 2))
    v_ref = z - s.m @ F.T @ H.T
    for name in ["ekf", "ukf", "ckf", "ghkf", "dd1", "dd2"]:
        t = adaptive.fading_terms(name, s, z, model, model)
        np.testing.assert_allclose(t.M, M_ref, rtol=LINEAR_RTOL, err_msg=name)
        np.testing.assert_allclose(t.HQH, HQH_ref, rtol=1e-7, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(t.v, v_ref, rtol=LINEAR_RTOL, err_msg=name)


def test_suboptimal_fading_factor_known_answer():
    """eq. 67-68 by hand at k = 0 (V = v v^T)."""
    v = np.array([[3.0, 4.0], [0.1, 0.1]])
    M = np.broadcast_to(np.diag([2.0, 3.0]), (2, 2, 2))
    HQH = np.broadcast_to(np.diag([0.5, 0.5]), (2, 2, 2))
    R = np.broadcast_to(np.eye(2), (2, 2, 2))
    terms = adaptive.FadingTerms(v, M, HQH, R, np.ones((2, 2), bool))
    lam, mem = adaptive.suboptimal_fading_factor(
        adaptive.init_fading_memory(2, 2), terms, beta=1.5, gamma=2.0
    )
    trN = 2.0 * 25.0 - 1.5 * 2.0 - 1.0
    assert lam[0] == pytest.approx(trN / 5.0)
    assert lam[1] == 1.0  # tr N < 0: no fading
    lam_stf, _ = adaptive.strong_tracking_factor(adaptive.init_fading_memory(2, 2), terms, beta=1.5)
    assert lam_stf[0] == pytest.approx((25.0 - 3.0 - 1.0) / 5.0)


def test_innovation_fading_factor_eq_63_known_answer():
    v = np.array([[3.0, 4.0]])
    P_yy = np.diag([1.0, 4.0])
    lam, _ = adaptive.innovation_fading_factor(
        adaptive.init_fading_memory(1, 2), v, P_yy, np.eye(2), eta=1.0, eps=2.0
    )
    assert lam[0] == pytest.approx((25.0 - 4.0) / 5.0)


def test_masked_row_is_ignored_by_the_formulas():
    rng = np.random.default_rng(4)
    model = RangeOnly2D()
    B = 3
    s = _state(B, rng)
    z = model.h(model.f(s.m)) + rng.normal(0, 5, (B, 3))
    mask = np.array([True, False, True])
    z_nan = z.copy()
    z_nan[:, 1] = np.nan
    t = adaptive.fading_terms("ckf", s, z_nan, model, model, mask=np.broadcast_to(mask, (B, 3)))
    assert (t.M[:, 1] == 0).all() and (t.HQH[:, :, 1] == 0).all() and (t.v[:, 1] == 0).all()
    lam, _ = adaptive.suboptimal_fading_factor(adaptive.init_fading_memory(B, 3), t)

    class Two(RangeOnly2D):
        def __init__(self):
            super().__init__()
            self.beacons = self.beacons[[0, 2]]
            self.R = np.eye(2)

    t2 = adaptive.fading_terms("ckf", s, z[:, [0, 2]], model, Two())
    lam2, _ = adaptive.suboptimal_fading_factor(adaptive.init_fading_memory(B, 2), t2)
    np.testing.assert_allclose(lam, lam2, rtol=ALGEBRA_RTOL)


# ------------------------------------------------------------------------------------------
# Formulas react to bias and manoeuvres
# ------------------------------------------------------------------------------------------


def _manoeuvre(names, B=100, T=70, t_man=30, bias_window=None, seed=0):
    model = RangeOnly2D(q=0.01)
    rng = np.random.default_rng(seed)
    x = np.column_stack([np.full(B, 100.0), np.full(B, 50.0), np.full(B, 2.0), np.ones(B)])
    x = x + rng.normal(0, 1, (B, 4)) * [5, 5, 0.2, 0.2]
    P0 = np.diag([25.0, 25.0, 0.04, 0.04])
    m0 = x + rng.standard_normal((B, 4)) @ np.linalg.cholesky(P0).T
    states = {k: GaussianState(m0.copy(), np.broadcast_to(P0, (B, 4, 4)).copy()) for k in names}
    memory = {k: adaptive.init_fading_memory(B, 3) for k in names}
    err = {k: [] for k in names}
    lams = {k: [] for k in names}
    for t in range(T):
        x = model.f(x)
        if bias_window is None and t == t_man:
            x[:, 2] -= 3.0
            x[:, 3] += 2.0
        z = model.h(x) + rng.standard_normal((B, 3))
        if bias_window is not None and bias_window[0] <= t < bias_window[1]:
            z[:, 0] += 8.0
        for k in names:
            base = "ekf" if "ekf" in k else "ckf"
            flt = registry.get(base)
            lam = np.ones(B)
            if k in ("ekf", "ckf"):
                s, _ = flt.update(flt.predict(states[k], model), z, model)
            elif k == "af_ckf_update_side":
                s, _, memory[k], lam = adaptive.adaptive_fading_update(
                    flt.predict(states[k], model), memory[k], z, model
                )
            else:
                terms = adaptive.fading_terms(flt, states[k], z, model, model)
                formula = (
                    adaptive.strong_tracking_factor
                    if k.startswith("stf")
                    else adaptive.suboptimal_fading_factor
                )
                lam, memory[k] = formula(memory[k], terms, rho=0.95, beta=1.0)
                s, _ = flt.update(flt.predict(states[k], model, fading=lam), z, model)
            states[k] = s
            lams[k].append(lam)
            err[k].append(((s.m[:, :2] - x[:, :2]) ** 2).sum(1))
    return {k: np.array(v) for k, v in err.items()}, {k: np.array(v) for k, v in lams.items()}


def test_fading_filters_track_a_manoeuvre_better_than_plain(capsys):
    """Velocity jump of 3.6 m/s at t = 30 (B = 100). Recorded RMSE [m] before/after:
    EKF 0.68/2.11, AF-EKF (eq. 67-70) 0.85/0.94, STF-EKF 0.85/0.94, AF-CKF (sigma-point
    eq. 67-70) 0.85/0.94, AF-CKF update side (eq. 63 + 65-66) 0.85/0.94."""
    names = ["ekf", "af_ekf", "stf_ekf", "ckf", "af_ckf", "af_ckf_update_side"]
    err, lams = _manoeuvre(names)
    t_man = 30
    table = {
        k: (
            round(float(np.sqrt(e[10:t_man].mean())), 3),
            round(float(np.sqrt(e[t_man : t_man + 20].mean())), 3),
            round(float(lams[k][t_man : t_man + 5].mean()), 2),
        )
        for k, e in err.items()
    }
    with capsys.disabled():
        print("\nmanoeuvre: RMSE before, RMSE after [m], mean lambda after:", table)
    for k in names:
        assert (lams[k] >= 1.0).all()
    for k in ["af_ekf", "stf_ekf", "af_ckf", "af_ckf_update_side"]:
        plain = "ekf" if "ekf" in k else "ckf"
        assert table[k][1] < 0.6 * table[plain][1], k
        assert table[k][2] > 2.0


def test_fading_factor_reacts_to_an_injected_bias():
    err, lams = _manoeuvre(["af_ekf", "af_ckf_update_side"], T=60, bias_window=(30, 40))
    for k, lam in lams.items():
        assert (lam >= 1.0).all()
        nominal = lam[15:30].mean()
        biased = lam[30:33].mean()
        assert biased > 3.0 * nominal, (k, nominal, biased)


# ------------------------------------------------------------------------------------------
# Sage-Husa
# ------------------------------------------------------------------------------------------


def _sage_husa_run(R_true, R0, B=50, T=1500, b=0.99, seed=1):
    rng = np.random.default_rng(seed)
    model = _cv_linear(q=0.1, R=R0)
    chol_Q, chol_R = np.linalg.cholesky(model.Q), np.linalg.cholesky(R_true)
    H, F = model.observation_matrix, model.transition_matrix
    x = np.zeros((B, 4))
    s = GaussianState(rng.normal(0, 1, (B, 4)), np.broadcast_to(np.eye(4), (B, 4, 4)).copy())
    est = adaptive.sage_husa_init(R0, B)
    for _ in range(T):
        x = x @ F.T + rng.standard_normal((B, 4)) @ chol_Q.T
        z = x @ H.T + rng.standard_normal((B, 2)) @ chol_R.T
        pred = kalman.predict(s, model)
        s, info = kalman.update(pred, z, model, R=est.R)
        est = adaptive.sage_husa_update(est, pred, s, info, b=b)
        assert (np.linalg.eigvalsh(est.R) > 0).all()
    return est


@pytest.mark.parametrize("scale", [25.0, 0.1])
def test_sage_husa_recovers_a_wrong_R(scale):
    R_true = np.array([[4.0, 1.0], [1.0, 1.0]])
    est = _sage_husa_run(R_true, scale * np.eye(2))
    np.testing.assert_allclose(est.R.mean(0), R_true, rtol=0.1, atol=0.1)
    assert np.median(np.abs(est.R - R_true).max(axis=(1, 2))) < 0.8


def test_sage_husa_recovers_a_scalar_Q():
    rng = np.random.default_rng(2)
    B, q, r = 50, 0.5, 1.0
    model = LinearGaussianModel(np.eye(1), np.eye(1), q * np.eye(1), r * np.eye(1))
    x = np.zeros((B, 1))
    s = GaussianState(x.copy(), np.ones((B, 1, 1)))
    est = adaptive.sage_husa_init(r * np.eye(1), B, Q0=5.0 * np.eye(1))
    for _ in range(3000):
        x = x + np.sqrt(q) * rng.standard_normal((B, 1))
        z = x + np.sqrt(r) * rng.standard_normal((B, 1))
        pred = kalman.predict(s, model, Q=est.Q)
        s, info = kalman.update(pred, z, model, R=est.R)
        est = adaptive.sage_husa_update(est, pred, s, info, b=0.995, estimate_R=False)
    assert est.Q.mean() == pytest.approx(q, rel=0.1)
    np.testing.assert_array_equal(est.R, r)


def test_sage_husa_first_step_is_guarded_positive_definite():
    """d_0 = 1: the first estimate is v v^T - H P H^T, indefinite in general; it is floored."""
    est = adaptive.sage_husa_init(np.eye(2), 1, floor=1e-3)
    info_S = np.array([[[10.0, 0.0], [0.0, 10.0]]])
    v = np.array([[0.1, 0.0]])

    class Info:
        innovation = v
        S = info_S

    s = GaussianState(np.zeros((1, 4)), np.eye(4)[None])
    new = adaptive.sage_husa_update(est, s, s, Info(), b=0.9)
    assert np.linalg.eigvalsh(new.R).min() >= 1e-3 - 1e-15


# ------------------------------------------------------------------------------------------
# Bad input
# ------------------------------------------------------------------------------------------


def test_bad_parameters_raise():
    rng = np.random.default_rng(5)
    model = RangeOnly2D()
    s = _state(2, rng)
    z = model.h(s.m)
    terms = adaptive.fading_terms("ekf", s, z, model, model)
    mem = adaptive.init_fading_memory(2, 3)
    with pytest.raises(ValueError, match="rho"):
        adaptive.suboptimal_fading_factor(mem, terms, rho=1.0)
    with pytest.raises(ValueError, match="rho"):
        adaptive.suboptimal_fading_factor(mem, terms, rho=np.array([0.5, np.nan]))
    with pytest.raises(ValueError, match="beta"):
        adaptive.suboptimal_fading_factor(mem, terms, beta=-1.0)
    with pytest.raises(ValueError, match="beta"):
        adaptive.strong_tracking_factor(mem, terms, beta=0.5)
    with pytest.raises(ValueError, match="gamma"):
        adaptive.suboptimal_fading_factor(mem, terms, gamma=np.zeros(2))
    with pytest.raises(ValueError, match="rho must be a scalar or have shape"):
        adaptive.suboptimal_fading_factor(mem, terms, rho=np.full(3, 0.5))
    with pytest.raises(ValueError, match="memory.V"):
        adaptive.suboptimal_fading_factor(adaptive.FadingMemory(np.zeros((2, 3)), np.zeros(2)), terms)
    with pytest.raises(ValueError, match="z must have shape"):
        adaptive.suboptimal_fading_factor(adaptive.init_fading_memory(2, 2), terms)
    with pytest.raises(ValueError, match="fading"):
        adaptive.fading_update(s, z, model, fading=np.array([1.0, 0.0]))
    with pytest.raises(ValueError, match="fading"):
        adaptive.fading_update(s, z, model, fading=np.ones(3))
    with pytest.raises(ValueError, match="eta"):
        adaptive.adaptive_fading_update(s, mem, z, model, eta=0.0)


def test_bad_sage_husa_input_raises():
    with pytest.raises(ValueError, match="R0"):
        adaptive.sage_husa_init(np.ones((2, 3)), 4)
    with pytest.raises(ValueError, match="R0"):
        adaptive.sage_husa_init(np.full((2, 2), np.nan), 4)
    with pytest.raises(ValueError, match="floor"):
        adaptive.sage_husa_init(np.eye(2), 4, floor=-1.0)
    est = adaptive.sage_husa_init(np.eye(2), 1)
    s = GaussianState(np.zeros((1, 4)), np.eye(4)[None])

    class Info:
        innovation = np.zeros((1, 2))
        S = np.eye(2)[None]

    with pytest.raises(ValueError, match="b must lie"):
        adaptive.sage_husa_update(est, s, s, Info(), b=1.0)


def test_sage_husa_q_estimate_is_kept_psd_not_floored_at_rs_scale():
    """R = 25 m^2 against Q = 1e-8: a floor sized from R (2.5e-5) must not be imposed on Q."""
    from filters import registry
    from filters.core.models import LinearGaussianModel
    from filters.core.types import GaussianState

    F, H = np.array([[1.0, 1.0], [0.0, 1.0]]), np.array([[1.0, 0.0]])
    Q, R = np.diag([1e-8, 1e-8]), np.array([[25.0]])
    model, kf = LinearGaussianModel(F, H, Q, R), registry.get("kf")
    est = adaptive.sage_husa_init(R, 1, Q0=Q, k0=10_000)
    state = GaussianState(np.zeros((1, 2)), 1e-2 * np.eye(2)[None])
    rng = np.random.default_rng(0)
    for _ in range(5):
        pred = kf.predict(state, model, Q=est.Q)
        state, info = kf.update(pred, pred.m @ H.T + 5.0 * rng.normal(size=(1, 1)), model, R=est.R)
        est = adaptive.sage_husa_update(est, pred, state, info, b=0.98)
        lam = np.linalg.eigvalsh(est.Q[0])
        assert lam.min() >= -1e-20 and lam.max() < 1e-6  # PSD, and of Q's own scale
