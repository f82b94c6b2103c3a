"""Robot2d filter models: Benzerrouk 2014's car-like robot (eq. 77), encoder, compass, GPS, GLONASS.

Benzerrouk 2014 (§2.7b-c) fuses GPS (10 Hz), GLONASS (5 Hz) and an electronic compass (5 Hz) with
a wheel encoder on a car-like robot whose point L moves by eq. 77 (see
:mod:`navgym.robot2d.robot`). The encoder formula is the rear-right wheel in these axes (x north,
y east, clockwise heading); Benzerrouk 2014's "back left wheel" names it in Guivant & Nebot's
mirrored frame. The filter state is::

    x = [x_N, y_E, phi]

north/east position of point L [m] and heading from north [rad] (unwrapped). Prediction over
one step ``dt = 0.1`` s is the exact discrete eq. 77 (circular arc,
:func:`navgym.robot2d.robot.robot_transition`) with the measured encoder speed and steering
angle held as control::

    v_c = v_e / (1 - H tan(alpha) / L),   w = v_c tan(alpha) / L,   x+ = eq. 77 arc

The truth has what the filter does not model: the encoder's scale error ``s`` (wheel radius,
the first extension Benzerrouk 2014 names after eq. 77; ``v_e = (1 + s) v_true + noise``, ``s``
drawn per episode) and commands that change inside a step. An encoder-scale state was left out on
purpose: under a sustained fading factor it is unobservable within the filter's short memory
and runs away; the unmodelled scale is the model error that fading factors exist for.

Measurements at each step (``m_max = 5`` rows, a mask says which are present)::

    z = [gps_N, gps_E, glonass_N, glonass_E, compass] = [x_N, y_E, x_N, y_E, phi] + v

GPS every step (10 Hz), GLONASS and compass every other step (5 Hz); GNSS rows are further
masked by the episode's scenario (outages, jamming losses). The compass is unwrapped along its
own delivered readings (a 5 Hz heading changes far less than pi between readings), so every
filter, the particle filter included, sees a continuous heading; the Gaussian filters also
wrap the compass residual (:meth:`FixCompassModel.residual`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from filters.core.compiled import compiled_enabled
from filters.core.layout import is_component_major
from filters.core.models import ElementwiseModel
from filters.core.threads import over_rows
from navgym.ins.attitude import wrap_angle
from navgym.robot2d.odometry_kernels import cloud_transition_pass, jacobian_pass, transition_pass
from navgym.robot2d.robot import (
    RobotGeometry,
)


def _dsinc(th: np.ndarray) -> np.ndarray:
    """Derivative of ``sin(th) / th`` (series below 1e-3, where the quotient cancels)."""
    small = np.abs(th) < 1e-3
    safe = np.where(small, 1.0, th)
    exact = (safe * np.cos(safe) - np.sin(safe)) / (safe * safe)
    return np.where(small, -th / 3.0 + th**3 / 30.0, exact)


def _offset_rate(phi: np.ndarray, g: RobotGeometry) -> np.ndarray:
    """``d offset(phi) / d phi`` of the point L relative to the rear-axle centre, ``(..., 2)``."""
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([-g.a * s - g.b * c, g.a * c - g.b * s], axis=-1)


class OdometryTransition(NamedTuple):
    """Eq. 77 driven by the measured encoder speed and steering, batched over B episodes.

    ``f`` broadcasts over ``(B, n)``, sigma points ``(B, S, n)`` and particles ``(B, N, n)``;
    the controls ``(B,)`` are aligned with axis 0.
    """

    v_c: np.ndarray  # (B,) rear-axle speed from the encoder, v_e / kappa [m/s]
    tan_alpha: np.ndarray  # (B,) tan of the measured steering angle
    Q: np.ndarray  # (B, 3, 3)
    geometry: RobotGeometry

    def repeat_batch(self, K: int) -> OdometryTransition:
        """Each episode's parameters repeated K times (Gaussian-sum filters stack components)."""
        return OdometryTransition(*(np.repeat(a, K, axis=0) for a in self[:3]), self.geometry)

    def _controls(self, k: int) -> np.ndarray:
        """``v_c`` (k = 0) or ``tan(alpha)`` (k = 1) as a contiguous float64 ``(B,)`` array."""
        return np.ascontiguousarray(self[k], dtype=np.float64)

    def _half_turn(self, dt: float) -> np.ndarray:
        """``th = w dt / 2`` with ``w = v_c tan(alpha) / L``, ``(B,)``."""
        return 0.5 * dt * self.v_c * self.tan_alpha / self.geometry.wheelbase

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 0.1) -> np.ndarray:
        """Exact discrete eq. 77 over one step (Benzerrouk 2014; arc form of ``robot_transition``).

        ``phi+ = phi + w dt``, ``c+ = c + v_c dt sinc(w dt / 2) [cos, sin](phi + w dt / 2)`` for the
        rear-axle centre ``c = p - offset(phi)``, ``p+ = c+ + offset(phi+)``. With ``offset(phi) =
        R(phi) [a, b]`` and ``th = w dt / 2`` the position step is ``R(phi) [d cos th - 2 a sin^2 th
        - 2 b sin th cos th, d sin th + 2 a sin th cos th - 2 b sin^2 th]``, ``d = v_c dt
        sinc(th)``: the body-frame step is the same for every state of an episode, so sigma points
        and particles cost two trigonometric calls each. ``u`` is ignored (controls are held in
        the model).
        """
        g = self.geometry
        B = x.shape[0]
        if x.ndim == 2 and compiled_enabled():  # one state per episode: the compiled twin
            out2 = np.empty((B, 3))
            transition_pass(
                np.ascontiguousarray(x, np.float64), self._controls(0), self._controls(1), dt,
                g.wheelbase, g.a, g.b, out2,
            )  # fmt: skip
            return out2
        th = self._half_turn(dt)
        sn, cs = np.sin(th), np.cos(th)
        d = self.v_c * dt * np.sinc(th / np.pi)
        s2, sc2 = 2.0 * sn * sn, 2.0 * sn * cs
        bx = d * cs - g.a * s2 - g.b * sc2
        by = d * sn + g.a * sc2 - g.b * s2
        if is_component_major(x) and x.dtype in (np.float32, np.float64) and compiled_enabled():
            xT = x.transpose(0, 2, 1)  # a particle cloud (B, 3, N), C-contiguous
            outT = np.empty_like(xT)
            bx, by = np.ascontiguousarray(bx, np.float64), np.ascontiguousarray(by, np.float64)
            turn = np.ascontiguousarray(2.0 * th, np.float64)

            def episodes(a: int, b: int) -> None:  # each episode's cloud from its own row alone
                phi = xT[a:b, 2]
                c0, s0 = np.cos(phi), np.sin(phi)
                cloud_transition_pass(xT[a:b], c0, s0, bx[a:b], by[a:b], turn[a:b], outT[a:b])

            over_rows(B, xT.shape[1] * xT.shape[2], episodes)
            return outT.transpose(0, 2, 1)
        flat = x.reshape(B, -1, x.shape[-1])
        bx, by = bx[:, None], by[:, None]
        phi = flat[..., 2]
        c0, s0 = np.cos(phi), np.sin(phi)
        out = np.empty_like(flat)
        out[..., 0] = flat[..., 0] + c0 * bx - s0 * by
        out[..., 1] = flat[..., 1] + s0 * bx + c0 * by
        out[..., 2] = phi + 2.0 * th[:, None]
        return out.reshape(x.shape)

    def F(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 0.1) -> np.ndarray:
        """Jacobian ``df/dx (B, 3, 3)`` of :meth:`f` at ``x (B, 3)`` (Benzerrouk 2014, eq. 77).

        ``dp+/dphi = d [-sin, cos](phi + th) + offset'(phi + 2 th) - offset'(phi)``; the rest is
        the identity.
        """
        g = self.geometry
        if compiled_enabled():  # the compiled twin (:mod:`navgym.robot2d.odometry_kernels`)
            J0 = np.empty((x.shape[0], 3, 3))
            jacobian_pass(
                np.ascontiguousarray(x, np.float64), self._controls(0), self._controls(1), dt,
                g.wheelbase, g.a, g.b, J0,
            )  # fmt: skip
            return J0
        th = self._half_turn(dt)
        phi = x[:, 2]
        d = self.v_c * dt * np.sinc(th / np.pi)
        mid = phi + th
        J = np.zeros((x.shape[0], 3, 3))
        J[:, 0, 0] = J[:, 1, 1] = J[:, 2, 2] = 1.0
        J[:, :2, 2] = (
            d[:, None] * np.stack([-np.sin(mid), np.cos(mid)], axis=-1)
            + _offset_rate(phi + 2.0 * th, g)
            - _offset_rate(phi, g)
        )
        return J


