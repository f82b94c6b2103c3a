"""Resampling schemes: reference-loop equality, unbiasedness, decisions, generators, bad input."""

import numpy as np
import pytest

from filters.core import resampling as rs

from ..particle.tolerances import N_SIGMA

METHODS = sorted(rs.RESAMPLERS)


# ---------------------------------------------------------------------------------------------
# reference implementations: one filter at a time, one point at a time (Touil & Ghadi 2012, eq. 17)
# ---------------------------------------------------------------------------------------------
def _cdf(w):
    c = np.cumsum(w)
    return c / c[-1]


def _select(c, u):
    """Eq. 17: the index M with c[M-1] < u <= c[M]."""
    for i, ci in enumerate(c):
        if u <= ci:
            return i
    return len(c) - 1


def ref_multinomial(w, u):
    c = _cdf(w)
    return np.array([_select(c, uj) for uj in u])


def ref_systematic(w, u):
    N = len(w)
    c = _cdf(w)
    return np.array([_select(c, (j + u[0]) / N) for j in range(N)])


def ref_stratified(w, u):
    N = len(w)
    c = _cdf(w)
    return np.array([_select(c, (j + u[j]) / N) for j in range(N)])


def ref_residual(w, u):
    N = len(w)
    counts = np.floor(N * w).astype(int)
    R = N - counts.sum()
    if R > 0:
        resid = N * w - np.floor(N * w)
        c = _cdf(resid)
        for j in range(R):
            counts[_select(c, u[j])] += 1
    return np.repeat(np.arange(N), counts)


REFERENCE = {
    "multinomial": ref_multinomial,
    "systematic": ref_systematic,
    "stratified": ref_stratified,
    "residual": ref_residual,
}


