"""The batched environment core's evaluation quantities (navgym.envs.core)."""

from __future__ import annotations

import contextlib

import numpy as np
import pytest

from filters.core.types import GaussianState
from navgym.envs.core import _nees


def _spd(rng: np.random.Generator, B: int, n: int) -> np.ndarray:
    A = rng.standard_normal((B, n, n))
    return A @ A.transpose(0, 2, 1) + 0.1 * np.eye(n)


def test_nees_is_the_quadratic_form_of_the_inverse_covariance():
    rng = np.random.default_rng(0)
    B, n = 7, 8
    P = _spd(rng, B, n)
    e = rng.standard_normal((B, n))
    ref = np.einsum("bi,bij,bj->b", e, np.linalg.inv(P), e)
    np.testing.assert_allclose(_nees(GaussianState(np.zeros((B, n)), P), e), ref, rtol=1e-10)


def test_nees_with_an_indefinite_member_falls_back_to_the_solve():
    """A diverged member's covariance is not positive definite: the batch is still evaluated."""
    rng = np.random.default_rng(1)
    B, n = 5, 4
    P = _spd(rng, B, n)
    P[2] = np.diag([1.0, -2.0, 3.0, 4.0])
    e = rng.standard_normal((B, n))
    out = _nees(GaussianState(np.zeros((B, n)), P), e)
    ref = np.einsum("bi,bij,bj->b", e, np.linalg.inv(P), e)
    np.testing.assert_allclose(out, ref, rtol=1e-10)
    assert np.isfinite(out).all()


def test_nees_without_a_state_error_is_nan():
    out = _nees(GaussianState(np.zeros((3, 2)), np.broadcast_to(np.eye(2), (3, 2, 2))), None)
    assert out.shape == (3,) and np.isnan(out).all()


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("distinct", [True, False])
def test_recorded_generators_rewind_every_generator_taken(compiled, distinct):
    """Taken by index and by iteration, drawn from, rewound: each back to its state when first
    taken (the compiled snapshot for distinct PCG64 generators, the states' dicts otherwise)."""
    from filters.core.compiled import numpy_only
    from navgym.envs.core import RecordedGenerators

    gens = [np.random.default_rng(40 + i) for i in range(5)]
    if not distinct:
        gens[3] = gens[1]
    with numpy_only() if not compiled else contextlib.nullcontext():
        recorded = RecordedGenerators(gens)
        recorded[2].random(3)  # taken and drawn from before the iteration
        at_first_take = {id(g): g.bit_generator.state for g in gens}
        at_first_take[id(gens[2])] = np.random.default_rng(42).bit_generator.state
        draws = [g.standard_normal(4).tolist() for g in recorded]
        recorded[0].integers(0, 9, dtype=np.uint32)
        recorded.rewind()
        assert [g.bit_generator.state for g in gens] == [at_first_take[id(g)] for g in gens]
        if distinct:
            again = [g.standard_normal(4).tolist() for g in gens]
            assert again[0] == draws[0] and again[4] == draws[4]


def test_nees_compiled_equals_the_numpy_form_and_isolates_diverged_rows(monkeypatch):
    """The compiled quadratic form equals the NumPy form; a diverged row takes the solve alone."""
    from filters.core.compiled import numpy_only
    from navgym.envs import core
    from tests.filters.compiled_paths import count_calls

    rng = np.random.default_rng(2)
    B, n = 9, 15
    P = _spd(rng, B, n)
    P[5] = -np.eye(n)
    e = rng.standard_normal((B, n))
    calls = count_calls(monkeypatch, core, ("quadratic_form_pass",))
    got = _nees(GaussianState(np.zeros((B, n)), P), e)
    with numpy_only():
        ref = _nees(GaussianState(np.zeros((B, n)), P), e)
    assert calls == {"quadratic_form_pass": 1}
    np.testing.assert_allclose(got, ref, rtol=1e-10)
    assert got[5] == pytest.approx(-(e[5] @ e[5]))
