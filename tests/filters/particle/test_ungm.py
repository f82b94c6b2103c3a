"""Touil & Ghadi 2012, §4.1 example 1: the univariate nonstationary growth model, bootstrap PF vs EKF.

Eq. 18-19 with Q = 10, R = 1, x_0 = 0.1, both filters initialized with p(x_0) = N(0, 2), 50 steps,
N = 500 particles, resampling at every step (Touil & Ghadi 2012, §3.2, multinomial as in eq. 17). 100
independent runs are batched as B = 100 filters. Touil & Ghadi 2012 (and Gordon et al. 1993, Fig. 2-3)
shows the PF tracking the bimodal posterior where the EKF fails; Arulampalam et al. (2002, Fig.
6-7) report RMSE of the order of 20 for the EKF and 4-5 for SIR on this model. We assert the PF
mean RMSE below UNGM_PF_OVER_EKF_MAX (0.7) times the EKF's, a bound that leaves a wide margin.
"""

import numpy as np

from filters import GaussianState, kalman
from filters.particle import bootstrap, estimates

from .problems import UNGM
from .tolerances import UNGM_PF_OVER_EKF_MAX, UNGM_PF_RMSE_MAX

B, N, T = 100, 500, 50


def _simulate(rng):
    model = UNGM()
    x = np.full((B, 1), 0.1)
    xs, zs = [], []
    for k in range(1, T + 1):
        x = model.f(x, k) + np.sqrt(10.0) * rng.standard_normal((B, 1))
        xs.append(x)
        zs.append(model.h(x) + rng.standard_normal((B, 1)))
    return np.array(xs), np.array(zs)


def test_ungm_bootstrap_pf_beats_ekf():
    model = UNGM()
    xs, zs = _simulate(np.random.default_rng(2002))
    ekf = GaussianState(np.zeros((B, 1)), np.full((B, 1, 1), 2.0))
    rng = np.random.default_rng(7)
    pf = bootstrap.from_gaussian(np.zeros((B, 1)), np.full((B, 1, 1), 2.0), N, rng)
    err_ekf, err_pf = [], []
    for k in range(1, T + 1):
        ekf = kalman.predict(ekf, model, u=float(k))
        ekf, _ = kalman.update(ekf, zs[k - 1], model)
        pf = bootstrap.predict(pf, model, float(k), 1.0, rng)
        pf, _ = bootstrap.update(pf, zs[k - 1], model)
        est = estimates.mean(pf)  # posterior mean, before resampling
        pf = bootstrap.resample(pf, True, rng, "multinomial")
        err_ekf.append(ekf.m[:, 0] - xs[k - 1, :, 0])
        err_pf.append(est[:, 0] - xs[k - 1, :, 0])
    rmse_ekf = np.sqrt(np.mean(np.square(err_ekf), axis=0))  # per run
    rmse_pf = np.sqrt(np.mean(np.square(err_pf), axis=0))
    print(
        f"\nUNGM (Touil & Ghadi 2012, ex. 1), {B} runs x {T} steps: mean RMSE EKF = {rmse_ekf.mean():.2f}"
        f" (median {np.median(rmse_ekf):.2f}), bootstrap PF N={N} = {rmse_pf.mean():.2f}"
        f" (median {np.median(rmse_pf):.2f}); PF better in {np.mean(rmse_pf < rmse_ekf):.0%} of runs"
    )
    assert np.isfinite(rmse_ekf).all() and np.isfinite(rmse_pf).all()
    assert rmse_pf.mean() < UNGM_PF_OVER_EKF_MAX * rmse_ekf.mean()
    assert rmse_pf.mean() < UNGM_PF_RMSE_MAX, rmse_pf.mean()
    assert np.mean(rmse_pf < rmse_ekf) > 0.8
