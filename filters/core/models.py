"""Model protocols: what a filter needs to know about dynamics and measurements.

Models are duck-typed (``typing.Protocol``), not subclasses. Their functions broadcast over any
leading axes: ``x`` arrives as ``(B, n)`` (EKF family), ``(B, S, n)`` (sigma points) or
``(B, N, n)`` (particles). Parameters batched over B (e.g. satellite positions per episode) are
aligned with the first axis of ``x``; such models may define ``repeat_batch(K)`` returning the
model with each batched parameter repeated ``np.repeat(a, K, axis=0)``, which
:mod:`filters.gaussian_sum` uses to stack K components into the batch axis. A model whose
functions are element-wise in the state components may say so by inheriting the marker
:class:`ElementwiseModel` (the sigma-point kernels then skip a copy of the points).
"""

from __future__ import annotations

from abc import ABC
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from filters.core.layout import is_component_major
from filters.core.threads import matmul


@runtime_checkable
class TransitionModel(Protocol):
    """``x_k = f(x_{k-1}, u, dt) + w``, ``w ~ N(0, Q)`` (Benzerrouk 2014, eq. 16)."""

    Q: np.ndarray  # (n, n) or (B, n, n)

    def f(self, x: np.ndarray, u: np.ndarray | None, dt: float) -> np.ndarray:
        """Propagate states ``(..., n)``."""
        ...


@runtime_checkable
class ObservationModel(Protocol):
    """``z = h(x) + v``, ``v ~ N(0, R)`` (Benzerrouk 2014, eq. 16)."""

    R: np.ndarray  # (m, m) or (B, m, m)

    def h(self, x: np.ndarray) -> np.ndarray:
        """Predicted measurements ``(..., m)`` of states ``(..., n)``."""
        ...


@runtime_checkable
class RowMaskable(Protocol):
    """An observation model that can predict a subset of its measurement rows alone.

    ``only_rows(rows)`` returns a model with the same ``m`` rows, ``R`` (and ``H``, ``residual``,
    where the model has them) whose ``h`` gives ``h(x)[..., rows]`` in the columns ``rows``, bit for
    bit, and 0 in the others, without the work of the others. The measurement keeps its ``m``
    columns, so every product a filter forms over them (a sigma-point filter's ``z_hat = sum wm Z``,
    whose rounding at pseudo-ranges of 2e7 m shows at 4e-9 m) rounds the rows asked for as the
    whole model's does. For callers that mask the other rows: the sequential per-row updates of
    :mod:`filters.row_mixture` predict each row alone through it (they check the model's class,
    once per class).
    """

    def only_rows(self, rows: np.ndarray) -> ObservationModel:
        """The model predicting the rows ``rows (k,)`` (0 in the other columns)."""
        ...


class ElementwiseModel(ABC):  # noqa: B024 - a marker: no abstract method
    """Marker: the model's ``f`` and ``h`` are element-wise in the state components.

    A model inherits it to declare that each output component of ``f(x)`` and ``h(x)`` is an
    element-wise NumPy expression of the components ``x[..., i]`` built from correctly rounded
    operations only (``+ - * /``, ``sqrt``, ``abs``, ``minimum``/``maximum``, comparisons; no sum,
    norm, ``@`` or ``einsum`` over an axis of ``x``, and no ``exp``, ``log`` or trigonometric
    function of an array: NumPy may take a SIMD loop for contiguous operands and a scalar one for
    strided ones, which differ in the last bit). Such operations round the same on every memory
    layout, so the model's numbers do not depend on how the points are laid out, and the
    sigma-point kernels (:mod:`filters.sigma_point`) hand it their state-major points as a
    ``(B, S, n)`` view instead of a C-contiguous batch-first copy: each component is then one
    contiguous block (RangeTracking's UKF step at B = 1024 about half the time, with the same
    numbers bit for bit). A model that reduces over an axis must not
    inherit it: a reduction's rounding follows the strides, and a single filter would differ from
    the same filter in a batch by an ulp. A class that cannot inherit it (a ``NamedTuple``)
    declares itself by ``ElementwiseModel.register(cls)``; an observation model without ``f``
    declares its ``h`` alone (a selection of state components such as a position fix qualifies).
    """

    __slots__ = ()