def control_jacobian(
    phi: np.ndarray, v_e: np.ndarray, alpha: np.ndarray, dt: float, geometry: RobotGeometry
) -> np.ndarray:
    """``df/d(v_e, alpha) (B, 3, 2)`` of eq. 77's arc (maps control noise into Q).

    Chain rule through ``v_c = v_e / kappa``, ``kappa = 1 - H tan(alpha) / L``, ``w = v_c
    tan(alpha) / L`` and the arc's ``dp+/dv_c = dt sinc(th) [cos, sin](phi + th)``, ``dp+/dw =
    v_c dt^2 / 2 sinc'(th) [cos, sin](phi + th) + d dt / 2 [-sin, cos](phi + th) + dt
    offset'(phi + 2 th)``, ``dphi+/dw = dt``.
    """
    g = geometry
    t = np.tan(alpha)
    sec2 = 1.0 + t * t
    kappa = 1.0 - g.encoder_offset * t / g.wheelbase
    v = v_e / kappa
    w = v * t / g.wheelbase
    th = 0.5 * w * dt
    sc = np.sinc(th / np.pi)
    d = v * dt * sc
    mid = phi + th
    along = np.stack([np.cos(mid), np.sin(mid)], axis=-1)
    normal = np.stack([-np.sin(mid), np.cos(mid)], axis=-1)
    dp_dv = (dt * sc)[:, None] * along
    dp_dw = (
        (v * dt * dt / 2.0 * _dsinc(th))[:, None] * along
        + (d * dt / 2.0)[:, None] * normal
        + dt * _offset_rate(phi + 2.0 * th, g)
    )
    dv = np.stack([1.0 / kappa, v * g.encoder_offset * sec2 / (g.wheelbase * kappa)], axis=-1)
    dw = t[:, None] / g.wheelbase * dv
    dw[:, 1] += v * sec2 / g.wheelbase
    G = np.zeros((phi.shape[0], 3, 2))
    G[:, :2, :] = dp_dv[:, :, None] * dv[:, None, :] + dp_dw[:, :, None] * dw[:, None, :]
    G[:, 2, :] = dt * dw
    return G


