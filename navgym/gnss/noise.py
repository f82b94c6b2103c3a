"""Measurement-noise regimes, switchable per episode and per step (batched).

A :class:`NoiseRegime` holds one parameter array ``(B,)`` per knob, so one call serves B
episodes in different regimes; switching regimes within an episode means passing other
parameters at the next step (:func:`where_regime` mixes two regimes per episode). Regimes:

* **Gaussian**: ``sigma`` only.
* **Gaussian mixture** (Benzerrouk 2014, eq. 71): ``p(x) = (1 - eps) N(0, sigma_1^2) + eps
  N(0, sigma_2^2)`` with contamination ``eps`` and variance ratio
  ``sigma_2^2 / sigma_1^2`` (50 to 2000 in Benzerrouk 2014).
* **Jamming burst**: extra Gaussian noise ``jam_sigma`` and/or the loss of each satellite with
  probability ``loss_prob`` (1 = total outage).
* **Outliers on chosen satellites**: on PRNs flagged in ``outlier_prns`` a gross error of
  ``+-outlier_scale`` occurs with probability ``outlier_prob`` per step.

Randomness comes in as arrays (standard normals, uniforms) drawn from per-episode generators
(:mod:`navgym.gnss.streams`), so the functions here are pure.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MAX_PRN",
    "SIGMA_PR_M",
    "SIGMA_DR_MPS",
    "NoiseRegime",
    "NoiseSample",
    "make_regime",
    "where_regime",
    "sample_noise",
]

#: Largest GPS PRN; ``outlier_prns`` has PRN columns 0..MAX_PRN (column 0 unused).
MAX_PRN: int = 32
#: Default pseudo-range noise standard deviation [m] (Touil & Ghadi 2012, §4, sigma = 10).
SIGMA_PR_M: float = 10.0
#: Default delta-range noise standard deviation [m/s] (Touil & Ghadi 2012, §4, sigma_lambda = 5).
SIGMA_DR_MPS: float = 5.0


class NoiseRegime(NamedTuple):
    """Per-episode noise parameters, each ``(B,)`` (``outlier_prns`` is ``(B, MAX_PRN + 1)``).

    Attributes:
        sigma: Nominal pseudo-range noise sigma_1 [m].
        sigma_dr: Nominal delta-range noise [m/s].
        eps: Mixture contamination probability (0 = Gaussian).
        var_ratio: Mixture variance ratio sigma_2^2 / sigma_1^2 (>= 1).
        jam_sigma: Extra Gaussian pseudo-range noise while jammed [m] (0 = none).
        loss_prob: Probability that a satellite's measurement is lost this step.
        outlier_prob: Probability of a gross error on a chosen satellite this step.
        outlier_scale: Magnitude of a gross error [m].
        outlier_prns: Chosen satellites by PRN, bool ``(B, MAX_PRN + 1)``.
    """

    sigma: NDArray[np.float64]
    sigma_dr: NDArray[np.float64]
    eps: NDArray[np.float64]
    var_ratio: NDArray[np.float64]
    jam_sigma: NDArray[np.float64]
    loss_prob: NDArray[np.float64]
    outlier_prob: NDArray[np.float64]
    outlier_scale: NDArray[np.float64]
    outlier_prns: NDArray[np.bool_]

    @property
    def batch_size(self) -> int:
        """Number of episodes B."""
        return int(self.sigma.shape[0])


class NoiseSample(NamedTuple):
    """Sampled measurement errors, each ``(B, m)``.

    Attributes:
        pseudorange: Pseudo-range error [m].
        delta_range: Delta-range error [m/s].
        lost: Measurement lost (to be masked out).
        contaminated: Drawn from the wide mixture component.
        outlier: Gross error added.
        std: Standard deviation of the Gaussian part of the pseudo-range error [m].
    """

    pseudorange: NDArray[np.float64]
    delta_range: NDArray[np.float64]
    lost: NDArray[np.bool_]
    contaminated: NDArray[np.bool_]
    outlier: NDArray[np.bool_]
    std: NDArray[np.float64]


def make_regime(
    batch: int,
    sigma: ArrayLike = SIGMA_PR_M,
    sigma_dr: ArrayLike = SIGMA_DR_MPS,
    eps: ArrayLike = 0.0,
    var_ratio: ArrayLike = 1.0,
    jam_sigma: ArrayLike = 0.0,
    loss_prob: ArrayLike = 0.0,
    outlier_prob: ArrayLike = 0.0,
    outlier_scale: ArrayLike = 0.0,
    outlier_prns: ArrayLike | None = None,
) -> NoiseRegime:
    """Build a :class:`NoiseRegime` for ``batch`` episodes, broadcasting scalars to ``(B,)``.

    Args:
        batch: Number of episodes B (>= 1).
        sigma: Pseudo-range sigma_1 [m] (> 0).
        sigma_dr: Delta-range sigma [m/s] (> 0).
        eps: Contamination probability in [0, 1] (Benzerrouk 2014, eq. 71).
        var_ratio: sigma_2^2 / sigma_1^2 (>= 1).
        jam_sigma: Extra jamming noise [m] (>= 0).
        loss_prob: Per-satellite loss probability in [0, 1].
        outlier_prob: Outlier probability in [0, 1].
        outlier_scale: Outlier magnitude [m] (>= 0).
        outlier_prns: PRNs with outliers: a sequence of PRNs (same for all episodes) or a bool
            array ``(B, MAX_PRN + 1)``; None = no satellite.

    Returns:
        The regime.

    Raises:
        ValueError: Naming the offending argument.
    """
    if int(batch) < 1:
        raise ValueError(f"batch must be >= 1, got {batch}")
    b = int(batch)

    def col(name: str, value: ArrayLike, lo: float, hi: float, lo_open: bool = False):
        arr = np.broadcast_to(np.asarray(value, np.float64), (b,)).copy()
        bad = ~np.isfinite(arr) | (arr < lo) | (arr > hi) | ((arr <= lo) if lo_open else False)
        if np.any(bad):
            rng = f"({lo}, {hi}]" if lo_open else f"[{lo}, {hi}]"
            raise ValueError(f"{name} must be in {rng}, got {value!r}")
        return arr

    prns = np.zeros((b, MAX_PRN + 1), bool)
    if outlier_prns is not None:
        op = np.asarray(outlier_prns)
        if op.dtype == bool:
            if op.shape != (b, MAX_PRN + 1):
                raise ValueError(f"outlier_prns must have shape ({b}, {MAX_PRN + 1}), got {op.shape}")
            prns = op.copy()
        else:
            op = op.astype(np.int64).ravel()
            if np.any((op < 1) | (op > MAX_PRN)):
                raise ValueError(f"outlier_prns must be PRNs in 1..{MAX_PRN}, got {outlier_prns}")
            prns[:, op] = True
    inf = np.inf
    return NoiseRegime(
        col("sigma", sigma, 0.0, inf, lo_open=True),
        col("sigma_dr", sigma_dr, 0.0, inf, lo_open=True),
        col("eps", eps, 0.0, 1.0),
        col("var_ratio", var_ratio, 1.0, inf),
        col("jam_sigma", jam_sigma, 0.0, inf),
        col("loss_prob", loss_prob, 0.0, 1.0),
        col("outlier_prob", outlier_prob, 0.0, 1.0),
        col("outlier_scale", outlier_scale, 0.0, inf),
        prns,
    )


def where_regime(condition: ArrayLike, if_true: NoiseRegime, if_false: NoiseRegime) -> NoiseRegime:
    """Per-episode choice between two regimes: field-wise ``where(condition (B,), a, b)``."""
    c = np.asarray(condition, bool)
    return NoiseRegime(
        *(
            np.where(c.reshape(c.shape + (1,) * (np.ndim(a) - 1)), a, f)
            for a, f in zip(if_true, if_false, strict=True)
        )
    )


def sample_noise(
    regime: NoiseRegime,
    prn: ArrayLike,
    z_pr: ArrayLike,
    z_dr: ArrayLike,
    u_mix: ArrayLike,
    u_loss: ArrayLike,
    u_out: ArrayLike,
) -> NoiseSample:
    """Draw pseudo-range and delta-range errors for ``(B, m)`` rows under per-episode regimes.

    With standard normals ``z_pr, z_dr`` and uniforms ``u_mix, u_loss, u_out`` per row::

        contaminated = u_mix < eps                              (Benzerrouk 2014, eq. 71)
        s = sqrt(sigma^2 (var_ratio if contaminated else 1) + jam_sigma^2)
        e_pr = s z_pr + outlier * sign * outlier_scale
        outlier = chosen(prn) and u_out < outlier_prob,  sign = +1 if u_out < outlier_prob/2 else -1
        e_dr = sigma_dr (s / sigma) z_dr                        (same regime, delta-range scale)
        lost = u_loss < loss_prob

    Scaling one normal by the chosen component's sigma samples the mixture exactly; adding an
    independent jamming Gaussian is the same as widening sigma.

    Args:
        regime: :class:`NoiseRegime` over B episodes.
        prn: PRN of each row, int ``(B, m)``.
        z_pr: Standard normals ``(B, m)`` for the pseudo-ranges.
        z_dr: Standard normals ``(B, m)`` for the delta-ranges.
        u_mix: Uniforms in [0, 1) ``(B, m)``: mixture component.
        u_loss: Uniforms ``(B, m)``: measurement loss.
        u_out: Uniforms ``(B, m)``: outlier occurrence and sign.

    Returns:
        :class:`NoiseSample`.

    Raises:
        ValueError: For shapes inconsistent with the regime's batch size (naming the argument).
    """
    prn = np.asarray(prn)
    b = regime.batch_size
    if prn.ndim != 2 or prn.shape[0] != b:
        raise ValueError(f"prn must have shape ({b}, m), got {prn.shape}")
    arrays = {"z_pr": z_pr, "z_dr": z_dr, "u_mix": u_mix, "u_loss": u_loss, "u_out": u_out}
    for name, a in arrays.items():
        if np.shape(a) != prn.shape:
            raise ValueError(f"{name} must have shape {prn.shape}, got {np.shape(a)}")
    col = (slice(None), None)
    contaminated = u_mix < regime.eps[col]
    var1 = regime.sigma[col] ** 2
    var = np.where(contaminated, var1 * regime.var_ratio[col], var1)
    if np.any(regime.jam_sigma > 0.0):
        var = var + regime.jam_sigma[col] ** 2
    std = np.sqrt(var)
    e_pr = std * z_pr
    if np.any(regime.outlier_prob > 0.0):
        chosen = np.take_along_axis(regime.outlier_prns, np.clip(prn, 0, MAX_PRN), axis=1)
        p_out = regime.outlier_prob[col]
        outlier = chosen & (u_out < p_out)
        sign = np.where(u_out < 0.5 * p_out, 1.0, -1.0)
        e_pr = e_pr + np.where(outlier, sign * regime.outlier_scale[col], 0.0)
    else:  # same result as the branch above with p_out = 0, without the gather
        outlier = np.zeros(prn.shape, bool)
    e_dr = (regime.sigma_dr / regime.sigma)[col] * std * z_dr
    lost = u_loss < regime.loss_prob[col]
    return NoiseSample(e_pr, e_dr, lost, contaminated, outlier, std)
