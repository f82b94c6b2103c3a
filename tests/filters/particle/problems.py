"""Small models shared by the particle-filter tests."""

import numpy as np

from filters import LinearGaussianModel
from filters.examples import UNGM  # noqa: F401  (Touil & Ghadi 2012, eq. 18-19, shared with experiments.ungm)


def cv_model(dt=1.0, q=0.3, r=0.5):
    """1-D constant velocity, position measured: x = [p, v]."""
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    H = np.array([[1.0, 0.0]])
    return LinearGaussianModel(F, H, Q, np.array([[r]]))


def two_sensor_model():
    """2-D random walk seen by three correlated sensors (full R, for masking tests)."""
    F = np.array([[0.95, 0.1], [0.0, 0.9]])
    Q = np.array([[0.2, 0.05], [0.05, 0.1]])
    H = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, -1.0]])
    R = np.array([[0.5, 0.1, 0.0], [0.1, 0.4, 0.05], [0.0, 0.05, 0.3]])
    return LinearGaussianModel(F, H, Q, R)


def simulate_linear(model, B, T, rng, m0=None, P0=None):
    """Truth and measurements (T, B, n) / (T, B, m) of a LinearGaussianModel."""
    F, H, Q, R = model.transition_matrix, model.observation_matrix, model.Q, model.R
    n, m = F.shape[0], H.shape[0]
    m0 = np.zeros((B, n)) if m0 is None else m0
    P0 = np.eye(n) if P0 is None else P0
    x = m0 + rng.standard_normal((B, n)) @ np.linalg.cholesky(P0).T
    xs, zs = [], []
    for _ in range(T):
        x = x @ F.T + rng.standard_normal((B, n)) @ np.linalg.cholesky(Q).T
        xs.append(x)
        zs.append(x @ H.T + rng.standard_normal((B, m)) @ np.linalg.cholesky(R).T)
    return np.array(xs), np.array(zs)