class FixCompassModel(NamedTuple):
    """``h(x) = [x_N, y_E, x_N, y_E, phi]``: GPS fix, GLONASS fix, compass (Benzerrouk 2014, §2.7c).

    Linear with constant ``H (5, 3)``; the compass residual is wrapped to ``[-pi, pi)``.
    """

    R: np.ndarray  # (5, 5)

    def repeat_batch(self, K: int) -> FixCompassModel:
        """No parameter is batched: the same model serves the stacked ``(B*K)`` batch."""
        return self

    def h(self, x: np.ndarray) -> np.ndarray:
        """``x[..., [0, 1, 0, 1, 2]]``; a component-major particle cloud gets a component-major copy.

        The same values; the cloud's layout (a ``(B, 5, N)`` buffer seen as ``(B, N, 5)``) is
        what the compiled weighing reads (:mod:`filters.particle.kernels`), which otherwise
        transposes a C-ordered copy. The NumPy path keeps the C-ordered copy (its reductions
        round by layout).
        """
        if compiled_enabled() and is_component_major(x):
            return np.take(x.transpose(0, 2, 1), _FIX_COMPASS_ROWS, axis=1).transpose(0, 2, 1)
        return x[..., _FIX_COMPASS_ROWS]

    def H(self, x: np.ndarray) -> np.ndarray:
        return _H

    def residual(self, z: np.ndarray, z_hat: np.ndarray) -> np.ndarray:
        """``z - z_hat`` with the compass row wrapped to ``[-pi, pi)``."""
        v = np.asarray(z, dtype=np.float64) - z_hat
        v[..., 4] = wrap_angle(v[..., 4])
        return v


# h selects state components: the sigma-point kernels may hand it their points without a copy
ElementwiseModel.register(FixCompassModel)

_FIX_COMPASS_ROWS = np.array([0, 1, 0, 1, 2])
_H = np.array([[1.0, 0, 0], [0, 1.0, 0], [1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0]], dtype=np.float64)
_H.setflags(write=False)
