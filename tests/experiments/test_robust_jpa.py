"""Belles et al. 2022, §5 study (experiments.robust_jpa): its model pieces and its quick mode."""

from __future__ import annotations

import csv
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from experiments.robust_jpa.__main__ import initial_estimates, main, run_filter
from navgym.ins.attitude import rotation_matrix, rotation_vector
from navgym.jpa.models import (
    JpaConfig,
    JpaObservation,
    dd_operator,
    make_geometry,
    observation_covariance,
    right_jacobian,
    simulate,
    slices,
)


@pytest.fixture(scope="module")
def short():
    cfg = replace(JpaConfig(), duration=20.0, outlier_zones=((10.0, 20.0),))
    return cfg, make_geometry(cfg)


def test_double_differences_cancel_receiver_and_satellite_terms():
    """D maps a per-receiver or per-satellite common term to zero, and each DD has four terms."""
    S, N = 10, 3
    D = dd_operator(S, N)
    assert D.shape == ((N + 1) * (S - 1), (N + 2) * S)
    per_receiver = np.repeat(np.arange(N + 2.0), S)  # a receiver clock
    per_satellite = np.tile(np.arange(S, dtype=float) ** 2, N + 2)  # a satellite clock / orbit
    np.testing.assert_array_equal(D @ per_receiver, 0.0)
    np.testing.assert_array_equal(D @ per_satellite, 0.0)
    np.testing.assert_array_equal(np.abs(D).sum(axis=1), 4.0)


def test_simulated_noise_has_the_model_covariance(short):
    """The differenced noise of the simulation has the filters' Sigma (sampled, 4000 runs)."""
    cfg, geom = short
    truth = simulate(replace(cfg, duration=0.0), geom, 4000, 0, outliers=False)
    obs = JpaObservation(cfg, truth.R[0], geom.U[0], np.eye(cfg.n_obs))
    sl = slices(cfg)
    x = np.zeros((4000, cfg.n_states))
    x[:, sl["a"]] = truth.a
    x[:, sl["p"]] = truth.p[0]
    noise = truth.z[0] - obs.h(x)
    Sigma = observation_covariance(cfg, geom.elevation[0], dd_operator(cfg.n_satellites, len(cfg.baselines)))
    emp = np.cov(noise.T)
    sd = np.sqrt(np.diag(Sigma))
    corr_err = np.abs(emp / np.outer(sd, sd) - Sigma / np.outer(sd, sd)).max()
    assert corr_err < 0.1, corr_err  # sampling error of a correlation from 4000 draws: ~0.016
    np.testing.assert_allclose(np.sqrt(np.diag(emp)), sd, rtol=0.05)


def test_observation_jacobian_matches_finite_differences(short):
    cfg, geom = short
    rng = np.random.default_rng(1)
    B = 3
    R_nom = rotation_matrix(rng.normal(0, 0.5, (B, 3)))
    obs = JpaObservation(cfg, R_nom, geom.U[0], np.eye(cfg.n_obs))
    x = rng.normal(0.0, 1.0, (B, cfg.n_states))
    x[:, 0:3] = rng.normal(0.0, 0.1, (B, 3))  # an attitude error away from zero
    H = obs.H(x)
    eps = 1e-6
    num = np.stack(
        [(obs.h(x + eps * e) - obs.h(x - eps * e)) / (2 * eps) for e in np.eye(cfg.n_states)], axis=-1
    )
    np.testing.assert_allclose(H, num, rtol=0, atol=1e-7)


def test_right_jacobian_is_the_derivative_of_the_exponential():
    phi = np.array([[0.3, -0.2, 0.5], [1e-7, 0.0, 0.0]])
    d = np.array([1e-6, -2e-6, 0.5e-6])
    lhs = rotation_matrix(phi + d)
    rhs = rotation_matrix(phi) @ rotation_matrix(right_jacobian(phi) @ d)
    np.testing.assert_allclose(lhs, rhs, rtol=0, atol=1e-11)


