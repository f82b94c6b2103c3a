import numpy as np
import pytest

from filters.core.conditioning import mask_moments, masked_covariance


@pytest.mark.parametrize(
    ("c_shape", "w_shape"),
    [((5, 5), (7, 5)), ((7, 5, 5), (7, 5)), ((7, 3, 5, 5), (7, 1, 5))],
    ids=["shared", "batched", "per-particle"],
)
def test_masked_covariance_keeps_the_used_block_and_isolates_masked_rows(c_shape, w_shape):
    rng = np.random.default_rng(0)
    C = rng.standard_normal(c_shape)
    C_before = C.copy()
    w = (rng.random(w_shape) < 0.6).astype(np.float64)
    got = masked_covariance(C, w)
    m = c_shape[-1]
    ref = C * (w[..., :, None] * w[..., None, :]) + np.eye(m) * (1.0 - w)[..., None, :]
    np.testing.assert_array_equal(got, ref)
    np.testing.assert_array_equal(C, C_before)  # a new array: the input is untouched
    used = w[..., :, None] * w[..., None, :] > 0
    np.testing.assert_array_equal(
        np.where(used, got, 0.0), np.where(used, np.broadcast_to(C, got.shape), 0.0)
    )


def test_mask_moments_zeroes_masked_rows_and_gives_them_unit_variance():
    rng = np.random.default_rng(1)
    B, m, n = 4, 3, 2
    v, S, P_xz = rng.standard_normal((B, m)), rng.standard_normal((B, m, m)), rng.standard_normal((B, n, m))
    mask = np.array([[True, False, True]] * B)
    v2, S2, P2 = mask_moments(v, S, P_xz, mask)
    assert (v2[:, 1] == 0).all() and (P2[:, :, 1] == 0).all()
    np.testing.assert_array_equal(S2[:, 1], np.broadcast_to([0.0, 1.0, 0.0], (B, 3)))
    np.testing.assert_array_equal(S2[:, [0, 2]][:, :, [0, 2]], S[:, [0, 2]][:, :, [0, 2]])
    assert mask_moments(v, S, P_xz, np.ones((B, m), bool))[1] is S  # nothing masked: no copy


