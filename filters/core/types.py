"""State and result containers shared by every filter family.

All containers are immutable ``NamedTuple``s whose arrays carry the batch axis first
(``docs/architecture.md``, "filters"): B independent filters advance in one call.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class GaussianState(NamedTuple):
    """Batch of Gaussian beliefs N(m, P).

    Attributes:
        m: means, shape ``(B, n)``.
        P: covariances, shape ``(B, n, n)``.

    """

    m: np.ndarray
    P: np.ndarray


class InformationState(NamedTuple):
    """Batch of Gaussian beliefs in information form (Benzerrouk 2014, eq. 22).

    Attributes:
        y: information vectors ``Y m``, shape ``(B, n)``.
        Y: information matrices ``P^-1``, shape ``(B, n, n)``.

    """

    y: np.ndarray
    Y: np.ndarray


class MixtureState(NamedTuple):
    """Batch of K-component Gaussian mixtures.

    Attributes:
        m: component means, shape ``(B, K, n)``.
        P: component covariances, shape ``(B, K, n, n)``.
        log_w: component log-weights (normalized), shape ``(B, K)``.

    """

    m: np.ndarray
    P: np.ndarray
    log_w: np.ndarray


class ParticleState(NamedTuple):
    """Batch of weighted particle clouds.

    Attributes:
        x: particles, shape ``(B, N, n)``.
        log_w: normalized log-weights, shape ``(B, N)``.

    """

    x: np.ndarray
    log_w: np.ndarray


class UpdateInfo(NamedTuple):
    """Diagnostics of one measurement update, for B filters.

    Attributes:
        innovation: ``z - z_hat`` (zero on masked rows), shape ``(B, m)``.
        S: innovation covariance (identity on masked rows and columns), shape ``(B, m, m)``.
        nis: normalized innovation squared ``v^T S^-1 v`` over unmasked rows, shape ``(B,)``.
        log_likelihood: ``log N(v; 0, S)`` over unmasked rows, shape ``(B,)``.
        healthy: finite outputs and positive-definite covariance, shape ``(B,)``.
        n_meas: number of unmasked rows used, shape ``(B,)``.
        ess: effective sample size (particle filters only, else ``None``), shape ``(B,)``.
        resampled: whether each filter resampled (particle filters only), shape ``(B,)``.

    """

    innovation: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    log_likelihood: np.ndarray
    healthy: np.ndarray
    n_meas: np.ndarray
    ess: np.ndarray | None = None
    resampled: np.ndarray | None = None


class MeasurementMoments(NamedTuple):
    """The measurement prediction of a Gaussian prior, without the measurement noise.

    Attributes:
        v: innovations ``z - z_hat`` (or the model's ``residual``), ``(B, m)``.
        C: spread of the predicted measurements, ``(B, m, m)``: the innovation covariance is
            ``S = C + R`` (sigma points: ``sum wc (Z - z_hat)(Z - z_hat)^T``, Benzerrouk 2014, eq. 58;
            divided differences: ``S1 S1^T + S2 S2^T``, eq. 36).
        P_xz: cross covariance ``(B, n, m)`` (eq. 59; eq. 37).
        ok: ``(B,)`` False where the prior covariance needed jitter to be factorized.
    """

    v: np.ndarray
    C: np.ndarray
    P_xz: np.ndarray
    ok: np.ndarray

    def faded(self, lam: np.ndarray) -> MeasurementMoments:
        """Measurement moments with faded spreads ``lam C``, ``lam P_xz`` (Benzerrouk 2014, eq. 65-66).

        The points stay where they were placed, on the unfaded prior ``N(m, P)``; only their
        spreads are scaled by ``lam (B,)``. For a linear ``h`` these are exactly the moments of
        the faded prior ``N(m, lam P)``; for a nonlinear ``h`` they are not (the points of
        ``N(m, lam P)`` would be ``sqrt(lam)`` further out), which is the sigma-point reading of
        eq. 65-66 that :mod:`filters.adaptive` documents.
        """
        L = np.asarray(lam)[:, None, None]
        return self._replace(C=L * self.C, P_xz=L * self.P_xz)
