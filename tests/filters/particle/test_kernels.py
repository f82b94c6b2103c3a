"""The compiled kernels of the bootstrap PF (filters.particle.kernels) equal its NumPy path.

Same draws (one seed per path), the NumPy path forced by ``filters.core.compiled.numpy_only``.
Each test also checks that the compiled kernel really ran (or, where it must not apply, that
it did not), so a silent fallback to NumPy cannot make an equality test pass.
"""

import numpy as np
import pytest

from filters.core.compiled import numpy_only
from filters.core.resampling import systematic_ancestors
from filters.core.types import ParticleState
from filters.particle import bootstrap, kernels
from tests.filters.compiled_paths import both_paths, count_calls

B, N = 6, 400


class RangeModel:
    """Planar constant velocity ``[px, py, vx, vy]`` seen as ranges to ``m`` beacons.

    ``f``, ``sample_noise`` and ``h`` keep a component-major cloud component-major (as the
    benchmark's and the GpsIns Resample envs' models do); ``Q`` drives the velocities only.
    """

    def __init__(self, m=5, dtype=np.float64, R=None):
        self.dtype, self.m = np.dtype(dtype), m
        self.Q = np.diag([0.0, 0.0, 0.2, 0.3])
        ang = np.linspace(0.0, 2 * np.pi, m, endpoint=False)
        self.beacons = 100.0 * np.stack([np.cos(ang), np.sin(ang)], axis=1)  # (m, 2)
        self.R = np.diag(np.linspace(1.0, 2.0, m)) if R is None else R

    def f(self, x, u=None, dt=1.0):
        xT = x.transpose(0, 2, 1)
        out = np.array(xT, copy=True)
        out[:, 0] += dt * xT[:, 2]
        out[:, 1] += dt * xT[:, 3]
        return out.transpose(0, 2, 1)

    def h(self, x):
        xT = x.transpose(0, 2, 1)
        dx = xT[:, None, 0, :] - self.beacons[:, 0, None].astype(self.dtype)
        dy = xT[:, None, 1, :] - self.beacons[:, 1, None].astype(self.dtype)
        return np.sqrt(dx * dx + dy * dy).transpose(0, 2, 1)  # (B, N, m) view of (B, m, N)


def _problem(dtype, seed=0, m=5, R=None, steps=2):
    """A cloud after ``steps`` NumPy steps (uneven weights), and the next measurement."""
    model = RangeModel(m, dtype, R)
    rng = np.random.default_rng(seed)
    truth = np.concatenate([rng.normal(0, 20, (B, 2)), rng.normal(0, 1, (B, 2))], axis=1)
    st = bootstrap.from_gaussian(truth, np.diag([25.0, 25.0, 1.0, 1.0]), N, rng, layout="soa")
    st = st._replace(x=st.x.astype(dtype))
    with numpy_only():
        for _ in range(steps + 1):
            truth = truth + np.concatenate([truth[:, 2:], rng.normal(0, 0.5, (B, 2))], axis=1)
            z = np.linalg.norm(truth[:, None, :2] - model.beacons, axis=2) + rng.normal(0, 1.0, (B, m))
            if _ == steps:
                break
            st = bootstrap.predict(st, model, None, 1.0, rng)
            st, _info = bootstrap.update(st, z, model)
    return model, st, z


@pytest.fixture
def calls(monkeypatch):
    """Counts the calls of each compiled kernel of :mod:`filters.particle.kernels`."""
    return count_calls(monkeypatch, kernels, ("weigh_pass", "systematic_pass"))


def _tol(dtype):
    """Agreement of the two paths: the cloud's rounding, on metres-sized numbers."""
    return (2e-4, 2e-4) if dtype == np.float32 else (1e-9, 1e-9)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("masked", [False, True])
def test_update_equals_the_numpy_path(calls, dtype, masked):
    """Posterior log-weights and every UpdateInfo field, with and without a measurement mask."""
    model, st, z = _problem(dtype)
    mask = None
    if masked:
        mask = np.ones(z.shape, dtype=bool)
        mask[1, 2] = mask[4, [0, 3]] = False
        mask[5] = False  # a full outage: weights unchanged
        z = np.where(mask, z, np.nan)
    (a, ia), (b, ib) = both_paths(lambda: bootstrap.update(st, z, model, mask=mask))
    assert calls["weigh_pass"] == 1
    rtol, atol = _tol(dtype)
    # log-weights of hundreds relative to the best particle: rounding scales with them
    np.testing.assert_allclose(a.log_w, b.log_w, rtol=rtol, atol=atol * np.abs(b.log_w).max())
    assert a.x is st.x
    for f in ("innovation", "S", "nis", "log_likelihood", "ess"):
        np.testing.assert_allclose(getattr(ia, f), getattr(ib, f), rtol=rtol, atol=atol, err_msg=f)
    for field in ("healthy", "n_meas", "resampled"):
        np.testing.assert_array_equal(getattr(ia, field), getattr(ib, field), err_msg=field)
    assert ia.healthy.all()
    if masked:
        np.testing.assert_array_equal(ia.innovation[~mask], 0.0)
        np.testing.assert_allclose(a.log_w[5], st.log_w[5], atol=1e-12)


def test_weigh_returns_the_numpy_particle_log_likelihoods(calls):
    model, st, z = _problem(np.float32)
    mask = np.ones(z.shape, dtype=bool)
    (pa, la, _), (pb, lb, _) = both_paths(lambda: bootstrap.weigh(st.x, st.log_w, z, model, mask))
    assert calls["weigh_pass"] == 1
    np.testing.assert_allclose(la, lb, rtol=2e-4, atol=2e-4 * np.abs(lb).max())
    np.testing.assert_allclose(pa, pb, rtol=2e-4, atol=2e-4 * np.abs(pb).max())