def test_outliers_are_cycle_slips_on_the_base_master_phases(short):
    """Inside the zone the corrupted rows differ from the outlier-free run by whole cycles."""
    cfg, geom = short
    clean = simulate(cfg, geom, 5, 3, outliers=False)
    dirty = simulate(cfg, geom, 5, 3, outliers=True)
    n = cfg.n_dd
    k = 15  # inside [10, 20)
    rows = dirty.outlier[k]
    assert rows.sum() == geom.outlier_rows.sum() == 2 and rows[:n].sum() == 2  # Phi_bm rows only
    np.testing.assert_array_equal(dirty.outlier[5], False)
    # the same noise draws are not shared (the slips draw random numbers), so compare with the
    # model: the slip is an integer multiple of the wavelength on the corrupted rows
    obs = JpaObservation(cfg, dirty.R[k], geom.U[k], np.eye(cfg.n_obs))
    sl = slices(cfg)
    x = np.zeros((5, cfg.n_states))
    x[:, sl["a"]] = dirty.a
    x[:, sl["p"]] = dirty.p[k]
    slip = (dirty.z[k] - obs.h(x))[:, rows] / 0.19029367279836487
    assert (np.abs(np.round(slip)) >= 1).all() and (np.abs(slip - np.round(slip)) < 0.3).all()
    assert clean.outlier.sum() == 0


def test_iterated_eskf_is_consistent_from_a_small_attitude_error():
    """Model, simulation and filter agree: from a 1 deg prior the attitude NEES is about 3.

    (From Belles et al. 2022's 10 deg prior it is 100-400 during the first 200 s: the float ambiguities
    absorb part of the linearization error; the study's README discusses it.)
    """
    cfg = replace(JpaConfig(), duration=100.0, outlier_zones=(), sigma0_attitude=np.deg2rad(1.0))
    geom = make_geometry(cfg)
    truth = simulate(cfg, geom, 40, 0, outliers=False)
    x0, R0 = initial_estimates(cfg, truth, 1)
    nees = []

    def record(k, state, R_nom):
        if k in (25, 50, 100):
            e = rotation_vector(np.swapaxes(R_nom, 1, 2) @ truth.R[k])
            nees.append(np.einsum("bi,bij,bj->b", e, np.linalg.inv(state.P[:, 0:3, 0:3]), e).mean())

    run_filter("I-ESKF", cfg, geom, truth, x0, R0, callback=record)
    assert len(nees) == 3
    assert all(1.5 < v < 6.0 for v in nees), nees  # chi-square(3) mean over 40 runs: 3 +- 0.4


def test_bad_outlier_ranks_raise():
    with pytest.raises(ValueError, match="outlier_ranks must lie in 1..9"):
        make_geometry(replace(JpaConfig(), outlier_ranks=(0, 3)))


def test_quick_study_reproduces_belles_2022_qualitatively(tmp_path: Path):
    """Robust filters keep the position near the ideal filter's; the I-ESKF breaks and stays off."""
    assert main(["--quick", "--out", str(tmp_path)]) == 0
    for name in (
        "table.csv",
        "report.md",
        "rmse.png",
        "cdf.png",
        "efficiency.png",
        "errors.npz",
        "manifest.json",
    ):
        assert (tmp_path / name).stat().st_size > 0
    with open(tmp_path / "table.csv") as f:
        rows = {r["filter"]: r for r in csv.DictReader(f)}
    col = "pos RMSE in outlier zones [m]"
    zone = {k: float(r[col]) for k, r in rows.items()}
    after = {k: float(r["pos RMSE after zones [m]"]) for k, r in rows.items()}
    for robust in ("Huber I-ESKF", "Tukey I-ESKF"):
        assert zone[robust] < 0.3 * zone["I-ESKF"], (robust, zone)
        assert after[robust] < 0.3 * after["I-ESKF"], (robust, after)
        # 6 runs x 100 s: a noisy estimate (0.79 and 1.03 measured with 6 and 8 runs; an
        # estimator that discarded the carrier phases would score below 0.01)
        assert 0.6 < float(rows[robust]["efficiency (no outliers, eq. 29)"]) < 1.5
    assert zone["ideal I-ESKF"] < zone["Tukey I-ESKF"]
    assert after["I-ESKF"] > 5 * after["ideal I-ESKF"]  # no recovery after the zone
