"""Attitude algebra on direction cosine matrices, vectorized over leading axes.

The one home of the rotation helpers: Rodrigues' formula and the cross product on ``(..., 3)``
arrays (:func:`rotation_matrix`, :func:`cross`) and on component-first ``(3, ...)`` slabs
(:func:`rotation_matrix_components`, :func:`cross_components`; see the note above them), and
angle wrapping (:func:`wrap_angle`).

Conventions: ``C_b_n`` (Groves' C_b^n) rotates body-frame vectors into the NED navigation
frame, ``v_n = C_b_n @ v_b``; Euler angles are the aerospace 3-2-1 sequence (yaw, pitch, roll).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "wrap_angle",
    "cross",
    "skew",
    "rotation_matrix",
    "rotation_matrix_components",
    "cross_components",
    "rotation_vector",
    "euler_to_dcm",
    "yaw_to_dcm",
    "dcm_to_euler",
    "euler_from_dcm_entries",
    "dcm_to_yaw",
    "orthonormalize",
]


def wrap_angle(a: ArrayLike) -> NDArray[np.float64]:
    """Angles wrapped into ``[-pi, pi)`` (NaN stays NaN, without a warning)."""
    with np.errstate(invalid="ignore"):
        return np.mod(np.asarray(a, np.float64) + np.pi, 2.0 * np.pi) - np.pi


def cross(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Cross product ``a x b`` over the last axis (faster than ``np.cross`` on small batches)."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    return a[..., _C1] * b[..., _C2] - a[..., _C2] * b[..., _C1]


_C1 = np.array([1, 2, 0])
_C2 = np.array([2, 0, 1])


def skew(w: ArrayLike) -> NDArray[np.float64]:
    """Skew-symmetric (cross-product) matrix [w x], Benzerrouk 2014, eq. 3's Omega.

    Args:
        w: Vectors, shape ``(..., 3)``.

    Returns:
        Matrices of shape ``(..., 3, 3)`` with ``skew(w) @ x == cross(w, x)``.

    """
    w = np.asarray(w, np.float64)
    out = np.zeros(w.shape + (3,))
    out[..., 0, 1] = -w[..., 2]
    out[..., 0, 2] = w[..., 1]
    out[..., 1, 0] = w[..., 2]
    out[..., 1, 2] = -w[..., 0]
    out[..., 2, 0] = -w[..., 1]
    out[..., 2, 1] = w[..., 0]
    return out


def rotation_matrix(phi: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrix of a rotation vector (Rodrigues' formula), the exponential map.

    Benzerrouk 2014, eq. 4 (attitude update over one step with ``phi = omega dt``)::

        exp([phi x]) = I + sin|phi| / |phi| [phi x] + (1 - cos|phi|) / |phi|^2 [phi x]^2

    (The transcription of eq. 4 in Benzerrouk 2014 prints the first coefficient with a minus sign and
    the second over ``|phi|``; the exact exponential above is what eq. 3 integrates to.)
    Evaluated in the closed form ``(1 - b |phi|^2) I + a [phi x] + b phi phi^T`` (with
    ``[phi x]^2 = phi phi^T - |phi|^2 I``), ``a = sin|phi| / |phi|`` and
    ``b = (1 - cos|phi|) / |phi|^2 = 2 sin^2(|phi|/2) / |phi|^2`` from half-angle sines: free of
    cancellation for small angles and, with ``|phi|`` offset by 1e-150, exact at ``phi = 0``
    (``a = 1``, ``b = 1/2``) without a branch.

    Args:
        phi: Rotation vectors [rad], shape ``(..., 3)``.

    Returns:
        Rotation matrices, shape ``(..., 3, 3)``.

    """
    phi = np.asarray(phi, np.float64)
    th2 = (phi * phi).sum(axis=-1)
    th = np.sqrt(th2) + 1e-150  # exact limits a -> 1, b -> 1/2 at phi = 0, no branch
    half = 0.5 * th
    sh = np.sin(half)
    a = 2.0 * sh * np.cos(half) / th  # sin|phi| / |phi|
    b = 2.0 * sh * sh / (th * th)  # (1 - cos|phi|) / |phi|^2, free of cancellation
    R = (b[..., None, None] * phi[..., :, None]) * phi[..., None, :]
    R += ((1.0 - b * th2)[..., None] * _EYE_FLAT + a[..., None] * (phi[..., _K_INDEX] * _K_SIGN)).reshape(
        R.shape
    )
    return R


