"""Linear-Gaussian: the bootstrap PF's mean and covariance converge to the KF's like 1/sqrt(N)."""

import numpy as np

from filters import GaussianState, kalman
from filters.particle import bootstrap, estimates, triggers

from .problems import cv_model, simulate_linear
from .tolerances import SLOPE_TOL

B, T = 64, 10
NS = (250, 1000, 4000, 16000)


def _errors(N, zs, model, seed):
    """RMS over filters and steps of the PF-KF difference, in units of the KF's std."""
    rng = np.random.default_rng(seed)
    m0, P0 = np.zeros((B, 2)), np.broadcast_to(np.eye(2), (B, 2, 2))
    kf = GaussianState(m0, P0)
    pf = bootstrap.from_gaussian(m0, P0, N, rng)
    em, eP = [], []
    for k in range(T):
        kf = kalman.predict(kf, model)
        kf, _ = kalman.update(kf, zs[k], model)
        pf = bootstrap.predict(pf, model, None, 1.0, rng)
        pf, _ = bootstrap.update(pf, zs[k], model)
        g = estimates.mean_and_covariance(pf)
        sd = np.sqrt(np.diagonal(kf.P, axis1=1, axis2=2))
        em.append((g.m - kf.m) / sd)
        eP.append((g.P - kf.P) / (sd[:, :, None] * sd[:, None, :]))
        pf = bootstrap.resample(pf, triggers.ess_trigger(pf.log_w, 0.5), rng)
    return np.sqrt(np.mean(np.square(em))), np.sqrt(np.mean(np.square(eP)))


def test_pf_converges_to_kf_at_monte_carlo_rate():
    model = cv_model()
    _, zs = simulate_linear(model, B, T, np.random.default_rng(0))
    errs = np.array([_errors(N, zs, model, seed=123) for N in NS])
    slope_m, _ = np.polyfit(np.log(NS), np.log(errs[:, 0]), 1)
    slope_P, _ = np.polyfit(np.log(NS), np.log(errs[:, 1]), 1)
    print("\nPF vs KF (B=64, T=10, cv model), RMS error in KF std units:")
    for N, (a, b) in zip(NS, errs, strict=True):
        print(f"  N={N:6d}  mean {a:.4f}  cov {b:.4f}")
    print(f"  log-log slope: mean {slope_m:.3f}, cov {slope_P:.3f} (Monte Carlo rate -0.5)")
    assert abs(slope_m + 0.5) < SLOPE_TOL
    assert abs(slope_P + 0.5) < SLOPE_TOL
    # and the errors are small in absolute terms at the largest N
    assert errs[-1, 0] < 0.05 and errs[-1, 1] < 0.05
