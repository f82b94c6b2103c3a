"""The compiled observed-subspace update (filters.core.observed_kernels) equals the NumPy form.

Same inputs through :func:`filters.kalman.update` on both paths (the NumPy path forced by
``filters.core.compiled.numpy_only``, where ``condition_observed`` takes the update); each test
checks that the kernel ran (or did not), so a silent fallback cannot make an equality pass.
"""

import numpy as np
import pytest

from filters import kalman
from filters.core import observed_kernels
from filters.core.models import LinearGaussianModel
from filters.core.types import GaussianState
from tests.filters.compiled_paths import both_paths, count_calls
from tests.filters.core.test_conditioning import _exact_posterior, _observed_problem

RTOL, ATOL = 1e-9, 1e-9


@pytest.fixture
def calls(monkeypatch):
    return count_calls(monkeypatch, observed_kernels, ("observed_pass",))


def _update(m, P, v, H, R, mask):
    """``kalman.update`` of a linear model with ``h(x) = H x``: innovations ``v``."""
    model = LinearGaussianModel(np.eye(P.shape[1]), H, np.eye(P.shape[1]), R)
    Hb = np.broadcast_to(H, (m.shape[0], *H.shape[-2:]))
    z = np.einsum("bij,bj->bi", Hb, m) + v
    return kalman.update(GaussianState(m, P), z, model, mask=mask)


def _assert_equal(a, b):
    (sa, ia), (sb, ib) = a, b
    with np.errstate(invalid="ignore"):  # an indefinite posterior's filter: NaN on both sides
        sd = np.sqrt(np.diagonal(sb.P, axis1=1, axis2=2))
    np.testing.assert_allclose(sa.m / sd, sb.m / sd, rtol=RTOL, atol=ATOL)
    corr = sd[:, :, None] * sd[:, None, :]
    np.testing.assert_allclose(sa.P / corr, sb.P / corr, rtol=RTOL, atol=ATOL)
    np.testing.assert_array_equal(sa.P, np.swapaxes(sa.P, 1, 2))  # exactly symmetric
    for f in ("innovation", "S", "nis", "log_likelihood"):
        np.testing.assert_allclose(getattr(ia, f), getattr(ib, f), rtol=RTOL, atol=ATOL, err_msg=f)
    np.testing.assert_array_equal(ia.healthy, ib.healthy)
    np.testing.assert_array_equal(ia.n_meas, ib.n_meas)


@pytest.mark.parametrize("observed", [(3,), (0, 5), (0, 1, 6)])
@pytest.mark.parametrize("batched", [False, True], ids=["shared", "per-filter"])
def test_the_kernel_equals_the_numpy_form(calls, observed, batched):
    m, P, v, H, r, mask = _observed_problem(len(observed), observed=observed)
    Hm, R = (H, r[:, :, None] * np.eye(12)) if batched else (H[0], np.diag(r[0]))
    a, b = both_paths(lambda: _update(m, P, v, Hm, R, mask))
    assert calls["observed_pass"] == 1
    _assert_equal(a, b)
    assert a[1].healthy.all()
    np.testing.assert_array_equal(a[0].m[0], m[0])  # the outage changes nothing
    np.testing.assert_array_equal(a[1].innovation[~mask], 0.0)


@pytest.mark.parametrize("B", [1, 5])
def test_small_batches(calls, B):
    m, P, v, H, r, mask = (a[2 : 2 + B] for a in _observed_problem(11, B=8))
    a, b = both_paths(lambda: _update(m, P, v, H[0], np.diag(r[0]), mask))
    assert calls["observed_pass"] == 1
    _assert_equal(a, b)


def test_a_cold_clock_prior_loses_no_more_digits_than_the_numpy_form(calls):
    """A 3e5 m clock prior: both forms lose digits (conditioning); against the exact posterior."""
    m, P, v, H, r, mask = _observed_problem(12, B=8, scale_clock=3e5)
    a, b = both_paths(lambda: _update(m, P, v, H[0], np.diag(r[0]), mask))
    assert calls["observed_pass"] == 1
    err = {"kernel": 0.0, "numpy": 0.0}
    for i in range(2, 8):
        u = np.flatnonzero(mask[i])
        em, eP = _exact_posterior(m[i], P[i], v[i, u], H[0][u], r[0][u])
        sd = np.sqrt(np.diag(eP))
        for name, (post, _) in (("kernel", a), ("numpy", b)):
            err[name] = max(err[name], np.abs((post.m[i] - em) / sd).max())
            err[name] = max(err[name], np.abs((post.P[i] - eP) / np.outer(sd, sd)).max())
    assert err["kernel"] < 1e-3 and err["kernel"] <= 10 * err["numpy"] + 1e-12, err


def test_a_zero_noise_row_or_an_indefinite_observed_block_is_handed_back(calls, monkeypatch):
    """The kernel returns None; ``kalman.update`` then runs what it runs without the kernel."""
    m, P, v, H, r, mask = _observed_problem(3)
    R = np.diag(r[0])
    R[2, 2] = 0.0  # row 2 has zero variance where it is used
    P2 = P.copy()
    P2[4, 0, 0] = -1.0  # P_oo of filter 4 not positive definite
    w = lambda R, P: _update(m, P, v, H[0], R, mask)  # noqa: E731
    got = [w(R, P), w(np.diag(r[0]), P2)]
    assert calls["observed_pass"] == 2
    monkeypatch.setattr(observed_kernels, "observed_update", lambda *a: None)
    for a, b in zip(got, [w(R, P), w(np.diag(r[0]), P2)], strict=True):
        _assert_equal(a, b)
    assert calls["observed_pass"] == 2
    assert not got[1][1].healthy[4]


def test_an_unhealthy_posterior_is_flagged_as_by_the_numpy_form(calls):
    m, P, v, H, r, mask = _observed_problem(4)
    P2 = P.copy()
    P2[7, 3, 3] = -5.0  # an unobserved state with a negative variance: P+ indefinite
    a, b = both_paths(lambda: _update(m, P2, v, H[0], np.diag(r[0]), mask))
    assert calls["observed_pass"] == 1
    _assert_equal(a, b)
    assert not a[1].healthy[7] and a[1].healthy[:7].all()


def test_a_gaussian_sum_bank_stays_on_the_numpy_form(calls):
    m, P, v, H, r, mask = _observed_problem(5, B=4)
    model = LinearGaussianModel(np.eye(8), H[0], np.eye(8), np.diag(r[0]))
    bank = np.stack([np.diag(r[0]), 4 * np.diag(r[0])])[None].repeat(4, axis=0)
    kalman.update_bank(GaussianState(m, P), m @ H[0].T + v, model, mask, bank)
    assert calls["observed_pass"] == 0