# Row-major entries of [phi x]: the component of phi at each entry and its sign.
_K_INDEX = np.array([0, 2, 1, 2, 0, 0, 1, 0, 0])
_K_SIGN = np.array([0.0, -1.0, 1.0, 1.0, 0.0, -1.0, -1.0, 1.0, 0.0])
_EYE_FLAT = np.eye(3).ravel()


# ---------------------------------------------------------------------------------------------
# Component-first ("structure of arrays") layout: vectors (3, ...), matrices (3, 3, ...) with
# M[i, j] the row-i, column-j entry over any trailing axes. NumPy's stacked 3x3 matmul costs one
# BLAS call per matrix; element-wise passes over the trailing axes are 5-10x faster, which is
# what the quadrotor transition's hot path uses.
# ---------------------------------------------------------------------------------------------
def cross_components(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cross product ``a x b`` along axis 0, component-first layout.

    ``(a x b)_i = a_j b_k - a_k b_j`` for ``(i, j, k)`` the cyclic permutations of ``(0, 1, 2)``,
    written into one output array with three element-wise passes per component. ``a`` broadcasts
    against ``b``; for a matrix ``B (3, m, ...)`` and ``a (3, 1, ...)`` the result is ``[a x] B``
    column by column.

    The layout exists for speed: on ``(..., 3)`` arrays a cross product is a gather over a trailing
    axis of length 3 (and a stacked 3x3 matmul one BLAS call per matrix); on component-first
    arrays each component is an element-wise pass over the trailing axes, 5-10x faster on
    large batches. :func:`cross` is the last-axis form.

    Args:
        a: Vectors, shape ``(3, ...)``.
        b: Vectors, shape ``(3, ...)``, broadcastable with ``a``.

    Returns:
        ``a x b``, shape ``broadcast(a, b).shape``.

    """
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
        np.multiply(a[j], b[k], out=out[i, ...])
        out[i] -= a[k] * b[j]
    return out


def rotation_matrix_components(th: NDArray[np.float64]) -> NDArray[np.float64]:
    """:func:`rotation_matrix` in the component-first layout (Rodrigues, Benzerrouk 2014, eq. 4).

    ``Exp(th) = cos|th| I + sinc|th| [th x] + (1 - cos|th|) / |th|^2 th th^T`` with
    ``(1 - cos x) / x^2 = sinc(x / 2)^2 / 2``, which keeps small angles free of cancellation
    (``np.sinc`` is exact at 0).

    The layout exists for speed: NumPy's stacked 3x3 matmul costs one BLAS call per matrix, so
    the callers (the quadrotor IMU preintegration) keep rotations as ``(3, 3, ...)`` slabs and
    multiply them with element-wise passes over the trailing axes, 5-10x faster; this builds the
    slab directly, with one element-wise pass per entry.

    Args:
        th: Rotation vectors [rad], shape ``(3, ...)``.

    Returns:
        Rotation matrices, shape ``(3, 3, ...)`` (``H[i, j]`` the row-i, column-j entry).

    """
    x = np.sqrt(th[0] * th[0] + th[1] * th[1] + th[2] * th[2])
    a = np.sinc(x / np.pi)
    b = 0.5 * np.sinc(x / (2.0 * np.pi)) ** 2
    bt = b * th
    H = bt[:, None] * th[None]
    c = np.cos(x)
    at = a * th
    H[0, 0] += c
    H[1, 1] += c
    H[2, 2] += c
    H[0, 1] -= at[2]
    H[1, 0] += at[2]
    H[0, 2] += at[1]
    H[2, 0] -= at[1]
    H[1, 2] -= at[0]
    H[2, 1] += at[0]
    return H


def rotation_vector(C: ArrayLike) -> NDArray[np.float64]:
    """Rotation vector of a rotation matrix (logarithm map, inverse of :func:`rotation_matrix`).

    ``phi = theta / (2 sin theta) vee(C - C^T)`` with ``cos theta = (tr C - 1) / 2``; valid for
    angles below pi (used here for small step rotations).

    Args:
        C: Rotation matrices, shape ``(..., 3, 3)``.

    Returns:
        Rotation vectors [rad], shape ``(..., 3)``.

    """
    C = np.asarray(C, np.float64)
    v = 0.5 * np.stack(
        [C[..., 2, 1] - C[..., 1, 2], C[..., 0, 2] - C[..., 2, 0], C[..., 1, 0] - C[..., 0, 1]],
        axis=-1,
    )
    s = np.linalg.norm(v, axis=-1)
    c = 0.5 * (np.trace(C, axis1=-2, axis2=-1) - 1.0)
    th = np.arctan2(s, c)
    small = s < 1e-8
    factor = np.where(small, 1.0 + th * th / 6.0, th / np.where(small, 1.0, s))
    return factor[..., None] * v


def yaw_to_dcm(cos_yaw: ArrayLike, sin_yaw: ArrayLike) -> NDArray[np.float64]:
    """``euler_to_dcm(0, 0, yaw)`` from the yaw's cosine and sine (level vehicles and ships).

    ``C_b^n = R_z(yaw) = [[c, -s, 0], [s, c, 0], [0, 0, 1]]``: the same values as the 3-2-1 form
    with zero roll and pitch, without its twelve trigonometric and product passes.

    Returns:
        ``C_b_n`` of shape ``broadcast(cos_yaw, sin_yaw).shape + (3, 3)``.
    """
    c, s = np.broadcast_arrays(np.asarray(cos_yaw, np.float64), np.asarray(sin_yaw, np.float64))
    C = np.zeros(c.shape + (3, 3))
    C[..., 0, 0] = c
    C[..., 0, 1] = -s
    C[..., 1, 0] = s
    C[..., 1, 1] = c
    C[..., 2, 2] = 1.0
    return C


def euler_to_dcm(roll: ArrayLike, pitch: ArrayLike, yaw: ArrayLike) -> NDArray[np.float64]:
    """Body-to-NED DCM from 3-2-1 Euler angles, ``C_b^n = R_z(yaw) R_y(pitch) R_x(roll)``.

    Groves (2013) eq. 2.22 (transposed, since Groves writes C_n^b).

    Args:
        roll: Roll [rad].
        pitch: Pitch [rad], broadcastable with ``roll``.
        yaw: Yaw (heading from north, clockwise seen from above) [rad].

    Returns:
        ``C_b_n`` of shape ``broadcast(roll, pitch, yaw).shape + (3, 3)``.

    """
    r, p, y = np.broadcast_arrays(
        np.asarray(roll, np.float64), np.asarray(pitch, np.float64), np.asarray(yaw, np.float64)
    )
    sr, cr, sp, cp, sy, cy = np.sin(r), np.cos(r), np.sin(p), np.cos(p), np.sin(y), np.cos(y)
    C = np.empty(r.shape + (3, 3))
    C[..., 0, 0] = cp * cy
    C[..., 0, 1] = -cr * sy + sr * sp * cy
    C[..., 0, 2] = sr * sy + cr * sp * cy
    C[..., 1, 0] = cp * sy
    C[..., 1, 1] = cr * cy + sr * sp * sy
    C[..., 1, 2] = -sr * cy + cr * sp * sy
    C[..., 2, 0] = -sp
    C[..., 2, 1] = sr * cp
    C[..., 2, 2] = cr * cp
    return C


def dcm_to_euler(
    C_b_n: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """3-2-1 Euler angles (roll, pitch, yaw) of a body-to-NED DCM (Groves eq. 2.23).

    Args:
        C_b_n: DCMs, shape ``(..., 3, 3)``.

    Returns:
        ``(roll, pitch, yaw)`` [rad], yaw in (-pi, pi].

    """
    C = np.asarray(C_b_n, np.float64)
    return euler_from_dcm_entries(C[..., 0, 0], C[..., 1, 0], C[..., 2, 0], C[..., 2, 1], C[..., 2, 2])


def euler_from_dcm_entries(
    c00: ArrayLike, c10: ArrayLike, c20: ArrayLike, c21: ArrayLike, c22: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`dcm_to_euler` from the five DCM entries it reads (Groves eq. 2.23).

    ``roll = atan2(C_21, C_22)``, ``pitch = -asin(C_20)``, ``yaw = atan2(C_10, C_00)``, for
    callers that hold the DCM as component arrays (no ``(..., 3, 3)`` array formed).
    """
    roll = np.arctan2(c21, c22)
    pitch = -np.arcsin(np.clip(c20, -1.0, 1.0))
    return roll, pitch, np.arctan2(c10, c00)


def dcm_to_yaw(C_b_n: ArrayLike) -> NDArray[np.float64]:
    """The yaw of :func:`dcm_to_euler` alone, ``atan2(C_10, C_00)`` [rad] in (-pi, pi]."""
    C = np.asarray(C_b_n, np.float64)
    return np.arctan2(C[..., 1, 0], C[..., 0, 0])


def orthonormalize(C: ArrayLike) -> NDArray[np.float64]:
    """One first-order re-orthonormalization step, ``C (3 I - C^T C) / 2``.

    Removes the rounding drift that long products of rotation matrices accumulate
    (Titterton & Weston 2004, §11.2.3).
    """
    C = np.asarray(C, np.float64)
    ctc = np.swapaxes(C, -1, -2) @ C
    return C @ (1.5 * np.eye(3) - 0.5 * ctc)