def _weights_zoo(rng, B, N):
    """Log-weights with spread, exact zeros (-inf), tiny values and a degenerate row."""
    lw = 3.0 * rng.standard_normal((B, N))
    lw[rng.random((B, N)) < 0.2] = -np.inf
    lw[:, 0] = np.where(np.isfinite(lw).any(axis=1), lw[:, 0], 0.0)
    lw[0] = -np.inf
    lw[0, N // 2] = 0.0  # all mass on one particle
    if B > 1:
        lw[1] = 0.0  # uniform
    if B > 2:
        lw[2, :] = -40.0  # tiny but equal
        lw[2, -1] = 0.0
    return lw


def _reference(method, lw, u):
    w = rs.normalized_weights(lw)
    return np.stack([REFERENCE[method](w[b], u[b]) for b in range(lw.shape[0])])


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("N", [1, 2, 7, 64])
@pytest.mark.parametrize("seed", [0, 1])
def test_kernel_matches_reference_loop_draw_for_draw(method, N, seed):
    rng = np.random.default_rng(seed)
    B = 12
    lw = _weights_zoo(rng, B, N)
    u = 1.0 - rng.random((B, rs.RESAMPLERS[method].n_uniforms(N)))
    got = rs.RESAMPLERS[method].kernel(rs.normalized_weights(lw), u)
    want = _reference(method, lw, u)
    if method == "multinomial":
        np.testing.assert_array_equal(got, want)  # same order: draw order
    else:
        np.testing.assert_array_equal(got, want)  # both nondecreasing


@pytest.mark.parametrize("method", METHODS)
def test_resample_always_equals_reference_loop_with_same_generator(method):
    """`resample` with decision all True draws (1 - U) of shape (B, uniforms) from the generator."""
    B, N = 9, 33
    lw = _weights_zoo(np.random.default_rng(5), B, N)
    got = rs.resample(lw, np.random.default_rng(42), method)
    u = 1.0 - np.random.default_rng(42).random((B, rs.RESAMPLERS[method].n_uniforms(N)))
    np.testing.assert_array_equal(got, _reference(method, lw, u))


@pytest.mark.parametrize("method", ["multinomial", "residual"])
def test_offset_search_is_exact_with_many_filters_and_tiny_weights(method):
    """Row offsets in the flattened search cost resolution; the exact correction repairs it."""
    rng = np.random.default_rng(3)
    B, N = 3000, 5
    lw = np.log(np.array([1e-17, 0.3, 1e-16, 0.7 - 2e-16, 1e-17]))[None, :] + np.zeros((B, 1))
    lw += 1e-3 * rng.standard_normal((B, N))
    u = 1.0 - rng.random((B, N))
    # put some uniforms right at the cumulative boundaries
    c = np.cumsum(rs.normalized_weights(lw), axis=1)
    c /= c[:, -1:]
    u[:, 0] = c[:, 1]
    u[:, 1] = np.nextafter(c[:, 1], 2.0)
    got = rs.RESAMPLERS[method].kernel(rs.normalized_weights(lw), u)
    np.testing.assert_array_equal(got, _reference(method, lw, u))


@pytest.mark.parametrize("method", METHODS)
def test_zero_weight_particles_are_never_selected(method):
    rng = np.random.default_rng(1)
    B, N = 200, 10
    lw = rng.standard_normal((B, N))
    dead = rng.random((B, N)) < 0.5
    dead[:, 0] = False
    lw[dead] = -np.inf
    anc = rs.resample(lw, rng, method)
    assert not np.take_along_axis(dead, anc, axis=1).any()


@pytest.mark.parametrize("method", METHODS)
def test_resampling_is_unbiased(method):
    """E[#copies of i] = N w_i, within N_SIGMA standard errors from the empirical variance.

    The batch axis is the replication: R identical filters resample in one call.
    """
    w = np.array([0.004, 0.31, 0.0, 0.123, 0.05, 0.2131, 0.3, 1e-4])
    w = w / w.sum()
    N, R = w.size, 40_000
    lw = np.log(np.where(w > 0, w, 1e-300))
    lw[w == 0] = -np.inf
    anc = rs.resample(np.tile(lw, (R, 1)), np.random.default_rng(11), method)
    counts = np.stack([(anc == i).sum(axis=1) for i in range(N)], axis=1)
    assert (counts.sum(axis=1) == N).all()
    mean = counts.mean(axis=0)
    se = counts.std(axis=0, ddof=1) / np.sqrt(R)
    err = np.abs(mean - N * w)
    assert (err <= N_SIGMA * se + 1e-12).all(), (method, mean, N * w, se)
    # the low-variance schemes keep every count within one of N w_i
    if method in ("systematic", "residual", "stratified"):
        lo = np.floor(N * w) if method != "stratified" else np.floor(N * w) - 1
        assert (counts >= lo).all()
    if method == "systematic":
        assert (counts <= np.ceil(N * w)).all()


@pytest.mark.parametrize("method", METHODS)
def test_decision_false_keeps_particles_and_draws_nothing(method):
    rng = np.random.default_rng(0)
    B, N = 8, 16
    lw = rng.standard_normal((B, N))
    decision = np.array([True, False, False, True, True, False, True, False])
    anc = rs.resample(lw, np.random.default_rng(9), method, decision)
    np.testing.assert_array_equal(anc[~decision], np.tile(np.arange(N), (int((~decision).sum()), 1)))
    # the decided rows equal resampling only those filters with the same generator
    sub = rs.resample(lw[decision], np.random.default_rng(9), method)
    np.testing.assert_array_equal(anc[decision], sub)
    # no decision at all: identity and the generator is untouched
    g = np.random.default_rng(4)
    state = g.bit_generator.state
    anc0 = rs.resample(lw, g, method, False)
    np.testing.assert_array_equal(anc0, np.tile(np.arange(N), (B, 1)))
    assert g.bit_generator.state == state


@pytest.mark.parametrize("method", METHODS)
def test_per_filter_generators_equal_separate_runs(method):
    B, N = 6, 20
    lw = np.random.default_rng(2).standard_normal((B, N))
    decision = np.array([1, 0, 1, 1, 0, 1], dtype=bool)
    gens = [np.random.default_rng(100 + b) for b in range(B)]
    together = rs.resample(lw, gens, method, decision)
    for b in range(B):
        alone = rs.resample(lw[b : b + 1], np.random.default_rng(100 + b), method, decision[b : b + 1])
        np.testing.assert_array_equal(together[b], alone[0])


def test_registry_and_helpers():
    assert set(rs.RESAMPLERS) == {"multinomial", "stratified", "systematic", "residual"}
    w = rs.normalized_weights(np.array([[0.0, np.log(3.0), -np.inf]]))
    np.testing.assert_allclose(w, [[0.25, 0.75, 0.0]])
    u = rs.uniform(np.random.default_rng(0), 3, (4,))
    assert u.shape == (3, 4) and (u > 0).all() and (u <= 1).all()


# ---------------------------------------------------------------------------------------------
# bad input
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "log_w, match",
    [
        (np.array([[0.0, np.nan]]), "log_w"),
        (np.array([[0.0, np.inf]]), "log_w"),
        (np.array([[-np.inf, -np.inf]]), "log_w"),
        (np.zeros((2, 0)), "N >= 1"),
        (np.zeros(5), "log_w"),
        ([["a", "b"]], "log_w"),
    ],
)
def test_bad_log_weights(log_w, match):
    with pytest.raises(ValueError, match=match):
        rs.resample(log_w, np.random.default_rng(0))