def _observed_problem(seed, B=64, n=8, m=12, observed=(0, 1, 6), scale_clock=1.0):
    """Random prior, H zero outside ``observed``, diagonal R, random masks (some all masked)."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((B, n, n))
    # standard deviations of an INS/GNSS error state (m, m/s, m/s^2, m, m/s), the clock bias
    # scaled up to a cold-start prior (3e5 m)
    D = np.diag([10.0, 10.0, 0.1, 0.1, 1e-3, 1e-3, 1.0, 0.1][:n])
    D[observed[-1], observed[-1]] *= scale_clock
    P = D @ (A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(n)) @ D
    mean = rng.standard_normal((B, n))
    H = np.zeros((B, m, n))
    H[:, :, list(observed)] = rng.standard_normal((B, m, len(observed)))
    r = rng.uniform(1.0, 30.0, (B, m))
    v = rng.standard_normal((B, m)) * np.sqrt(r) * 3
    mask = rng.random((B, m)) < 0.7
    mask[0] = False  # an outage
    mask[1, 1:] = False  # one satellite
    mask[2] = True
    return mean, P, v, H, r, mask


def _exact_posterior(m, P, v, H, r):
    """The Kalman posterior in exact rational arithmetic (one filter, used rows only)."""
    from fractions import Fraction as Fr

    def mat(a):
        return [[Fr(float(x)) for x in row] for row in np.atleast_2d(a)]

    def mul(A, B):
        cols = list(zip(*B, strict=True))
        return [[sum(a * b for a, b in zip(row, col, strict=True)) for col in cols] for row in A]

    def inv(A):
        k = len(A)
        M = [row[:] + [Fr(int(i == j)) for j in range(k)] for i, row in enumerate(A)]
        for c in range(k):
            p = next(i for i in range(c, k) if M[i][c] != 0)
            M[c], M[p] = M[p], M[c]
            M[c] = [x / M[c][c] for x in M[c]]
            for i in range(k):
                if i != c and M[i][c] != 0:
                    M[i] = [a - M[i][c] * b for a, b in zip(M[i], M[c], strict=True)]
        return [row[k:] for row in M]

    Pm, Hm, vm = mat(P), mat(H), mat(v[:, None])
    Ht = [list(col) for col in zip(*Hm, strict=True)]
    PHt = mul(Pm, Ht)
    S = mul(Hm, PHt)
    for i, ri in enumerate(r):
        S[i][i] += Fr(float(ri))
    K = mul(PHt, inv(S))
    mean = [float(Fr(float(a)) + b[0]) for a, b in zip(m, mul(K, vm), strict=True)]
    KHP = mul(K, mul(Hm, Pm))
    cov = [[float(Pm[i][j] - KHP[i][j]) for j in range(len(Pm))] for i in range(len(Pm))]
    return np.array(mean), np.array(cov)


@pytest.mark.parametrize("observed", [(3,), (0, 5), (0, 1, 6)])
def test_the_observed_subspace_update_is_accurate_from_a_cold_start(observed):
    """A 3e5 m clock prior: both forms lose digits of P (conditioning), this one no more."""
    from filters.core.conditioning import condition, condition_observed, observed_states

    m, P, v, H, r, mask = _observed_problem(len(observed), B=8, observed=observed, scale_clock=3e5)
    R = r[:, :, None] * np.eye(r.shape[1])
    ref, _ = condition(m, P, v, H @ P @ np.swapaxes(H, 1, 2) + R, P @ np.swapaxes(H, 1, 2), mask)
    got, _ = condition_observed(m, P, v, H, r, mask, observed_states(H))
    err = {"whitened": [0.0, 0.0], "subspace": [0.0, 0.0]}
    for b in range(3, 8):
        u = np.flatnonzero(mask[b])
        em, eP = _exact_posterior(m[b], P[b], v[b, u], H[b, u], r[b, u])
        sd = np.sqrt(np.diag(eP))
        for name, post in (("whitened", ref), ("subspace", got)):
            err[name][0] = max(err[name][0], np.abs((post.m[b] - em) / sd).max())
            err[name][1] = max(err[name][1], np.abs((post.P[b] - eP) / np.outer(sd, sd)).max())
    for i in range(2):  # mean, covariance (in standard deviations / correlations)
        assert err["subspace"][i] < 1e-3, err
        assert err["subspace"][i] <= 10 * err["whitened"][i] + 1e-12, err


@pytest.mark.parametrize("observed", [(3,), (0, 5), (0, 1, 6)])
def test_the_observed_subspace_update_equals_the_whitened_form(observed):
    from filters.core.conditioning import condition, condition_observed, observed_states

    from ..tolerances import ATOL, RTOL

    m, P, v, H, r, mask = _observed_problem(len(observed), observed=observed)
    o = observed_states(H)
    np.testing.assert_array_equal(o, observed)
    R = r[:, :, None] * np.eye(r.shape[1])
    ref, ref_info = condition(m, P, v, H @ P @ np.swapaxes(H, 1, 2) + R, P @ np.swapaxes(H, 1, 2), mask)
    got, info = condition_observed(m, P, v, H, r, mask, o)
    sd = np.sqrt(np.diagonal(ref.P, axis1=1, axis2=2))
    np.testing.assert_allclose(got.m / sd, ref.m / sd, rtol=RTOL, atol=ATOL)
    corr = sd[:, :, None] * sd[:, None, :]
    np.testing.assert_allclose(got.P / corr, ref.P / corr, rtol=RTOL, atol=ATOL)
    np.testing.assert_array_equal(got.P, np.swapaxes(got.P, 1, 2))
    for name in ("innovation", "S", "nis", "log_likelihood"):
        got_v, ref_v = getattr(info, name), getattr(ref_info, name)
        np.testing.assert_allclose(got_v, ref_v, rtol=RTOL, atol=ATOL, err_msg=name)
    np.testing.assert_array_equal(info.n_meas, ref_info.n_meas)
    assert info.healthy.all() and ref_info.healthy.all()
    # the outage changes nothing
    np.testing.assert_array_equal(got.m[0], m[0])
    np.testing.assert_allclose(got.P[0], P[0], rtol=1e-15, atol=0)


def test_kalman_update_takes_the_subspace_form_only_where_it_applies(monkeypatch):
    from filters import kalman
    from filters.core import conditioning
    from filters.core.models import LinearGaussianModel
    from filters.core.types import GaussianState

    m, P, v, H, r, mask = _observed_problem(7)
    z = v  # a linear model with h(x) = H x at x = 0: innovations z - H 0
    calls = []
    real = conditioning.condition_observed

    def spy(*a):
        calls.append(1)
        return real(*a)

    monkeypatch.setattr(kalman, "condition_observed", spy)
    monkeypatch.setattr(kalman, "compiled_enabled", lambda: False)  # the NumPy path's own choice
    state = GaussianState(np.zeros_like(m), P)
    for Hm, R, expect in (
        (H[0], np.diag(r[0]), 1),  # shared H and R, diagonal: subspace form
        (H, r[:, :, None] * np.eye(12), 1),  # batched
        (H[0], np.diag(r[0]) + 0.1 * (np.eye(12, k=1) + np.eye(12, k=-1)), 0),  # correlated noise
        (np.ones((12, 8)), np.diag(r[0]), 0),  # every state observed
    ):
        calls.clear()
        model = LinearGaussianModel(np.eye(8), Hm, np.eye(8), R)
        post, info = kalman.update(state, z, model, mask=mask)
        assert len(calls) == expect
        Hb = np.broadcast_to(Hm, (m.shape[0], 12, 8))
        Rb = np.broadcast_to(R, (m.shape[0], 12, 12))
        ref, _ = conditioning.condition(
            np.zeros_like(m), P, z, Hb @ P @ np.swapaxes(Hb, 1, 2) + Rb, P @ np.swapaxes(Hb, 1, 2), mask
        )
        sd = np.sqrt(np.diagonal(ref.P, axis1=1, axis2=2))
        np.testing.assert_allclose(post.m / sd, ref.m / sd, rtol=1e-9, atol=1e-9)


def test_a_prior_block_that_is_not_positive_definite_falls_back():
    from filters.core.conditioning import condition_observed

    m, P, v, H, r, mask = _observed_problem(8)
    P = P.copy()
    P[3][:, [0, 1, 6]] = 0.0
    P[3][[0, 1, 6], :] = 0.0  # P_oo = 0 for one filter
    assert condition_observed(m, P, v, H, r, mask, np.array([0, 1, 6])) is None


def test_a_used_row_of_zero_noise_variance_falls_back_to_the_general_update():
    """R_ii = 0 with S positive definite is a valid (noise-free) measurement: no 1/r division."""
    from filters import kalman
    from filters.core.conditioning import condition, condition_observed
    from filters.core.models import LinearGaussianModel
    from filters.core.types import GaussianState

    m, P, v, H, r, mask = _observed_problem(11, B=8)
    r = r.copy()
    r[:, 4] = 0.0
    mask[:, 4] = True
    assert condition_observed(m, P, v, H, r, mask, np.array([0, 1, 6])) is None
    R = r[0, :, None] * np.eye(12)
    post, info = kalman.update(
        GaussianState(m, P), v, LinearGaussianModel(np.eye(8), H[0], np.eye(8), R), mask=mask
    )
    Hb = np.broadcast_to(H[0], (8, 12, 8))
    ref, _ = condition(
        np.zeros_like(m) + m,
        P,
        v - m @ H[0].T,
        Hb @ P @ np.swapaxes(Hb, 1, 2) + R,
        P @ np.swapaxes(Hb, 1, 2),
        mask,
    )
    assert np.isfinite(post.m).all() and np.isfinite(post.P).all()  # (P+ is singular: R_ii = 0)
    np.testing.assert_allclose(post.m, ref.m, rtol=1e-9, atol=1e-9)


def test_unrolled_cholesky_and_row_solve_match_lapack():
    from filters.core.linalg import cholesky_unrolled, solve_lower_rows

    rng = np.random.default_rng(9)
    for k in (1, 2, 3, 4):
        A = rng.standard_normal((50, k, k))
        S = A @ np.swapaxes(A, 1, 2) + 0.5 * np.eye(k)
        L, ok = cholesky_unrolled(S)
        assert ok.all()
        np.testing.assert_allclose(L, np.linalg.cholesky(S), rtol=1e-12, atol=1e-12)
        X = rng.standard_normal((50, 6, k))
        Y = solve_lower_rows(L, X)
        np.testing.assert_allclose(Y @ np.swapaxes(L, 1, 2), X, rtol=1e-12, atol=1e-12)
    bad = np.array([[[1.0, 2.0], [2.0, 1.0]], [[np.nan, 0.0], [0.0, 1.0]], [[2.0, 0.0], [0.0, 3.0]]])
    _, ok = cholesky_unrolled(bad)
    np.testing.assert_array_equal(ok, [False, False, True])


def test_health_flags_a_covariance_that_is_not_positive_definite():
    """The health flag is "finite and positive definite"; a positive diagonal is not enough."""
    from filters import kalman
    from filters.core.conditioning import health
    from filters.core.models import LinearGaussianModel
    from filters.core.types import GaussianState

    indefinite = np.array([[1.0, 2.0], [2.0, 1.0]])  # eigenvalues 3 and -1, positive diagonal
    P = np.stack([np.eye(2), indefinite, np.full((2, 2), np.nan)])
    assert health(np.zeros((3, 2)), P).tolist() == [True, False, False]
    model = LinearGaussianModel(np.eye(2), np.eye(2)[:1], np.eye(2), np.eye(1))
    _, info = kalman.update(GaussianState(np.zeros((2, 2)), P[:2]), np.zeros((2, 1)), model)
    assert info.healthy.tolist() == [True, False]
