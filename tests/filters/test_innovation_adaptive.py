"""IAE noise estimation and chi-square exclusion (filters.innovation_adaptive)."""

from __future__ import annotations

from contextlib import nullcontext

import numpy as np
import pytest
from scipy.stats import chi2

from filters.innovation_adaptive import chi2_thresholds, chi_square_exclusion, iae_init, iae_update
from tests.filters.compiled_paths import count_calls


def _epochs(rng, B, m, T, hph, r_true):
    """Innovations of a filter whose predicted spread is ``hph`` and whose true noise is ``r_true``."""
    return rng.normal(size=(T, B, m)) * np.sqrt(hph + r_true)


def test_iae_recovers_the_true_noise_ratio():
    rng = np.random.default_rng(0)
    B, m, N = 200, 3, 400
    hph = np.array([1.0, 2.0, 0.5])
    R = np.diag([1.0, 1.0, 4.0])
    r_true = np.array([1.0, 9.0, 16.0])  # ratios 1, 9, 4
    mem = iae_init(B, m, N)
    S = np.broadcast_to(np.diag(hph) + R, (B, m, m))
    for v in _epochs(rng, B, m, N, hph, r_true):
        mem, ratio = iae_update(mem, v, S, R, np.ones((B, m), dtype=bool))
    # the mean over filters of a window estimate: standard error ~ sqrt(2/N) (hph + r) / r / sqrt(B)
    np.testing.assert_allclose(ratio.mean(axis=0), [1.0, 9.0, 4.0], rtol=0.02)


def test_iae_uses_only_the_epochs_a_row_was_received_and_forgets_outside_the_window():
    B, m, N = 2, 2, 3
    mem = iae_init(B, m, N)
    R = np.eye(m)
    S = np.broadcast_to(2.0 * np.eye(m), (B, m, m))  # hph = 1
    mask = np.array([[True, False], [True, True]])
    for v in (np.full((B, m), 2.0), np.full((B, m), 2.0), np.full((B, m), 2.0)):
        mem, ratio = iae_update(mem, v, S, R, mask)
    # v^2 = 4, hph = 1: R_hat = 3 on received rows; row 1 of filter 0 never received: ratio 1
    np.testing.assert_allclose(ratio, [[3.0, 1.0], [3.0, 3.0]])
    for v in (np.zeros((B, m)),) * 3:  # three quiet epochs push the loud ones out of the window
        mem, ratio = iae_update(mem, v, S, R, np.ones((B, m), dtype=bool))
    np.testing.assert_allclose(ratio, 0.1)  # floored (-1 / 1 below the floor)


def test_iae_batch_equals_loop():
    rng = np.random.default_rng(1)
    B, m, N = 4, 3, 5
    R = np.diag([1.0, 2.0, 3.0])
    mem = iae_init(B, m, N)
    mems = [iae_init(1, m, N) for _ in range(B)]
    for _ in range(8):
        v = rng.normal(size=(B, m))
        S = R + np.eye(m) * rng.uniform(0.5, 1.5, (B, 1, 1))
        mask = rng.random((B, m)) > 0.3
        mem, ratio = iae_update(mem, v, S, R, mask)
        for b in range(B):
            mems[b], r1 = iae_update(mems[b], v[b : b + 1], S[b : b + 1], R, mask[b : b + 1])
            np.testing.assert_allclose(r1[0], ratio[b], rtol=1e-12)


def test_exclusion_removes_the_faulty_row_only():
    rng = np.random.default_rng(2)
    B, m = 50, 6
    S = np.broadcast_to(np.eye(m), (B, m, m))
    v = rng.normal(size=(B, m)) * 0.5
    v[:, 3] += 12.0
    res = chi_square_exclusion(v, S, np.ones((B, m), dtype=bool), alpha=0.01)
    assert res.excluded[:, 3].all() and res.excluded.sum() == B
    assert res.consistent.all()
    np.testing.assert_allclose(res.nis, (np.delete(v, 3, axis=1) ** 2).sum(axis=1))


def test_exclusion_false_alarm_rate_is_alpha_on_consistent_innovations():
    rng = np.random.default_rng(3)
    B, m, alpha = 20000, 5, 0.05
    A = rng.normal(size=(m, m))
    S = A @ A.T + m * np.eye(m)
    v = rng.multivariate_normal(np.zeros(m), S, size=B)
    res = chi_square_exclusion(
        v, np.broadcast_to(S, (B, m, m)), np.ones((B, m), dtype=bool), alpha=alpha, max_exclusions=0
    )
    rate = 1.0 - res.consistent.mean()
    assert abs(rate - alpha) < 4 * np.sqrt(alpha * (1 - alpha) / B)
    np.testing.assert_allclose(res.nis, np.einsum("bi,ij,bj->b", v, np.linalg.inv(S), v), rtol=1e-10)


def test_exclusion_respects_masks_and_keeps_one_row():
    v = np.array([[30.0, 40.0, 0.0]])
    S = np.eye(3)[None]
    res = chi_square_exclusion(v, S, np.array([[True, True, False]]), alpha=0.01, max_exclusions=5)
    assert res.mask.tolist() == [[True, False, False]]  # the worst (40) out, one row always kept
    assert not res.consistent[0]  # 30 sigma still fails with one row
    assert res.nis[0] == pytest.approx(900.0)
    assert chi2.ppf(0.99, 1) < 900.0


