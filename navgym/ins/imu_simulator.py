"""IMU simulator: truth kinematics -> measured specific force and angular rate with errors.

The ideal outputs come from :func:`navgym.ins.imu_from_kinematics` (the inverse mechanization);
this module adds the error model of :class:`~navgym.ins.imu_grades.ImuErrorSpec`. Benzerrouk 2014, eq. 2
and 5 write the outputs as truth minus an error, ``omega~ = omega - delta omega`` and
``a~ = a - delta a``, with the covariance of eq. 10; the code adds the error instead, measured =
true + bias + noise. The biases and noises are zero-mean and symmetric, so the measured samples
have the same distribution either way, but the bias sign convention differs: the ``b_k`` here
(returned as :class:`ImuBias`) is measured minus true, i.e. ``-delta`` in Benzerrouk's notation,
and is subtracted from a measurement to correct it::

    y_k = x_k + b_k + sigma_n / sqrt(dt) n_k,      b_{k+1} = b_k + sigma_w sqrt(dt) w_k,
    b_0 ~ N(0, sigma_b^2),   n_k, w_k ~ N(0, I)

Each episode draws from its own generator, in a fixed order: 6 turn-on biases (accel xyz, gyro
xyz), then per step 12 numbers (accel white, gyro white, accel walk, gyro walk). Whole-episode
simulation (:func:`simulate_imu`), blocks of steps (:func:`imu_error_steps`) and stepping
(:func:`imu_error_step` fed by a :class:`~navgym.scenarios.seeding.NormalStream` of width 12)
therefore give the same samples (to rounding: the walk of a block is a cumulative sum).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from navgym.ins.imu_grades import ImuErrorSpec
from navgym.ins.types import ImuSample
from navgym.scenarios.seeding import standard_normal_batch
from navgym.scenarios.validation import check_positive

__all__ = [
    "IMU_NOISE_WIDTH",
    "ImuBias",
    "sample_imu_bias",
    "imu_bias_walks",
    "imu_error_step",
    "imu_error_steps",
    "simulate_imu",
]

#: Standard normals consumed per step and episode by the IMU error model.
IMU_NOISE_WIDTH = 12


class ImuBias(NamedTuple):
    """Accelerometer and gyro biases, shape ``(B, 3)`` (or ``(B, T, 3)`` for a trace)."""

    accel: NDArray[np.float64]
    gyro: NDArray[np.float64]


def sample_imu_bias(spec: ImuErrorSpec, rngs: Sequence[np.random.Generator]) -> ImuBias:
    """Draw the turn-on biases ``b_0 ~ N(0, sigma_b^2)`` of each episode (6 normals each).

    Args:
        spec: Error specification.
        rngs: One generator per episode.

    Returns:
        Biases of shape ``(B, 3)``.

    """
    z = standard_normal_batch(rngs, (6,))
    return ImuBias(spec.accel_bias * z[:, :3], spec.gyro_bias * z[:, 3:])


def imu_bias_walks(
    spec: ImuErrorSpec,
    rngs: Sequence[np.random.Generator],
    dt: float,
    steps: int,
    scale: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Biases ``(B, steps + 1, 6)`` (accelerometer then gyro) held over each step of ``dt``.

    A turn-on bias ``b_0 ~ N(0, sigma_b^2)`` then one random-walk increment per step,
    ``b_{k+1} = b_k + sigma_w sqrt(dt) w_k`` (Groves 2013, §4.4.3), all times the episode's
    ``scale`` (the true IMU's scale against the filter's model; 1 by default). Episode ``b``
    draws ``6 + 6 steps`` normals from ``rngs[b]`` alone, in that order, so B episodes at once
    equal B single ones (a loop over the generators at reset, not in a step).
    """
    sig0 = np.repeat([spec.accel_bias, spec.gyro_bias], 3)
    walk = np.repeat([spec.accel_bias_walk, spec.gyro_bias_walk], 3) * np.sqrt(dt)
    scale = np.ones(len(rngs)) if scale is None else scale
    bias = np.empty((len(rngs), steps + 1, 6))
    for i, g in enumerate(rngs):
        bias[i, 0] = scale[i] * sig0 * g.standard_normal(6)
        bias[i, 1:] = bias[i, 0] + np.cumsum(scale[i] * walk * g.standard_normal((steps, 6)), axis=0)
    return bias


def imu_error_step(
    ideal: ImuSample, bias: ImuBias, spec: ImuErrorSpec, dt: float, noise: NDArray[np.float64]
) -> tuple[ImuSample, ImuBias]:
    """Corrupt one interval's ideal IMU sample and advance the bias random walk.

    Args:
        ideal: Error-free sample, fields ``(B, 3)``.
        bias: Biases during this interval, ``(B, 3)`` each.
        spec: Error specification.
        dt: Interval [s].
        noise: Standard normals of shape ``(B, 12)`` (see the module docstring).

    Returns:
        ``(measured, next_bias)``.

    """
    dt = check_positive("dt", dt)
    noise = np.asarray(noise, np.float64)
    if noise.shape != (bias.accel.shape[0], IMU_NOISE_WIDTH):
        raise ValueError(
            f"noise must have shape ({bias.accel.shape[0]}, {IMU_NOISE_WIDTH}), got {noise.shape}"
        )
    rdt = np.sqrt(dt)
    measured = ImuSample(
        ideal.specific_force + bias.accel + spec.accel_noise / rdt * noise[:, 0:3],
        ideal.angular_rate + bias.gyro + spec.gyro_noise / rdt * noise[:, 3:6],
    )
    nxt = ImuBias(
        bias.accel + spec.accel_bias_walk * rdt * noise[:, 6:9],
        bias.gyro + spec.gyro_bias_walk * rdt * noise[:, 9:12],
    )
    return measured, nxt


