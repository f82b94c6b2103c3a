"""The compiled memory step (navgym.envs.memory_kernel) equals the NumPy form to rounding.

Random diagnostics with masked rows, outages, NaN and infinite innovations and NIS, zero and
negative ``S_ii``, over enough steps to wrap the whiteness window; the kernel must also leave
the memory it was given unchanged (a snapshot may hold it).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from filters.core.compiled import numpy_only
from navgym.envs import memory as memory_module
from navgym.envs.memory import InnovationMemory
from tests.filters.compiled_paths import count_calls


def _diagnostics(rng: np.random.Generator, B: int, m: int) -> tuple[SimpleNamespace, np.ndarray]:
    used = rng.random((B, m)) < 0.7
    used[0] = False  # an outage
    S_diag = rng.uniform(0.5, 20.0, (B, m))
    S_diag[1, 0] = 0.0
    S_diag[2, 1] = -1.0
    v = rng.standard_normal((B, m)) * np.sqrt(np.abs(S_diag)) * 3.0
    v[3, 0], v[4, 1] = np.nan, np.inf
    S = np.zeros((B, m, m))
    S[:, np.arange(m), np.arange(m)] = S_diag
    with np.errstate(invalid="ignore"):  # the infinite innovation of a masked row
        nis = (v * v / np.maximum(S_diag, 1e-12) * used).sum(axis=1)
    nis[5], nis[6] = np.nan, np.inf
    return SimpleNamespace(innovation=v, S=S, nis=nis, n_meas=used.sum(axis=1)), used


def test_the_compiled_step_equals_the_numpy_form(monkeypatch):
    rng = np.random.default_rng(0)
    B, m = 16, 5
    mem = InnovationMemory(dt=0.5, m_max=m, window=6)
    compiled = reference = mem.initial_state(B)
    calls = count_calls(monkeypatch, memory_module, ("memory_pass",))
    for k in range(15):
        info, used = _diagnostics(rng, B, m)
        t = np.full(B, k) + np.arange(B) % 3
        compiled, cols = mem.update(compiled, t, info, used)
        with numpy_only():
            reference, ref_cols = mem.update(reference, t, info, used)
        for name, a in zip(reference._fields, reference, strict=True):
            np.testing.assert_allclose(getattr(compiled, name), a, rtol=1e-12, atol=1e-12, err_msg=name)
        assert set(cols) == set(ref_cols)
        for name, a in ref_cols.items():
            np.testing.assert_allclose(cols[name], a, rtol=1e-12, atol=1e-12, err_msg=name)
        assert all(np.isfinite(c).all() for c in cols.values())
    assert calls["memory_pass"] == 15


def test_the_compiled_step_leaves_the_given_memory_unchanged():
    rng = np.random.default_rng(1)
    mem = InnovationMemory(dt=1.0, m_max=3)
    state = mem.initial_state(4)
    for k in range(3):
        info, used = _diagnostics(rng, 8, 3)
        state, _ = mem.update(
            state,
            np.full(4, k),
            SimpleNamespace(
                innovation=info.innovation[4:], S=info.S[4:], nis=info.nis[4:], n_meas=info.n_meas[4:]
            ),
            used[4:],
        )
    kept = [a.copy() for a in state]
    info, used = _diagnostics(rng, 8, 3)
    mem.update(
        state,
        np.full(4, 3),
        SimpleNamespace(
            innovation=info.innovation[4:], S=info.S[4:], nis=info.nis[4:], n_meas=info.n_meas[4:]
        ),
        used[4:],
    )
    for a, b in zip(state, kept, strict=True):
        np.testing.assert_array_equal(a, b)
