"""GpsIns filter models: Carvalho et al. 1997's pseudo-range observation of the error state.

The filter state is Carvalho et al. 1997's eight-state error vector (eq. 13)::

    x = [e_lambda, e_phi, de_lambda, de_phi, a_x, a_y, b, d]

INS position errors east/north [m], their rates [m/s], horizontal accelerometer biases
[m/s^2], receiver clock bias b = c delta [m] and drift d = c d(delta)/dt [m/s] (eq. 11 scaled
by c for conditioning). Dynamics: :func:`navgym.ins.gps_ins_transition` with the known heading.
Measurements: pseudo-ranges (eq. 10 and 15) of up to ``m_max`` satellites of the real almanac
at 1 Hz; the observation predicted from the INS-indicated position corrected by the error
state (eq. 14)::

    h_i(x) = |s_i' - (p_INS - e_lambda E - e_phi N)| + Sagnac + b + T_i

with ``s_i'`` the satellite moved back by the light time, ``E``, ``N`` the local east/north unit
vectors and ``T_i`` the modelled troposphere. It is nonlinear in x, so the filter choice matters.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from filters.core.layout import is_component_major
from navgym.geo import C_LIGHT, OMEGA_E


class PseudorangeModel(NamedTuple):
    """Observation model of the error state (module docstring), batched over B episodes.

    With ``d0 = s' - p_INS`` and ``delta = e_lambda E + e_phi N`` the corrected position is
    ``p = p_INS - delta`` and, exactly,
    ``|s' - p|^2 = |d0|^2 + 2 d0 . delta + |delta|^2`` with ``|delta|^2 = e_lambda^2 + e_phi^2``
    (E, N orthonormal); the Sagnac term ``(w_e / c)(s_x p_y - s_y p_x)`` is affine in delta. So
    ``h`` needs one ``(.., 2) @ (2, m)`` product per episode, whatever the number of sigma points
    or particles, and no cancellation (``d0`` is formed once in float64).
    """

    rho0_sq: np.ndarray  # (B, m) |d0|^2
    A: np.ndarray  # (B, 2, m) rows E.d0, N.d0
    W: np.ndarray  # (B, 2, m) rows E.w, N.w with w = (w_e/c)(-s_y, s_x, 0)
    c0: np.ndarray  # (B, m) Sagnac term at p_INS plus the modelled troposphere
    R: np.ndarray  # (m, m)

    @classmethod
    def build(cls, p_ins, east, north, sat, troposphere, R) -> PseudorangeModel:
        """From the INS point ``(B, 3)``, unit vectors ``(B, 3)`` and satellites ``(B, m, 3)``."""
        d0 = [sat[..., i] - p_ins[:, i : i + 1] for i in range(3)]  # component-first (B, m)
        k = OMEGA_E / C_LIGHT
        w = (-k * sat[..., 1], k * sat[..., 0])  # w = (w_e / c)(-s_y, s_x, 0)
        A = np.empty((sat.shape[0], 2, sat.shape[1]))
        W = np.empty_like(A)
        for r, u in enumerate((east, north)):
            A[:, r] = d0[0] * u[:, 0:1] + d0[1] * u[:, 1:2] + d0[2] * u[:, 2:3]
            W[:, r] = w[0] * u[:, 0:1] + w[1] * u[:, 1:2]
        c0 = k * (sat[..., 0] * p_ins[:, None, 1] - sat[..., 1] * p_ins[:, None, 0]) + troposphere
        return cls(d0[0] * d0[0] + d0[1] * d0[1] + d0[2] * d0[2], A, W, c0, R)

    def only_rows(self, rows: np.ndarray) -> PseudorangeRows:
        """The model predicting the pseudo-ranges ``rows (k,)`` alone (0 in the other columns).

        :class:`filters.core.models.RowMaskable`: the per-row mixture update predicts one row a
        turn through it (one pseudo-range at the points instead of ``m``).
        """
        rows = np.asarray(rows)
        sub = PseudorangeModel(
            self.rho0_sq[:, rows],
            self.A[:, :, rows],
            self.W[:, :, rows],
            self.c0[:, rows],
            self.R[..., rows[:, None], rows],
        )
        return PseudorangeRows(self, sub, rows)

    def repeat_batch(self, K: int) -> PseudorangeModel:
        """Each episode's parameters repeated K times (Gaussian-sum filters stack components)."""
        return PseudorangeModel(*(np.repeat(a, K, axis=0) for a in self[:4]), self.R)

    def _flat(self, x: np.ndarray) -> np.ndarray:
        return x.reshape(x.shape[0], -1, x.shape[-1])  # (B, K, n)

    def h(self, x: np.ndarray) -> np.ndarray:
        if is_component_major(x):  # particles stored as (B, n, N): the reduced form runs along N
            rho0 = np.sqrt(self.rho0_sq)
            return ReducedPseudorangeModel(self, rho0).h(x) + rho0[:, None, :]
        flat = self._flat(x)
        e = flat[..., 0:2]
        out = e @ self.A  # in-place from here: (B, K, m) may hold millions of particles x rows
        out *= 2.0
        out += self.rho0_sq[:, None, :]
        e2 = e[..., 0] * e[..., 0]  # |e|^2 from the two columns: a reduction over an axis of
        e2 += e[..., 1] * e[..., 1]  # length 2 costs NumPy several times more
        out += e2[..., None]
        np.sqrt(out, out=out)
        out -= e @ self.W
        out += self.c0[:, None, :]
        out += flat[..., 6:7]
        return out.reshape(*x.shape[:-1], self.A.shape[-1])

    def reduced(self, z: np.ndarray) -> tuple[ReducedPseudorangeModel, np.ndarray]:
        """The same model about ``rho0 = |d0|``: ``(model of h(x) - rho0, z - rho0)``.

        "Observed minus computed" pseudo-ranges are metres, not 2e7 m, so a float32 particle
        cloud can be weighed without losing the innovation (see :class:`ReducedPseudorangeModel`).
        """
        rho0 = np.sqrt(self.rho0_sq)
        return ReducedPseudorangeModel(self, rho0), z - rho0

    def H(self, x: np.ndarray) -> np.ndarray:
        e = x[:, 0:2]  # (B, 2)
        rho = np.sqrt(
            self.rho0_sq + 2.0 * (e[:, None, :] @ self.A)[:, 0] + (e * e).sum(axis=1, keepdims=True)
        )
        J = np.zeros((x.shape[0], self.A.shape[-1], 8))
        J[..., 0:2] = np.swapaxes((self.A + e[:, :, None]) / rho[:, None, :] - self.W, -1, -2)
        J[..., 6] = 1.0
        return J

    def position(self, x: np.ndarray, p_ins: np.ndarray, east: np.ndarray, north: np.ndarray) -> np.ndarray:
        """Corrected ECEF position ``p_INS - e_lambda E - e_phi N`` for ``x (B, n)``."""
        return p_ins - x[:, 0:1] * east - x[:, 1:2] * north