def _faulty_innovations(B, m, seed):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(B, m))
    v[rng.random((B, m)) < 0.2] *= 8.0  # gross errors on some rows
    keep = rng.random((B, m)) < 0.85
    return v, keep


def test_whitened_exclusion_equals_the_identity_covariance_bit_for_bit():
    """S = None (whitened innovations) gives what S = I gives, compiled and NumPy alike."""
    from filters.core.compiled import numpy_only

    B, m = 400, 12
    v, keep = _faulty_innovations(B, m, 7)
    eye = np.broadcast_to(np.eye(m), (B, m, m))
    for ctx in (nullcontext, numpy_only):
        with ctx():
            a = chi_square_exclusion(v, None, keep, alpha=0.01, max_exclusions=3)
            b = chi_square_exclusion(v, eye, keep, alpha=0.01, max_exclusions=3)
        assert a.excluded.any() and not a.consistent.all()  # the test did exclude rows
        np.testing.assert_array_equal(a.mask, b.mask)
        np.testing.assert_array_equal(a.consistent, b.consistent)
        if ctx is nullcontext:  # the compiled sum of squares = the compiled identity solve
            np.testing.assert_array_equal(a.nis, b.nis)
        else:
            np.testing.assert_allclose(a.nis, b.nis, rtol=1e-12)


def test_per_filter_parameters_equal_separate_calls_bit_for_bit():
    """alpha and max_exclusions per filter (a tuning grid's rows) = one call per parameter pair."""
    B, m = 300, 6
    v, keep = _faulty_innovations(B, m, 8)
    rng = np.random.default_rng(9)
    alpha = rng.choice([0.001, 0.01, 0.1], B)
    kmax = rng.integers(0, 4, B)
    got = chi_square_exclusion(v, None, keep, alpha=alpha, max_exclusions=kmax)
    for a in np.unique(alpha):
        for k in np.unique(kmax):
            rows = (alpha == a) & (kmax == k)
            ref = chi_square_exclusion(v[rows], None, keep[rows], alpha=float(a), max_exclusions=int(k))
            for x, y in zip(got, ref, strict=True):
                np.testing.assert_array_equal(x[rows], y)
    # the parameters matter: a scalar call of the most lenient test differs
    assert (got.excluded != chi_square_exclusion(v, None, keep, alpha=0.001, max_exclusions=0).excluded).any()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"alpha": 0.0}, "alpha"),
        ({"alpha": 1.5}, "alpha"),
        ({"alpha": np.array([0.01, 0.0])}, "alpha"),
        ({"alpha": np.full(3, 0.01)}, "alpha must be a scalar or one per filter"),
        ({"max_exclusions": -1}, "max_exclusions"),
        ({"max_exclusions": 1.5}, "max_exclusions"),
        ({"max_exclusions": np.array([1, 2, 3])}, "max_exclusions must be a scalar or one per filter"),
    ],
)
def test_exclusion_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        chi_square_exclusion(
            np.zeros((2, 2)), np.broadcast_to(np.eye(2), (2, 2, 2)), np.ones((2, 2), dtype=bool), **kwargs
        )


def test_iae_bad_input():
    mem = iae_init(2, 2, 3)
    with pytest.raises(ValueError, match="shapes"):
        iae_update(mem, np.zeros((2, 3)), np.zeros((2, 2, 2)), np.eye(2), np.ones((2, 2), dtype=bool))
    with pytest.raises(ValueError, match="window"):
        iae_init(2, 2, 0)


def test_chi2_thresholds_are_the_ppf_of_each_row_count():
    table = chi2_thresholds(0.01, 6)
    assert table.shape == (7,) and not table.flags.writeable
    np.testing.assert_array_equal(table[1:], chi2.ppf(0.99, np.arange(1, 7)))
    assert table[0] == table[1]
    assert chi2_thresholds(0.01, 6) is table  # computed once


def test_the_compiled_nis_equals_the_numpy_form(monkeypatch):
    from filters import innovation_adaptive as ia
    from filters.core.compiled import numpy_only

    rng = np.random.default_rng(5)
    B, m = 300, 6
    A = rng.standard_normal((B, m, m))
    S = A @ np.swapaxes(A, 1, 2) + 0.5 * np.eye(m)
    v = rng.standard_normal((B, m)) * 3
    keep = rng.random((B, m)) < 0.6
    keep[0] = False  # nothing kept: 0
    keep[1] = True
    calls = count_calls(monkeypatch, ia, ("masked_nis_pass",))
    got = ia._nis(v, S, keep)
    with numpy_only():
        ref = ia._nis(v, S, keep)
    assert calls == {"masked_nis_pass": 1}
    np.testing.assert_allclose(got, ref, rtol=1e-10, atol=1e-12)
    assert got[0] == 0.0
    bad = S.copy()
    bad[3] = -np.eye(m)  # a broken S: the NumPy form takes the batch
    keep[3] = True
    with numpy_only():
        ref = ia._nis(v, bad, keep)
    np.testing.assert_array_equal(ia._nis(v, bad, keep), ref)
    assert calls == {"masked_nis_pass": 2}
    result = chi_square_exclusion(v, S, keep)  # the test through the compiled form
    with numpy_only():
        expected = chi_square_exclusion(v, S, keep)
    np.testing.assert_array_equal(result.mask, expected.mask)
    np.testing.assert_allclose(result.nis, expected.nis, rtol=1e-10, atol=1e-12)
