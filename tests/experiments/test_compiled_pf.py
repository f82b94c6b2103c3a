"""The compiled bootstrap step of experiments.compiled_pf equals filters.particle.bootstrap."""

from pathlib import Path

import numpy as np
import pytest

from benchmarks.particles import PseudorangePF, run_steps
from experiments.compiled_pf.__main__ import main
from experiments.compiled_pf.kernel import _systematic_gather, compiled_step
from filters.core.resampling import systematic_ancestors
from filters.particle import bootstrap

B, N = 12, 300


def _problem(steps_done=2, seed=4):
    model = PseudorangePF(layout="soa", dtype="float32", h_impl="compiled")
    rng = np.random.Generator(np.random.PCG64(seed))
    state, zs, _ = model.scenario(B, N, steps_done + 1, rng)
    state = run_steps(state, zs[:steps_done], model, rng, "none")  # uneven weights
    return model, state, zs[steps_done]


def test_step_equals_the_numpy_filter_on_the_same_draws():
    model, state, z = _problem()
    xT = np.ascontiguousarray(state.x.transpose(0, 2, 1))
    pred = bootstrap.predict(state, model, None, model.dt, np.random.Generator(np.random.PCG64(9)))
    post, info = bootstrap.update(pred, z, model)
    c = compiled_step(xT, state.log_w, z, model, np.random.Generator(np.random.PCG64(9)), resample=False)
    scale = np.abs(pred.x).max()
    np.testing.assert_allclose(c.predicted, pred.x.transpose(0, 2, 1), rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(c.post_log_w, post.log_w, rtol=0, atol=1e-3)
    np.testing.assert_allclose(c.ess, info.ess, rtol=1e-4)
    np.testing.assert_allclose(c.innovation, info.innovation, rtol=0, atol=1e-3)
    np.testing.assert_allclose(c.S, info.S, rtol=1e-4, atol=1e-6 * np.abs(info.S).max())
    np.testing.assert_allclose(c.nis, info.nis, rtol=1e-4, atol=1e-6)
    np.testing.assert_allclose(c.log_likelihood, info.log_likelihood, rtol=0, atol=1e-3)
    np.testing.assert_array_equal(c.healthy, info.healthy)
    assert c.healthy.all() and c.ancestors is None and c.xT is c.predicted


def test_non_finite_particles_are_flagged_as_by_the_filter():
    model, state, z = _problem()
    xT = np.ascontiguousarray(state.x.transpose(0, 2, 1))
    xT[3, 4, 7] = np.nan  # a velocity component: it reaches the position through the prediction
    c = compiled_step(xT, state.log_w, z, model, np.random.default_rng(0), resample=False)
    assert not c.healthy[3] and np.delete(c.healthy, 3).all()


def test_systematic_ancestors_and_gather_are_the_filters_draw_for_draw():
    model, state, z = _problem()
    pred = bootstrap.predict(state, model, None, model.dt, np.random.Generator(np.random.PCG64(1)))
    post, _ = bootstrap.update(pred, z, model)
    w = np.exp(post.log_w - post.log_w.max(axis=1, keepdims=True))
    w /= w.sum(axis=1, keepdims=True)
    U = np.random.default_rng(2).random((B, 1))
    xp = np.ascontiguousarray(pred.x.transpose(0, 2, 1))
    out, anc = np.empty_like(xp), np.empty((B, N), dtype=np.int64)
    _systematic_gather(w, U[:, 0], xp, out, anc)
    expected = systematic_ancestors(w, U)
    assert (np.diff(expected, axis=1) > 0).any()  # the weights are uneven: real resampling
    np.testing.assert_array_equal(anc, expected)
    np.testing.assert_array_equal(out, bootstrap.gather(pred.x, expected).transpose(0, 2, 1))


def test_resampled_step_follows_the_filter_and_resets_the_weights():
    model, state, z = _problem()
    xT = np.ascontiguousarray(state.x.transpose(0, 2, 1))
    r = np.random.Generator(np.random.PCG64(3))
    pred = bootstrap.predict(state, model, None, model.dt, r)
    post, _ = bootstrap.update(pred, z, model, decision=True, rng=r, method="systematic")
    c = compiled_step(xT, state.log_w, z, model, np.random.Generator(np.random.PCG64(3)), resample=True)
    np.testing.assert_array_equal(c.log_w, np.full((B, N), -np.log(N)))
    same = np.all(np.abs(c.xT - post.x.transpose(0, 2, 1)) <= 1e-4 * np.abs(c.xT).max(), axis=1)
    # rounding-level weight differences may move an ancestor across a systematic point
    assert same.mean() > 0.999


def test_bad_input_raises():
    model, state, z = _problem()
    xT = np.ascontiguousarray(state.x.transpose(0, 2, 1))
    with pytest.raises(ValueError, match="float32"):
        compiled_step(xT.astype(np.float64), state.log_w, z, model, np.random.default_rng(0), False)
    with pytest.raises(ValueError, match="expected"):
        compiled_step(xT, state.log_w[:, :5], z, model, np.random.default_rng(0), False)


def test_quick_mode_writes_its_results(tmp_path: Path):
    assert main(["--quick", "--out", str(tmp_path)]) == 0
    for name in ("table.csv", "report.md", "manifest.json"):
        assert (tmp_path / name).stat().st_size > 0
    text = (tmp_path / "report.md").read_text()
    assert "experiments.compiled_pf (Numba)" in text and "filters.particle.bootstrap (NumPy)" in text