class PseudorangeRows(NamedTuple):
    """A :class:`PseudorangeModel` predicting the rows ``rows`` alone, 0 in the others.

    ``h`` evaluates the rows' own model ``sub`` (their columns of ``A``, ``W``, ``rho0_sq``,
    ``c0``: the same numbers as the whole model's columns, bit for bit) into an ``(..., m)``
    array, so a filter's products over the rows round as the whole model's do; ``R`` and ``H``
    are the whole model's. From :meth:`PseudorangeModel.only_rows`.
    """

    whole: PseudorangeModel
    sub: PseudorangeModel
    rows: np.ndarray

    @property
    def R(self) -> np.ndarray:
        return self.whole.R

    def h(self, x: np.ndarray) -> np.ndarray:
        out = np.zeros((*x.shape[:-1], self.whole.A.shape[-1]))
        out[..., self.rows] = self.sub.h(x)
        return out

    def H(self, x: np.ndarray) -> np.ndarray:
        return self.whole.H(x)


class ReducedPseudorangeModel(NamedTuple):
    """``h(x) - rho0`` of a :class:`PseudorangeModel`, cancellation-free for float32 particles.

    With ``q = 2 d0 . delta + |delta|^2`` (``delta`` as in :class:`PseudorangeModel`),
    ``|s' - p| - |d0| = q / (|s' - p| + |d0|)`` exactly; ``q`` is dominated by ``2 d0 . delta``
    (no cancellation), so every factor keeps the particles' relative precision (float32: about
    1e-4 m for errors of a kilometre against the 5 m pseudo-range noise). Particles stored as a
    ``(B, n, N)`` buffer are evaluated along N.
    """

    base: PseudorangeModel
    rho0: np.ndarray  # (B, m) |d0|

    @property
    def R(self) -> np.ndarray:
        return self.base.R

    def h(self, x: np.ndarray) -> np.ndarray:
        """``h(x) - rho0`` for ``x (B, N, n)``; a ``(B, n, N)`` cloud by the compiled loop.

        :func:`navgym.gps_ins.pseudorange_kernel.reduced_pseudoranges` when ``x`` is the view of a
        contiguous ``(B, n, N)`` buffer (the Resample envs' clouds), else :meth:`h_reference`.
        """
        xT = x.transpose(0, 2, 1) if x.ndim == 3 else None
        if xT is not None and xT.flags.c_contiguous and x.dtype in (np.float32, np.float64):
            from navgym.gps_ins.pseudorange_kernel import reduced_pseudoranges  # numba: on first use

            b = self.base
            return reduced_pseudoranges(xT, b.A, b.W, b.rho0_sq, self.rho0, b.c0).transpose(0, 2, 1)
        return self.h_reference(x)

    def h_reference(self, x: np.ndarray) -> np.ndarray:
        """NumPy form of :meth:`h` (any layout and leading shape ``(B, ...)``)."""
        b = self.base
        dt = x.dtype
        comp = is_component_major(x)
        xT = (
            x.transpose(0, 2, 1)
            if comp
            else np.ascontiguousarray(x.reshape(x.shape[0], -1, x.shape[-1]).transpose(0, 2, 1))
        )
        e = xT[:, 0:2]  # (B, 2, N)
        m = b.A.shape[-1]
        # one product for both linear terms: rows [2 d0 . delta ; w . delta], (B, 2m, N)
        lin = np.concatenate([2.0 * np.swapaxes(b.A, 1, 2), np.swapaxes(b.W, 1, 2)], axis=1).astype(dt) @ e
        q, sag = lin[:, :m], lin[:, m:]
        e2 = e[:, 0] * e[:, 0]
        e2 += e[:, 1] * e[:, 1]
        q += e2[:, None, :]
        r = q + b.rho0_sq.astype(dt)[:, :, None]
        np.sqrt(r, out=r)
        r += self.rho0.astype(dt)[:, :, None]
        np.divide(q, r, out=q)
        q = np.subtract(q, sag, out=r)  # contiguous (B, m, N) again
        q += b.c0.astype(dt)[:, :, None]
        q += xT[:, 6:7]
        out = q.transpose(0, 2, 1)
        return out if comp else np.ascontiguousarray(out).reshape(*x.shape[:-1], q.shape[1])