class LinearizedTransition(TransitionModel, Protocol):
    """A transition model with its Jacobian (EKF family)."""

    def F(self, x: np.ndarray, u: np.ndarray | None, dt: float) -> np.ndarray:
        """Jacobian ``df/dx`` at ``x (B, n)``: ``(B, n, n)`` or ``(n, n)``."""
        ...


class LinearizedObservation(ObservationModel, Protocol):
    """An observation model with its Jacobian (EKF family)."""

    def H(self, x: np.ndarray) -> np.ndarray:
        """Jacobian ``dh/dx`` at ``x (B, n)``: ``(B, m, n)`` or ``(m, n)``."""
        ...


class LinearGaussianModel(NamedTuple):
    """``x_k = F x_{k-1} + G u + w``, ``z = H x + v`` with constant matrices.

    Satisfies both linearized protocols, so every filter accepts it.

    Attributes:
        transition_matrix: F, ``(n, n)`` or ``(B, n, n)``.
        observation_matrix: H, ``(m, n)`` or ``(B, m, n)``.
        Q: process noise covariance ``(n, n)`` or ``(B, n, n)``.
        R: measurement noise covariance ``(m, m)`` or ``(B, m, m)``.
        control_matrix: G, ``(n, p)``, or None.

    """

    transition_matrix: np.ndarray
    observation_matrix: np.ndarray
    Q: np.ndarray
    R: np.ndarray
    control_matrix: np.ndarray | None = None

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        """``F x + G u`` over leading axes (F may be batched over the first axis)."""
        Fm = self.transition_matrix
        out = _apply(Fm, x)
        if u is not None and self.control_matrix is not None:
            Gu = np.asarray(u) @ self.control_matrix.T
            out = out + (Gu if x.ndim == 2 else Gu.reshape(Gu.shape[0], *([1] * (x.ndim - 2)), -1))
        return out

    def F(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        return self.transition_matrix

    def h(self, x: np.ndarray) -> np.ndarray:
        return _apply(self.observation_matrix, x)

    def H(self, x: np.ndarray) -> np.ndarray:
        return self.observation_matrix


def _apply(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A x`` for x ``(B, ..., n)`` and A ``(r, n)`` or ``(B, r, n)``.

    Keeps a "structure of arrays" layout: for ``x (B, N, n)`` that is the transposed view of a
    C-contiguous ``(B, n, N)`` buffer (particle filters, :mod:`filters.particle.bootstrap`) the
    product is formed as ``A @ x^T`` and returned as the same kind of view. float32 ``x`` gives
    a float32 product.
    """
    if x.dtype == np.float32:
        A = A.astype(np.float32)  # keep float32 particles in float32 (A is small)
    if is_component_major(x):
        return matmul(A, x.transpose(0, 2, 1)).transpose(0, 2, 1)
    if A.ndim == 2:
        return x @ A.T
    flat = x.reshape(x.shape[0], -1, x.shape[-1])
    out = flat @ np.swapaxes(A, -1, -2)
    return out.reshape(*x.shape[:-1], A.shape[-2])


class LinearTransition(NamedTuple):
    """``x_k = F x_{k-1} + w`` with ``F`` shared ``(n, n)`` or per filter ``(B, n, n)``.

    A transition model for the whole family (``f``, Jacobian ``F``, ``Q``); ``f`` broadcasts
    over sigma points and particles ``(B, ..., n)``.
    """

    transition_matrix: np.ndarray
    Q: np.ndarray

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        return _apply(self.transition_matrix, x)

    def F(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        return self.transition_matrix


def innovation(model: object, z: np.ndarray, z_hat: np.ndarray) -> np.ndarray:
    """``v = z - z_hat``, or the model's own ``residual(z, z_hat)`` when it has one.

    A model whose measurements live on a circle (a compass heading) defines ``residual`` to wrap
    the difference; every filter takes its innovations through this one function.
    """
    # an attribute lookup, not isinstance against a runtime-checkable Protocol: this runs in every
    # update, and the Protocol check costs far more (docs/performance.md, "Figures behind the code")
    residual = getattr(model, "residual", None)
    return z - z_hat if residual is None else residual(z, z_hat)
