"""Property-based tests (Hypothesis) over every registered Gaussian filter and the bootstrap PF.

Each example draws a batch size B in 1-8, a state dimension n in 1-6, a measurement dimension
m in 1-4, a random model (nonlinear, linear, or measurements on at most three states with
diagonal noise, which sends the KF/EKF to :func:`filters.core.conditioning.condition_observed`),
random SPD covariances (well-conditioned, or a prior of condition number 1e4-1e8) and a random
mask (every row used, random rows, some filters with every row masked, the whole batch masked).
The matrices come from a seeded NumPy generator whose seed Hypothesis draws; the dimensions,
conditioning and mask pattern are drawn by Hypothesis itself, so a failure shrinks to the
smallest shape and the simplest mask.

Properties (docs/architecture.md, "filters"):

* outputs are finite, covariances symmetric (updates: exactly) and PSD (eigenvalues >= -tol),
  health flags True on valid input, and True only where the covariance is positive definite;
* a non-finite covariance (P, Q or R) is bad input: ``ValueError`` naming it;
* an indefinite prior, or an innovation covariance made indefinite by a negative R, sets the
  health flag False for that filter only, with finite outputs (never NaN silently), and leaves
  the other filters of the batch exactly as they would be alone;
* batch == loop: each filter run alone gives the batched result;
* a masked row equals the row deleted; a fully masked filter keeps its prior;
* float32 input is accepted and gives the float64 result to float32 precision;
* bootstrap PF: log-weights normalized, ESS in [1, N], float32 clouds stay float32, resampled
  filters get uniform weights, and batch == loop with the same per-row generators.

The default run is deterministic (``derandomize``) and small. ``NAVGYM_PROPERTY_EXAMPLES=2000``
runs that many random examples per test (a search, not a regression test).
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.configuration import set_hypothesis_home_dir

from filters import FILTERS, GaussianState
from filters.core.linalg import symmetrize
from filters.particle import bootstrap

from .problems import RandomNonlinear

# Hypothesis caches what it learns in ./.hypothesis/ by default; keep the working tree clean
set_hypothesis_home_dir(Path(tempfile.gettempdir()) / "navgym-hypothesis")
_EXAMPLES = os.environ.get("NAVGYM_PROPERTY_EXAMPLES")
PROPERTY = settings(
    max_examples=int(_EXAMPLES) if _EXAMPLES else 25,
    deadline=None,
    database=None,  # no .hypothesis/ folder in the working tree
    derandomize=_EXAMPLES is None,
    suppress_health_check=[HealthCheck.too_slow],
)

NAMES = sorted(FILTERS)

#: Covariances: symmetry of predictions (not symmetrized) and PSD tolerance, relative to the
#: largest eigenvalue of the covariance compared.
SYM_RTOL = 1e-12
PSD_RTOL = 1e-9
#: batch == loop and masked == deleted: relative to the scale of each compared quantity.
SAME_RTOL = 1e-9
#: float32 input against the float64 result.
F32_RTOL = 1e-3


# ---------------------------------------------------------------------------------------------
# random problems
# ---------------------------------------------------------------------------------------------
def spd(rng: np.random.Generator, n: int, log10_cond: float, scale: float) -> np.ndarray:
    """A random SPD ``U diag(lam) U^T``, ``lam`` from ``scale`` down to ``scale / 10**log10_cond``."""
    U, _ = np.linalg.qr(rng.standard_normal((n, n)))
    lam = scale * 10.0 ** (-log10_cond * rng.random(n))
    lam[0] = scale
    if n > 1:
        lam[-1] = scale * 10.0**-log10_cond
    P = (U * lam) @ U.T
    return 0.5 * (P + P.T)


class Rows:
    """The observation model restricted to some rows (the 'deleted rows' reference)."""

    def __init__(self, p: RandomNonlinear, rows: np.ndarray) -> None:
        self.p, self.rows = p, np.asarray(rows)
        self.R = p.R[np.ix_(self.rows, self.rows)]

    def h(self, x):
        return self.p.h(x)[..., self.rows]

    def H(self, x):
        return self.p.H(x)[..., self.rows, :]


@dataclass
class Case:
    """One drawn problem: a model, a prior batch, measurements and a mask."""

    model: RandomNonlinear
    m0: np.ndarray  # (B, n)
    P0: np.ndarray  # (B, n, n)
    z: np.ndarray  # (B, m); NaN on masked entries
    mask: np.ndarray  # (B, m)
    kind: str
    ill: bool
    seed: int

    @property
    def B(self) -> int:
        return self.m0.shape[0]

    def prior(self) -> GaussianState:
        return GaussianState(self.m0.copy(), self.P0.copy())

    def row(self, b: int) -> Case:
        """Filter ``b`` alone (a batch of one)."""
        s = slice(b, b + 1)
        return Case(
            self.model, self.m0[s], self.P0[s], self.z[s], self.mask[s], self.kind, self.ill, self.seed
        )


def _model(rng: np.random.Generator, n: int, m: int, kind: str, k: int) -> RandomNonlinear:
    A = rng.standard_normal((n, n))
    A *= 0.95 / max(abs(np.linalg.eigvals(A)).max(), 1e-12)
    C = rng.standard_normal((m, n))
    D = rng.standard_normal((m, n)) * 0.3
    if kind == "subspace":  # measurements on k < min(m, n) states, diagonal noise
        cols = rng.choice(n, size=k, replace=False)
        keep = np.zeros(n, dtype=bool)
        keep[cols] = True
        C[:, ~keep] = 0.0
        D[:, ~keep] = 0.0
        R = np.diag(10.0 ** rng.uniform(-2, 1, m))
    else:
        R = spd(rng, m, rng.uniform(0, 3), 10.0 ** rng.uniform(-2, 1))
    nonlinear = kind != "linear"
    return RandomNonlinear(
        A=A,
        a=0.2 if nonlinear else 0.0,
        C=C,
        D=D,
        c=0.1 if nonlinear else 0.0,
        Q=spd(rng, n, rng.uniform(0, 3), 10.0 ** rng.uniform(-3, 0)),
        R=R,
    )


@st.composite
def cases(draw, ill: bool | None = None, mask_modes=("all", "random", "some_filters_blind", "all_blind")):
    B = draw(st.integers(1, 8), label="B")
    n = draw(st.integers(1, 6), label="n")
    m = draw(st.integers(1, 4), label="m")
    kinds = ["nonlinear", "linear"] + (["subspace"] if min(m, n) >= 2 else [])
    kind = draw(st.sampled_from(kinds), label="kind")
    k = draw(st.integers(1, min(3, n - 1, m - 1)), label="k") if kind == "subspace" else 0
    ill = draw(st.booleans(), label="ill") if ill is None else ill
    mode = draw(st.sampled_from(mask_modes), label="mask")
    if mode == "all":
        mask = np.ones((B, m), dtype=bool)
    elif mode == "all_blind":
        mask = np.zeros((B, m), dtype=bool)
    else:
        mask = np.array(draw(st.lists(st.booleans(), min_size=B * m, max_size=B * m)), bool).reshape(B, m)
        if mode == "some_filters_blind":
            blind = draw(st.integers(0, B - 1), label="blind filter")
            mask[blind] = False
    seed = draw(st.integers(0, 2**32 - 1), label="seed")
    rng = np.random.default_rng(seed)
    model = _model(rng, n, m, kind, k)
    P0 = np.stack(
        [
            spd(rng, n, rng.uniform(4, 8) if ill else rng.uniform(0, 2), 10.0 ** rng.uniform(-2, 2))
            for _ in range(B)
        ]
    )
    m0 = rng.standard_normal((B, n))
    x = m0 + np.einsum("bij,bj->bi", np.linalg.cholesky(P0), rng.standard_normal((B, n)))
    z = model.h(x) + rng.standard_normal((B, m)) @ np.linalg.cholesky(model.R).T
    z[~mask] = np.nan  # anything may sit in a masked row
    return Case(model, m0, P0, z, mask, kind, ill, seed)


# ---------------------------------------------------------------------------------------------
# checks
# ---------------------------------------------------------------------------------------------
def assert_psd(P: np.ndarray, rtol: float = PSD_RTOL) -> None:
    lam = np.linalg.eigvalsh(P)
    top = np.abs(lam).max(axis=-1, keepdims=True)
    assert (lam >= -rtol * top).all(), f"eigenvalues {lam}"


def assert_symmetric(P: np.ndarray, rtol: float = 0.0) -> None:
    top = np.abs(P).max(axis=(-2, -1), keepdims=True)
    err = np.abs(P - np.swapaxes(P, -1, -2))
    assert (err <= rtol * top).all(), f"asymmetry {err.max()}"


def positive_definite(P: np.ndarray) -> np.ndarray:
    """Per-matrix Cholesky success (the health flag's definition)."""
    ok = np.empty(P.shape[0], dtype=bool)
    for b in range(P.shape[0]):
        try:
            np.linalg.cholesky(P[b])
            ok[b] = np.isfinite(P[b]).all()
        except np.linalg.LinAlgError:
            ok[b] = False
    return ok


def assert_close(a: np.ndarray, b: np.ndarray, rtol: float, what: str) -> None:
    """``|a - b| <= rtol * max(1e-300, max |b|)`` per filter (first axis)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    scale = np.abs(b).reshape(b.shape[0], -1).max(axis=1) if b.size else np.zeros(b.shape[0])
    err = np.abs(a - b).reshape(a.shape[0], -1).max(axis=1) if a.size else np.zeros(a.shape[0])
    assert (err <= rtol * np.maximum(scale, 1e-300)).all(), f"{what}: error {err} against scale {scale}"


def step(name: str, state: GaussianState, c: Case, mask=None, z=None, model=None):
    flt = FILTERS[name]
    model = c.model if model is None else model
    pred = flt.predict(state, c.model)
    post, info = flt.update(pred, c.z if z is None else z, model, mask=c.mask if mask is None else mask)
    return pred, post, info


# ---------------------------------------------------------------------------------------------
# Gaussian filters
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", NAMES)
@PROPERTY
@given(c=cases())
def test_outputs_are_symmetric_psd_finite_and_healthy(name, c):
    pred, post, info = step(name, c.prior(), c)
    for a in (pred.m, pred.P, post.m, post.P, info.innovation, info.S, info.nis, info.log_likelihood):
        assert np.isfinite(a).all()
    assert_symmetric(pred.P, SYM_RTOL)
    assert_symmetric(post.P)  # updates symmetrize: exactly symmetric
    assert_psd(pred.P)
    assert_psd(post.P)
    assert info.healthy.dtype == bool and info.healthy.shape == (c.B,)
    assert info.healthy.all(), f"unhealthy on valid input: {info.healthy}"
    # the flag's meaning: finite mean and a positive-definite covariance
    assert not (info.healthy & ~positive_definite(post.P)).any()
    assert (info.n_meas == c.mask.sum(axis=1)).all()
    assert (info.innovation[~c.mask] == 0.0).all()
    assert (info.nis >= 0).all()
    # fully masked filters keep their (symmetrized) prior: exactly on the whitened path, to
    # rounding on the subspace path (P - G_x G_x^T + V V^T with V = G_x)
    blind = ~c.mask.any(axis=1)
    np.testing.assert_array_equal(post.m[blind], pred.m[blind])
    assert_close(post.P[blind], symmetrize(pred.P[blind]), SAME_RTOL, "blind P")
    assert (info.log_likelihood[blind] == 0.0).all() and (info.nis[blind] == 0.0).all()


@pytest.mark.parametrize("name", NAMES)
@PROPERTY
@given(c=cases(ill=False), where=st.sampled_from(["P", "m", "Q", "R"]), bad=st.sampled_from([np.nan, np.inf]))
def test_non_finite_input_raises_value_error(name, c, where, bad):
    flt = FILTERS[name]
    rng = np.random.default_rng(c.seed)
    b = int(rng.integers(c.B))
    s = c.prior()
    if where in ("P", "m"):
        arr = s.P if where == "P" else s.m
        idx = (b, *(int(rng.integers(k)) for k in arr.shape[1:]))
        arr[idx] = bad
        with pytest.raises(ValueError, match=rf"state\.{where} has non-finite"):
            flt.predict(s, c.model)
        with pytest.raises(ValueError, match=rf"state\.{where} has non-finite"):
            flt.update(s, c.z, c.model, mask=c.mask)
    elif where == "Q":
        Q = np.broadcast_to(c.model.Q, (c.B, *c.model.Q.shape)).copy()
        Q[b, 0, 0] = bad
        with pytest.raises(ValueError, match=r"^Q has non-finite"):
            flt.predict(s, c.model, Q=Q)
    else:
        R = np.broadcast_to(c.model.R, (c.B, *c.model.R.shape)).copy()
        R[b, -1, 0] = bad
        with pytest.raises(ValueError, match=r"^R has non-finite"):
            flt.update(s, c.z, c.model, mask=c.mask, R=R)


@pytest.mark.parametrize("name", NAMES)
@PROPERTY
@given(c=cases(ill=False), negative=st.floats(0.05, 1.0), which=st.integers(0, 5))
def test_indefinite_prior_is_flagged_in_that_filter_only(name, c, negative, which):
    """One filter's prior gets a negative eigenvalue: its flag is False, its outputs finite."""
    flt = FILTERS[name]
    b = which % c.B
    P = c.P0.copy()
    lam, U = np.linalg.eigh(P[b])
    lam[0] = -negative * lam[-1]
    P[b] = (U * lam) @ U.T
    P[b] = 0.5 * (P[b] + P[b].T)
    bad = GaussianState(c.m0.copy(), P)
    post, info = flt.update(bad, c.z, c.model, mask=c.mask)
    assert np.isfinite(post.m).all() and np.isfinite(post.P).all()
    assert np.isfinite(info.nis).all() and np.isfinite(info.log_likelihood).all()
    assert not info.healthy[b]
    others = np.flatnonzero(np.arange(c.B) != b)
    assert info.healthy[others].all()
    # the bad member does not leak into the others: each equals its own run
    for i in others:
        one = c.row(int(i))
        alone, _ = flt.update(one.prior(), one.z, c.model, mask=one.mask)
        assert_close(post.m[i : i + 1], alone.m, SAME_RTOL, "m")
        assert_close(post.P[i : i + 1], alone.P, SAME_RTOL, "P")
    # a prediction from it returns finite numbers (no flag there; the next update judges it)
    pred = flt.predict(bad, c.model)
    assert np.isfinite(pred.m).all() and np.isfinite(pred.P).all()


@pytest.mark.parametrize("name", NAMES)
@PROPERTY
@given(c=cases(ill=False, mask_modes=("all", "random", "some_filters_blind")))
def test_indefinite_innovation_covariance_is_flagged(name, c):
    """``R = -k I`` with ``k`` above every spread makes ``S`` negative definite on the used rows."""
    flt = FILTERS[name]
    pred = flt.predict(c.prior(), c.model)
    k = 10.0 * (1.0 + np.abs(pred.P).max()) * (1.0 + np.abs(c.model.C).sum() + np.abs(c.model.D).sum()) ** 2
    R = -k * np.eye(c.z.shape[1])
    post, info = flt.update(pred, c.z, c.model, mask=c.mask, R=R)
    assert np.isfinite(post.m).all() and np.isfinite(post.P).all()
    assert np.isfinite(info.nis).all() and np.isfinite(info.log_likelihood).all()
    used = c.mask.any(axis=1)
    assert not info.healthy[used].any()
    assert info.healthy[~used].all()  # a blind filter keeps its (valid) prior


@pytest.mark.parametrize("name", NAMES)
@PROPERTY
@given(c=cases())
def test_batch_equals_loop(name, c):
    pred, post, info = step(name, c.prior(), c)
    for b in range(c.B):
        one = c.row(b)
        p1, q1, i1 = step(name, one.prior(), one)
        assert_close(pred.m[b : b + 1], p1.m, SAME_RTOL, "predicted m")
        assert_close(pred.P[b : b + 1], p1.P, SAME_RTOL, "predicted P")
        assert_close(post.m[b : b + 1], q1.m, SAME_RTOL, "filtered m")
        assert_close(post.P[b : b + 1], q1.P, SAME_RTOL, "filtered P")
        assert_close(info.nis[b : b + 1], i1.nis, SAME_RTOL, "nis")
        assert_close(info.log_likelihood[b : b + 1], i1.log_likelihood, SAME_RTOL, "log-likelihood")
        assert info.healthy[b] == i1.healthy[0]


@pytest.mark.parametrize("name", NAMES)
@PROPERTY
@given(c=cases(mask_modes=("random", "some_filters_blind")))
def test_masked_rows_equal_deleted_rows(name, c):
    flt = FILTERS[name]
    pred = flt.predict(c.prior(), c.model)
    for b in range(c.B):
        prior = GaussianState(pred.m[b : b + 1], pred.P[b : b + 1])
        got, info = flt.update(prior, c.z[b : b + 1], c.model, mask=c.mask[b : b + 1])
        keep = np.flatnonzero(c.mask[b])
        if keep.size == 0:
            np.testing.assert_array_equal(got.m, prior.m)
            assert_close(got.P, symmetrize(prior.P), SAME_RTOL, "blind P")
            continue
        ref, ref_info = flt.update(prior, c.z[b : b + 1, keep], Rows(c.model, keep))
        assert_close(got.m, ref.m, SAME_RTOL, "m")
        assert_close(got.P, ref.P, SAME_RTOL, "P")
        assert_close(info.nis, ref_info.nis, SAME_RTOL, "nis")
        assert_close(info.log_likelihood, ref_info.log_likelihood, SAME_RTOL, "log-likelihood")
        assert info.healthy[0] == ref_info.healthy[0]


@pytest.mark.parametrize("name", NAMES)
@PROPERTY
@given(c=cases(ill=False))
def test_float32_input_gives_the_float64_result(name, c):
    s32 = GaussianState(c.m0.astype(np.float32), c.P0.astype(np.float32))
    s64 = GaussianState(s32.m.astype(np.float64), s32.P.astype(np.float64))
    z32 = c.z.astype(np.float32)
    p32, q32, i32 = step(name, s32, c, z=z32)
    p64, q64, i64 = step(name, s64, c, z=z32.astype(np.float64))
    assert np.isfinite(q32.m).all() and np.isfinite(q32.P).all()
    assert i32.healthy.all()
    assert_symmetric(q32.P)
    assert_psd(q32.P)
    assert_close(q32.m - p32.m, q64.m - p64.m, F32_RTOL, "correction")
    assert_close(q32.P, q64.P, F32_RTOL, "P")


# ---------------------------------------------------------------------------------------------
# bootstrap particle filter
# ---------------------------------------------------------------------------------------------
@st.composite
def pf_cases(draw):
    c = draw(cases(ill=False))
    N = draw(st.integers(1, 64), label="N")
    dtype = draw(st.sampled_from([np.float64, np.float32]), label="dtype")
    decision = np.array(draw(st.lists(st.booleans(), min_size=c.B, max_size=c.B)), bool)
    forgetting = draw(st.one_of(st.none(), st.floats(0.05, 1.0)), label="forgetting")
    method = draw(st.sampled_from(["systematic", "stratified", "multinomial", "residual"]), label="method")
    return c, N, dtype, decision, forgetting, method


def pf_run(c: Case, N, dtype, decision, forgetting, method, rows=None, steps: int = 2):
    """``steps`` predict/update cycles of the filters ``rows``, one generator per filter."""
    rows = np.arange(c.B) if rows is None else np.asarray(rows)
    rngs = [np.random.default_rng([c.seed, int(b)]) for b in rows]
    s = bootstrap.from_gaussian(c.m0[rows], c.P0[rows], N, rngs)
    s = s._replace(x=s.x.astype(dtype))
    out = []
    for _ in range(steps):
        s = bootstrap.predict(s, c.model, rng=rngs)
        s, info = bootstrap.update(
            s,
            c.z[rows],
            c.model,
            mask=c.mask[rows],
            forgetting=forgetting,
            decision=decision[rows],
            rng=rngs,
            method=method,
        )
        out.append((s, info))
    return out


@PROPERTY
@given(pc=pf_cases())
def test_bootstrap_weights_normalized_and_ess_in_range(pc):
    c, N, dtype, decision, forgetting, method = pc
    for s, info in pf_run(c, N, dtype, decision, forgetting, method):
        assert s.x.dtype == dtype and s.x.shape == (c.B, N, c.m0.shape[1])
        assert np.isfinite(s.x).all() and np.isfinite(s.log_w).all()
        total = np.exp(s.log_w).sum(axis=1)
        np.testing.assert_allclose(total, 1.0, rtol=0, atol=1e-12)
        assert info.ess.shape == (c.B,)
        assert (info.ess >= 1.0 - 1e-9).all() and (info.ess <= N * (1 + 1e-12)).all(), info.ess
        assert info.healthy.all()
        np.testing.assert_array_equal(info.resampled, decision)
        np.testing.assert_array_equal(s.log_w[decision], np.full((decision.sum(), N), -np.log(N)))
        assert (info.n_meas == c.mask.sum(axis=1)).all()
        assert np.isfinite(info.nis).all() and (info.nis >= 0).all()
        blind = ~c.mask.any(axis=1)  # no measurement: the weights stay uniform (or as forgotten)
        np.testing.assert_allclose(info.ess[blind & ~decision], N, rtol=1e-9)


@PROPERTY
@given(pc=pf_cases())
def test_bootstrap_batch_equals_loop(pc):
    c, N, dtype, decision, forgetting, method = pc
    batch = pf_run(c, N, dtype, decision, forgetting, method)
    rtol = 1e-5 if dtype == np.float32 else 1e-12
    for b in range(c.B):
        alone = pf_run(c, N, dtype, decision, forgetting, method, rows=[b])
        for (s, info), (s1, i1) in zip(batch, alone, strict=True):
            assert_close(s.x[b : b + 1], s1.x, rtol, "particles")
            np.testing.assert_allclose(s.log_w[b], s1.log_w[0], rtol=rtol, atol=rtol)
            np.testing.assert_allclose(info.ess[b], i1.ess[0], rtol=rtol)
            assert info.healthy[b] == i1.healthy[0]
