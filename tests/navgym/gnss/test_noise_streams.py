import numpy as np
import pytest

from navgym import geo
from navgym.gnss import (
    NORMALS_PER_ROW,
    UNIFORMS_PER_ROW,
    EpisodeStreams,
    clock_init,
    clock_step,
    constellation,
    episode_generators,
    make_regime,
    sample_noise,
    simulate_gnss_step,
    where_regime,
)

from .tolerances import MC_STD_REL


def _draws(b, m, seed=0):
    """(z_pr, z_dr, u_mix, u_loss, u_out), each (b, m)."""
    rng = np.random.default_rng(seed)
    return (*rng.standard_normal((2, b, m)), *rng.random((3, b, m)))


def _binom_tol(p, n):
    return 5 * np.sqrt(p * (1 - p) / n) + 1e-12


def test_gaussian_std_matches_configuration():
    b, m = 20000, 12
    reg = make_regime(b, sigma=np.where(np.arange(b) < b // 2, 3.0, 30.0), sigma_dr=0.2)
    s = sample_noise(reg, np.ones((b, m), int), *_draws(b, m))
    assert np.std(s.pseudorange[: b // 2]) == pytest.approx(3.0, rel=MC_STD_REL)
    assert np.std(s.pseudorange[b // 2 :]) == pytest.approx(30.0, rel=MC_STD_REL)
    assert np.std(s.delta_range[: b // 2]) == pytest.approx(0.2, rel=MC_STD_REL)
    assert not (s.lost.any() or s.contaminated.any() or s.outlier.any())


@pytest.mark.parametrize(("eps", "ratio"), [(0.05, 2000.0), (0.2, 100.0), (0.5, 50.0)])
def test_mixture_contamination_and_variance(eps, ratio):
    b, m = 20000, 12
    n = b * m
    reg = make_regime(b, sigma=2.0, eps=eps, var_ratio=ratio)
    s = sample_noise(reg, np.ones((b, m), int), *_draws(b, m, seed=1))
    assert s.contaminated.mean() == pytest.approx(eps, abs=_binom_tol(eps, n))
    # Benzerrouk 2014, eq. 71: variance (1 - eps) s1^2 + eps s2^2; each component Gaussian.
    assert np.std(s.pseudorange[~s.contaminated]) == pytest.approx(2.0, rel=MC_STD_REL)
    wide = s.pseudorange[s.contaminated]
    assert np.std(wide) == pytest.approx(2.0 * np.sqrt(ratio), rel=3 * MC_STD_REL)


def test_jamming_and_outliers():
    b, m = 5000, 12
    prn = np.tile(np.arange(1, m + 1), (b, 1))
    reg = make_regime(
        b,
        sigma=1.0,
        jam_sigma=50.0,
        loss_prob=0.3,
        outlier_prob=0.4,
        outlier_scale=200.0,
        outlier_prns=[3, 7],
    )
    s = sample_noise(reg, prn, *_draws(b, m, seed=2))
    assert s.lost.mean() == pytest.approx(0.3, abs=_binom_tol(0.3, b * m))
    chosen = np.isin(prn, [3, 7])
    assert not s.outlier[~chosen].any()
    assert s.outlier[chosen].mean() == pytest.approx(0.4, abs=_binom_tol(0.4, 2 * b))
    signs = np.sign(s.pseudorange[s.outlier])
    assert abs(signs.mean()) < 0.1
    clean = s.pseudorange[~chosen]
    assert np.std(clean) == pytest.approx(np.sqrt(1 + 50.0**2), rel=MC_STD_REL)


def test_where_regime_switches_per_episode():
    calm = make_regime(4, sigma=1.0)
    jam = make_regime(4, sigma=1.0, loss_prob=1.0, outlier_prns=[5])
    mixed = where_regime(np.array([True, False, True, False]), jam, calm)
    assert mixed.loss_prob.tolist() == [1.0, 0.0, 1.0, 0.0]
    assert mixed.outlier_prns[:, 5].tolist() == [True, False, True, False]
    s = sample_noise(mixed, np.ones((4, 6), int), *_draws(4, 6))
    assert s.lost.all(axis=1).tolist() == [True, False, True, False]


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"eps": 1.5}, "eps"),
        ({"var_ratio": 0.5}, "var_ratio"),
        ({"sigma": 0.0}, "sigma"),
        ({"loss_prob": -0.1}, "loss_prob"),
        ({"outlier_prns": [40]}, "outlier_prns"),
        ({"jam_sigma": np.nan}, "jam_sigma"),
    ],
)
def test_bad_regime_names_argument(kwargs, name):
    with pytest.raises(ValueError, match=name):
        make_regime(3, **kwargs)


def test_sample_noise_bad_shapes():
    reg = make_regime(2)
    ok = np.zeros((2, 4))
    with pytest.raises(ValueError, match="u_loss"):
        sample_noise(reg, np.ones((2, 4), int), ok, ok, ok, np.zeros((2, 5)), ok)
    with pytest.raises(ValueError, match="prn"):
        sample_noise(reg, np.ones((3, 4), int), ok, ok, ok, ok, ok)


@pytest.mark.parametrize("seed", [0, 123])
def test_streams_batch_equals_single_seeds(seed):
    b, steps = 4, 13
    batch = EpisodeStreams(episode_generators(seed, b), 5, 2, block=6)
    singles = [EpisodeStreams(episode_generators(seed + i, 1), 5, 2, block=6) for i in range(b)]
    for _ in range(steps):
        z, u = batch.step()
        for i, s in enumerate(singles):
            zi, ui = s.step()
            np.testing.assert_array_equal(z[i], zi[0])
            np.testing.assert_array_equal(u[i], ui[0])


def test_simulated_episodes_batch_equals_single_runs(almanac):
    """Full GNSS step pipeline: B episodes at once == B single episodes with seeds s+i."""
    seed, b, m, steps = 42, 3, 12, 5
    lat = np.deg2rad([45.0, -20.0, 10.0])
    lon = np.deg2rad([0.0, 120.0, -60.0])
    rx = geo.geodetic_to_ecef(lat, lon, 50.0)
    vel = np.zeros((b, 3))
    regimes = make_regime(b, eps=[0.0, 0.3, 0.1], var_ratio=[1.0, 500.0, 50.0], loss_prob=[0.0, 0.0, 0.2])

    def run(gens, idx):
        n = len(idx)
        streams = EpisodeStreams(gens, NORMALS_PER_ROW * m + 2, UNIFORMS_PER_ROW * m, block=4)
        z, _ = streams.step()
        clock = clock_init(z[:, -2:])
        reg = type(regimes)(*(f[idx] for f in regimes))
        out = []
        for k in range(steps):
            z, u = streams.step()
            clock = clock_step(clock, 1.0, z[:, -2:])
            t = almanac.t_ref[0] + k
            g = simulate_gnss_step(
                almanac,
                t,
                rx[idx],
                vel[idx],
                clock,
                reg,
                z[:, : NORMALS_PER_ROW * m],
                u,
                orbit=constellation(almanac, t),
            )
            assert g.pseudorange.shape == (n, m)
            out.append((g.pseudorange, g.delta_range, g.mask))
        return out

    together = run(episode_generators(seed, b), np.arange(b))
    for i in range(b):
        alone = run(episode_generators(seed + i, 1), np.array([i]))
        for (pb, db, mb), (p1, d1, m1) in zip(together, alone, strict=True):
            np.testing.assert_allclose(pb[i], p1[0], rtol=0, atol=1e-6)
            np.testing.assert_allclose(db[i], d1[0], rtol=0, atol=1e-9)
            np.testing.assert_array_equal(mb[i], m1[0])