def imu_error_steps(
    ideal: ImuSample, bias: ImuBias, spec: ImuErrorSpec, dt: float, noise: NDArray[np.float64]
) -> tuple[ImuSample, ImuBias, ImuBias]:
    """Corrupt ``K`` consecutive intervals at once (:func:`imu_error_step` ``K`` times).

    The bias in effect during interval ``k`` is ``b_k = b_0 + sigma_w sqrt(dt) sum_{j<k} w_j``
    (a cumulative sum over the block instead of ``K`` sequential additions; equal to rounding).
    For whole episodes (:func:`simulate_imu`); for a few intervals of a large batch, ``K`` calls of
    :func:`imu_error_step` on ``(B, 3)`` slices are faster (NumPy's loops over a trailing axis of
    length 3 dominate the block).

    Args:
        ideal: Error-free samples, fields ``(B, K, 3)``.
        bias: Biases during the first interval, ``(B, 3)`` each.
        spec: Error specification.
        dt: Interval [s].
        noise: Standard normals ``(B, K, 12)`` (see the module docstring).

    Returns:
        ``(measured (B, K, 3), biases in effect (B, K, 3), bias after the last interval (B, 3))``.

    Raises:
        ValueError: If shapes disagree or ``dt`` is not positive.

    """
    dt = check_positive("dt", dt)
    f = np.asarray(ideal.specific_force, np.float64)
    w = np.asarray(ideal.angular_rate, np.float64)
    if f.ndim != 3 or f.shape[-1] != 3 or w.shape != f.shape:
        raise ValueError(f"ideal fields must have shape (B, K, 3), got {f.shape} and {w.shape}")
    z = np.asarray(noise, np.float64)
    if z.shape != (*f.shape[:2], IMU_NOISE_WIDTH):
        raise ValueError(f"noise must have shape {(*f.shape[:2], IMU_NOISE_WIDTH)}, got {z.shape}")
    rdt = np.sqrt(dt)

    def walk(b_init: NDArray, sigma: float, zz: NDArray) -> tuple[NDArray, NDArray]:
        cum = np.cumsum(sigma * rdt * zz, axis=1)
        out = np.empty_like(cum)
        out[:, 0] = 0.0
        out[:, 1:] = cum[:, :-1]
        return b_init[:, None, :] + out, b_init + cum[:, -1]

    ba, ba_next = walk(np.asarray(bias.accel, np.float64), spec.accel_bias_walk, z[..., 6:9])
    bg, bg_next = walk(np.asarray(bias.gyro, np.float64), spec.gyro_bias_walk, z[..., 9:12])
    measured = ImuSample(
        f + ba + spec.accel_noise / rdt * z[..., 0:3],
        w + bg + spec.gyro_noise / rdt * z[..., 3:6],
    )
    return measured, ImuBias(ba, bg), ImuBias(ba_next, bg_next)


def simulate_imu(
    ideal: ImuSample,
    dt: float,
    spec: ImuErrorSpec,
    rngs: Sequence[np.random.Generator],
) -> tuple[ImuSample, ImuBias]:
    """Corrupt a whole episode of ideal IMU samples (vectorized over batch and time).

    Args:
        ideal: Error-free samples, fields of shape ``(B, T, 3)`` (e.g. from
            :func:`navgym.ins.imu_from_kinematics` at the interval midpoints).
        dt: Sampling interval [s].
        spec: Error specification.
        rngs: One generator per episode (B of them).

    Returns:
        ``(measured, bias)``: measured samples ``(B, T, 3)`` and the bias in effect during each
        interval ``(B, T, 3)``.

    Raises:
        ValueError: If shapes disagree or ``dt`` is not positive.

    """
    dt = check_positive("dt", dt)
    f = np.asarray(ideal.specific_force, np.float64)
    if f.ndim != 3 or f.shape[-1] != 3 or np.shape(ideal.angular_rate) != f.shape:
        raise ValueError(
            f"ideal fields must have shape (B, T, 3), got {f.shape} and {np.shape(ideal.angular_rate)}"
        )
    if len(rngs) != f.shape[0]:
        raise ValueError(f"rngs must hold {f.shape[0]} generators, got {len(rngs)}")
    b0 = sample_imu_bias(spec, rngs)
    z = standard_normal_batch(rngs, (f.shape[1], IMU_NOISE_WIDTH))
    measured, bias, _ = imu_error_steps(ideal, b0, spec, dt, z)
    return measured, bias