def test_bad_method_decision_rng():
    lw = np.zeros((3, 4))
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="method"):
        rs.resample(lw, rng, "bogus")
    with pytest.raises(ValueError, match="decision"):
        rs.resample(lw, rng, decision=np.ones(2, bool))
    with pytest.raises(ValueError, match="decision"):
        rs.resample(lw, rng, decision=np.array([0.5, 1, 0]))
    with pytest.raises(ValueError, match="rng"):
        rs.resample(lw, 123)
    with pytest.raises(ValueError, match="rng"):
        rs.resample(lw, [np.random.default_rng(0)] * 2)


@pytest.mark.parametrize("scheme", ["systematic", "stratified"])
def test_systematic_and_stratified_match_filterpy(scheme, monkeypatch):
    """Against filterpy 2.0.0's ``monte_carlo`` loops, fed the same uniforms: the same
    ancestors (filterpy selects the first ``j`` with ``position < cumsum_j``; ties have
    probability zero)."""
    import warnings

    warnings.filterwarnings("ignore", category=DeprecationWarning)
    fp = pytest.importorskip("filterpy.monte_carlo.resampling")
    from filters.core.resampling import stratified_ancestors, systematic_ancestors

    rng = np.random.default_rng(11)
    B, N = 20, 60
    w = rng.dirichlet(np.full(N, 0.3), B)  # uneven weights, many near zero
    if scheme == "systematic":
        U = rng.random((B, 1))
        ours = systematic_ancestors(w, U)
    else:
        U = rng.random((B, N))
        ours = stratified_ancestors(w, U)
    for b in range(B):
        monkeypatch.setattr(fp, "random", lambda *size, r=U[b]: r[0] if not size else r.copy())
        theirs = getattr(fp, f"{scheme}_resample")(w[b])
        np.testing.assert_array_equal(ours[b], theirs)


def test_exp_weights_flushes_only_negligible_weights():
    """exp_weights == exp above -700, exactly 0 below (and for -inf), NaN kept; the normalized
    weights of a wide cloud equal the exact ones to rounding."""
    from filters.core.resampling import EXP_FLUSH, exp_weights

    a = np.array([0.0, -1.0, -699.9, -700.1, -708.5, -745.5, -np.inf, np.nan])
    w = exp_weights(a.copy())
    np.testing.assert_array_equal(w[:3], np.exp(a[:3]))
    np.testing.assert_array_equal(w[3:7], 0.0)
    assert np.isnan(w[7])
    rng = np.random.default_rng(1)
    lw = rng.uniform(-900.0, 0.0, (4, 1000))
    lw[:, 0] = 0.0
    exact = np.exp(lw)
    exact /= exact.sum(axis=1, keepdims=True)
    np.testing.assert_allclose(rs.normalized_weights(lw.copy()), exact, rtol=1e-15, atol=1e-300)
    assert EXP_FLUSH == -700.0