def test_batched_diagonal_noise_is_compiled_and_a_full_noise_matrix_is_not(calls):
    model, st, z = _problem(np.float64)
    Rb = np.stack([np.diag(np.full(5, 1.0 + b)) for b in range(B)])
    (a, ia), (b, ib) = both_paths(lambda: bootstrap.update(st, z, model, R=Rb))
    assert calls["weigh_pass"] == 1
    np.testing.assert_allclose(a.log_w, b.log_w, rtol=1e-9, atol=1e-9 * np.abs(b.log_w).max())
    np.testing.assert_allclose(ia.nis, ib.nis, rtol=1e-9)
    full = np.eye(5) + 0.2 * (np.ones((5, 5)) - np.eye(5))
    bootstrap.update(st, z, model, R=full)
    assert calls["weigh_pass"] == 1  # correlated noise: the NumPy path


def test_array_of_structures_clouds_take_the_numpy_path(calls):
    model, st, z = _problem(np.float64)
    aos = ParticleState(np.ascontiguousarray(st.x), st.log_w)

    class AosModel(RangeModel):
        def h(self, x):
            return np.ascontiguousarray(super().h(x))

    bootstrap.update(aos, z, AosModel())
    assert calls["weigh_pass"] == 0


def test_non_finite_particles_fall_back_to_numpy_with_the_same_flags(calls):
    model, st, z = _problem(np.float32)
    x = st.x.copy(order="K")
    x[2, 7, 0] = np.nan
    bad = st._replace(x=x)
    (a, ia), (b, ib) = both_paths(lambda: bootstrap.update(bad, z, model))
    assert calls["weigh_pass"] == 1  # ran, found the NaN, left the step to NumPy
    np.testing.assert_array_equal(ia.healthy, ib.healthy)
    assert not ia.healthy[2] and np.delete(ia.healthy, 2).all()
    np.testing.assert_array_equal(a.log_w, b.log_w)


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_systematic_resampling_gives_the_same_ancestors_for_the_same_weights(calls, dtype):
    """Given identical weights and generators, identical particles (bit for bit), all or some filters."""
    model, st, z = _problem(dtype)
    with numpy_only():
        post, _ = bootstrap.update(st, z, model)
    assert (post.log_w.max(axis=1) - post.log_w.min(axis=1) > 5).all()  # uneven: real resampling
    for decision in (True, np.array([True, False, True, True, False, True])):
        a, b = both_paths(lambda d=decision: bootstrap.resample(post, d, np.random.default_rng(5)))
        np.testing.assert_array_equal(a.x, b.x)
        np.testing.assert_array_equal(a.log_w, b.log_w)
        assert bootstrap.is_component_major(a.x) and a.x.dtype == dtype
    assert calls["systematic_pass"] == 2


def test_systematic_kernel_against_systematic_ancestors_with_zero_weights():
    rng = np.random.default_rng(3)
    w = rng.random((40, 257)) ** 8
    w[:, ::7] = 0.0  # zero-weight particles are never picked
    w[3] = 0.0
    w[3, 100] = 1.0  # one particle holds everything
    w /= w.sum(axis=1, keepdims=True)
    U = 1.0 - rng.random(40)
    x = rng.standard_normal((40, 3, 257))
    out, anc = np.empty_like(x), np.empty((40, 257), dtype=np.int64)
    kernels.systematic_pass(w, U, np.ones(40, dtype=bool), x, out, anc)
    np.testing.assert_array_equal(anc, systematic_ancestors(w, U[:, None]))
    np.testing.assert_array_equal(out, np.take_along_axis(x, anc[:, None, :], axis=2))
    assert (anc[3] == 100).all()


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_resampled_steps_branch_in_few_particles_and_runs_keep_their_statistics(calls, dtype):
    """Ten predict/update/resample steps: per step, and over the whole run.

    The paths agree to rounding; systematic resampling is discontinuous in the weights, so a
    rounding-level weight difference can move an ancestor across a systematic point, and the
    two clouds then differ in that particle. Per step (both paths from the NumPy path's cloud,
    same generator state) fewer than 0.5 % of the particles branch. Over a run the branches
    compound (a moved particle changes the normalizer, so later bounds move too; with this
    seed the float32 clouds first differ at step 6, in 1 of 2400 particles, and 29 % differ
    after step 10, while the float64 clouds stay equal): the clouds' weighted means still
    agree within the Monte Carlo error.
    """
    model, st0, _ = _problem(dtype, steps=0)
    zs = [np.linalg.norm(st0.x.mean(axis=1)[:, None, :2] - model.beacons, axis=2) + k for k in range(10)]

    def step(st, z, seed):
        rng = np.random.default_rng(seed)
        st = bootstrap.predict(st, model, None, 1.0, rng)
        return bootstrap.update(st, z, model, decision=True, rng=rng)[0]

    st = {"compiled": st0, "numpy": st0}
    for k, z in enumerate(zs):
        one, ref = both_paths(lambda s=st["numpy"], z=z, k=k: step(s, z, k))
        same = np.all(np.abs(one.x - ref.x) <= 1e-3 * max(1.0, np.abs(ref.x).max()), axis=2)
        assert same.mean() > 0.995, (k, same.mean())
        st = {"compiled": step(st["compiled"], z, k), "numpy": ref}
    assert calls["weigh_pass"] == 20 and calls["systematic_pass"] == 20
    a, b = st["compiled"].x, st["numpy"].x
    se = np.sqrt(2.0 / N) * b.std(axis=1)  # two clouds of N equally weighted particles
    assert (np.abs(a.mean(axis=1) - b.mean(axis=1)) < 5 * se + 1e-6).all()
