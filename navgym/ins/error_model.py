"""The two-axis INS error model of Carvalho et al. 1997 (eq. 12-14) with the receiver clock of eq. 11.

State (Carvalho et al. 1997, §IV-D-1), ``e = [e_lambda, e_phi, de_lambda, de_phi, a_x, a_y]``: INS position
errors in longitude and latitude, their rates, and the biases of the two horizontal
accelerometers (X along the known heading Theta, Y completing the frame). Continuous model,
Carvalho et al. 1997, eq. 12::

    d e_lambda  = de_lambda dt
    d e_phi     = de_phi dt
    d de_lambda = (-K de_lambda - cos(Theta) a_x - sin(Theta) a_y) dt
    d de_phi    = (-K de_phi    - sin(Theta) a_x + cos(Theta) a_y) dt
    d a_x = sigma_x dw_x,   d a_y = sigma_y dw_y          (random-walk biases)

and its discrete form (Euler step, eq. 13)::

    e_{k+1} = F_k e_k + G w_k,  F_k = I + A(Theta_k) dt,  G w_k = [0 0 0 0 sigma_x sqrt(dt) w_x,
                                                                    sigma_y sqrt(dt) w_y]

**Units.** The paper does not fix them and its bias terms enter the position-error rates
directly, so the position errors are expressed here as metres along the parallel
(``e_lambda``, eastward) and the meridian (``e_phi``, northward), rates in m/s, biases in m/s^2.
:func:`position_error_to_radians` converts to the angular errors of eq. 14; the bias projection
matrix ``[[-cos, -sin], [-sin, cos]]`` is taken exactly as printed in eq. 12-13 (it is a
reflection, not a rotation, which leaves the error statistics unchanged).

Carvalho et al. 1997, §IV-D: biases "modeled as random walks, limited to 10 ug"; the velocity feedback gain K
is not given. Defaults (:class:`InsErrorParams`): K = 1e-3 1/s, the 10 ug limit enforced by
reflecting the walk, the walk sigma chosen so that its spread after 3600 s is half the limit.

Receiver clock (Carvalho et al. 1997, eq. 11 and the last two rows of eq. 13): the drift rate ``x`` is an
exponentially correlated process ``dx/dt = -a x + w`` and the clock bias ``delta`` its
integral; with ``a = 1/500`` 1/s and ``sigma_w = 1e-12``. Bias in seconds, drift in s/s.
The printed eq. 13 has a spurious ninth column; the 8x8 matrices here are its intended content.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from navgym.geo import meridian_radius, normal_radius
from navgym.ins.imu_grades import G0
from navgym.scenarios.seeding import standard_normal_batch
from navgym.scenarios.validation import check_nonnegative, check_positive

__all__ = [
    "InsErrorParams",
    "CLOCK_A",
    "CLOCK_SIGMA_W",
    "ins_error_transition",
    "ins_error_process_noise",
    "receiver_clock_transition",
    "receiver_clock_process_noise",
    "gps_ins_transition",
    "gps_ins_process_noise",
    "ins_error_initial_covariance",
    "simulate_ins_errors",
    "position_error_to_radians",
    "ins_indicated_position",
]

#: Inverse correlation time a of the clock drift [1/s] (Carvalho et al. 1997, eq. 11).
CLOCK_A = 1.0 / 500.0
#: Clock drift driving-noise sigma_w (Carvalho et al. 1997, eq. 11).
CLOCK_SIGMA_W = 1e-12

_BIAS_LIMIT = 10e-6 * G0


@dataclass(frozen=True)
class InsErrorParams:
    """Parameters of the two-axis INS error model (Carvalho et al. 1997, eq. 12-13).

    Attributes:
        K: Velocity feedback (damping) gain [1/s] (not given in Carvalho et al. 1997).
        sigma_x: Random-walk density of the X accelerometer bias [m/s^2/sqrt(s)].
        sigma_y: Same for Y.
        bias_limit: Magnitude limit of each bias [m/s^2] (Carvalho et al. 1997: 10 ug); ``inf`` disables it.
        sigma_position0: Initial position-error sigma per axis [m].
        sigma_velocity0: Initial velocity-error sigma per axis [m/s].
        sigma_bias0: Initial bias sigma per axis [m/s^2].

    """

    K: float = 1e-3
    sigma_x: float = _BIAS_LIMIT / (2.0 * 60.0)
    sigma_y: float = _BIAS_LIMIT / (2.0 * 60.0)
    bias_limit: float = _BIAS_LIMIT
    sigma_position0: float = 10.0
    sigma_velocity0: float = 0.05
    sigma_bias0: float = _BIAS_LIMIT / 2.0

    def __post_init__(self) -> None:
        check_nonnegative("K", self.K)
        check_nonnegative("sigma_x", self.sigma_x)
        check_nonnegative("sigma_y", self.sigma_y)
        if not self.bias_limit > 0:  # +inf disables the limit; NaN is rejected
            raise ValueError(f"bias_limit must be > 0, got {self.bias_limit!r}")
        check_nonnegative("sigma_position0", self.sigma_position0)
        check_nonnegative("sigma_velocity0", self.sigma_velocity0)
        check_nonnegative("sigma_bias0", self.sigma_bias0)


def _heading(heading: ArrayLike) -> NDArray[np.float64]:
    th = np.asarray(heading, np.float64)
    if not np.all(np.isfinite(th)):
        raise ValueError("heading must be finite")
    return th


def ins_error_transition(heading: ArrayLike, dt: float, K: float = 1e-3) -> NDArray[np.float64]:
    """Six-state transition matrix F_k of Carvalho et al. 1997, eq. 13 (rows/columns 1-6).

    ``F = I + A(Theta) dt`` with A of eq. 12.

    Args:
        heading: Heading Theta_k [rad] from north, any shape ``(...)`` (e.g. ``(B,)``).
        dt: Step [s].
        K: Velocity damping gain [1/s].

    Returns:
        F of shape ``heading.shape + (6, 6)``.

    """
    dt = check_positive("dt", dt)
    return _with_heading(_ins_error_constant(dt, check_nonnegative("K", K)), _heading(heading), dt)


def _ins_error_constant(dt: float, K: float) -> NDArray[np.float64]:
    """The heading-free entries of eq. 13's F (6 x 6; the bias-to-velocity block left 0)."""
    F = np.eye(6)
    F[0, 2] = F[1, 3] = dt
    F[2, 2] = F[3, 3] = 1.0 - K * dt
    return F


def _with_heading(const: NDArray[np.float64], th: NDArray[np.float64], dt: float) -> NDArray[np.float64]:
    """``const`` copied to every heading, with the bias-to-velocity block of eq. 13 filled in.

    ``F[2:4, 4:6] = -dt [[cos, sin], [sin, -cos]](Theta)`` (accelerometer biases resolved by the
    known heading, eq. 12); one broadcast copy instead of per-entry fancy indexing.
    """
    F = np.empty(th.shape + const.shape)
    F[...] = const
    c, s = np.cos(th), np.sin(th)
    F[..., 2, 4] = -dt * c
    F[..., 2, 5] = -dt * s
    F[..., 3, 4] = -dt * s
    F[..., 3, 5] = dt * c
    return F


def ins_error_process_noise(dt: float, sigma_x: float, sigma_y: float) -> NDArray[np.float64]:
    """Six-state process noise Q = G G^T of Carvalho et al. 1997, eq. 13: ``diag(0,0,0,0,sx^2 dt, sy^2 dt)``.

    Args:
        dt: Step [s].
        sigma_x: X bias random-walk density [m/s^2/sqrt(s)].
        sigma_y: Y bias random-walk density.

    Returns:
        Q of shape ``(6, 6)``.

    """
    dt = check_positive("dt", dt)
    Q = np.zeros((6, 6))
    Q[4, 4] = check_nonnegative("sigma_x", sigma_x) ** 2 * dt
    Q[5, 5] = check_nonnegative("sigma_y", sigma_y) ** 2 * dt
    return Q


def receiver_clock_transition(dt: float, a: float = CLOCK_A) -> NDArray[np.float64]:
    """Clock bias/drift transition ``[[1, dt], [0, 1 - a dt]]`` (Carvalho et al. 1997, eq. 13, last rows).

    This is the paper's Euler step; :func:`navgym.gnss.clock_transition` gives the exact
    discretization of eq. 11 that the GNSS simulator uses (``exact=True`` below).

    Args:
        dt: Step [s].
        a: Inverse correlation time of the drift [1/s] (eq. 11: 1/500).

    Returns:
        Matrix of shape ``(2, 2)``.

    """
    dt = check_positive("dt", dt)
    a = check_nonnegative("a", a)
    return np.array([[1.0, dt], [0.0, 1.0 - a * dt]])


def receiver_clock_process_noise(dt: float, sigma_w: float = CLOCK_SIGMA_W) -> NDArray[np.float64]:
    """Clock process noise of Carvalho et al. 1997, eq. 13: ``diag(0, sigma_w^2 dt)`` [s^2, (s/s)^2].

    Args:
        dt: Step [s].
        sigma_w: Drift driving-noise density (eq. 11: 1e-12).

    Returns:
        Matrix of shape ``(2, 2)``.

    """
    dt = check_positive("dt", dt)
    return np.diag([0.0, check_nonnegative("sigma_w", sigma_w) ** 2 * dt])


def gps_ins_transition(
    heading: ArrayLike, dt: float, K: float = 1e-3, a: float = CLOCK_A, *, exact: bool = False
) -> NDArray[np.float64]:
    """Eight-state transition of Carvalho et al. 1997, eq. 13: INS errors (6) and clock bias, drift (2).

    State order ``[e_lambda, e_phi, de_lambda, de_phi, a_x, a_y, delta, ddelta]``.

    Args:
        heading: Heading Theta_k [rad], shape ``(...)``.
        dt: Step [s].
        K: Velocity damping gain [1/s].
        a: Clock drift inverse correlation time [1/s].
        exact: Clock block from the exact discretization of eq. 11
            (:func:`navgym.gnss.clock_transition`, what the GNSS simulator uses) instead of
            eq. 13's Euler step.

    Returns:
        F of shape ``heading.shape + (8, 8)``.

    """
    dt = check_positive("dt", dt)
    return _with_heading(
        _gps_ins_constant(dt, check_nonnegative("K", K), float(a), bool(exact)), _heading(heading), dt
    )


@lru_cache(maxsize=16)
def _gps_ins_constant(dt: float, K: float, a: float, exact: bool) -> NDArray[np.float64]:
    """The heading-free entries of :func:`gps_ins_transition`'s F, formed once per parameters.

    Read-only (shared by every call: the GpsIns platforms ask for it every step).
    """
    const = np.zeros((8, 8))
    const[:6, :6] = _ins_error_constant(dt, K)
    const[6:, 6:] = _clock_blocks(dt, a, CLOCK_SIGMA_W)[0] if exact else receiver_clock_transition(dt, a)
    const.flags.writeable = False
    return const


def _clock_blocks(dt: float, a: float, sigma_w: float) -> tuple[NDArray, NDArray]:
    from navgym.gnss.clock import clock_transition  # the simulator's exact eq. 11

    check_positive("dt", dt)
    check_positive("a", a)
    return clock_transition(dt, a, check_nonnegative("sigma_w", sigma_w))


def gps_ins_process_noise(
    dt: float,
    sigma_x: float = InsErrorParams.sigma_x,
    sigma_y: float = InsErrorParams.sigma_y,
    sigma_w: float = CLOCK_SIGMA_W,
    *,
    a: float = CLOCK_A,
    exact: bool = False,
) -> NDArray[np.float64]:
    """Eight-state process noise of Carvalho et al. 1997, eq. 13 (block diagonal of the two parts).

    Args:
        dt: Step [s].
        sigma_x: X bias random-walk density.
        sigma_y: Y bias random-walk density.
        sigma_w: Clock drift driving-noise density.
        a: Clock drift inverse correlation time [1/s] (used with ``exact``).
        exact: Clock block from the exact discretization of eq. 11 (see
            :func:`gps_ins_transition`).

    Returns:
        Q of shape ``(8, 8)``.

    """
    Q = np.zeros((8, 8))
    Q[:6, :6] = ins_error_process_noise(dt, sigma_x, sigma_y)
    Q[6:, 6:] = _clock_blocks(dt, a, sigma_w)[1] if exact else receiver_clock_process_noise(dt, sigma_w)
    return Q


def ins_error_initial_covariance(params: InsErrorParams) -> NDArray[np.float64]:
    """Initial covariance ``diag(sp^2, sp^2, sv^2, sv^2, sb^2, sb^2)`` of the six error states."""
    return np.diag(
        [params.sigma_position0**2] * 2 + [params.sigma_velocity0**2] * 2 + [params.sigma_bias0**2] * 2
    )


def _reflect(x: NDArray[np.float64], limit: float | NDArray[np.float64]) -> NDArray[np.float64]:
    """Fold a path into [-limit, limit] by reflection at the bounds (a reflected random walk)."""
    if np.ndim(limit) == 0 and not np.isfinite(limit):
        return x
    y = np.mod(x + limit, 4.0 * limit)
    return limit - np.abs(y - 2.0 * limit)


def simulate_ins_errors(
    heading: ArrayLike,
    dt: float,
    params: InsErrorParams,
    rngs: Sequence[np.random.Generator],
    bias_limit: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Simulate INS error trajectories of Carvalho et al. 1997, eq. 13, vectorized over batch and time.

    Per episode the generator draws 6 normals for the initial state ``e_0 ~ N(0, P0)`` and then
    ``(T - 1, 2)`` normals for the bias walk. The biases are reflected at ``+-bias_limit``
    (Carvalho et al. 1997: "random walks, limited to 10 ug"). The recursion ``de_{k+1} = (1 - K dt) de_k +
    dt M(Theta_k) a_k`` runs as a first-order IIR filter along time, positions are cumulative
    sums: the result equals stepping eq. 13 with :func:`ins_error_transition`.

    Args:
        heading: Known heading Theta_k [rad] at each step, shape ``(B, T)``.
        dt: Step [s].
        params: Model parameters.
        rngs: One generator per episode.
        bias_limit: Optional per-episode bias limits ``(B,)`` [m/s^2] (an IMU of another grade
            than ``params`` describes, same model): episode b uses ``bias_limit[b]`` and scales
            the walk densities and the initial bias sigma by ``k = bias_limit[b] /
            params.bias_limit``; the initial position and velocity sigmas are kept. Equal, value
            for value, to one call per episode with those parameters.

    Returns:
        Errors of shape ``(B, T, 6)``, index k at time ``k dt``.

    Raises:
        ValueError: If ``heading`` is not ``(B, T)`` or ``rngs`` has the wrong length.

    """
    dt = check_positive("dt", dt)
    th = _heading(heading)
    if th.ndim != 2:
        raise ValueError(f"heading must have shape (B, T), got {th.shape}")
    b, n = th.shape
    if len(rngs) != b:
        raise ValueError(f"rngs must hold {b} generators, got {len(rngs)}")
    z0 = standard_normal_batch(rngs, (6,))
    zw = standard_normal_batch(rngs, (max(n - 1, 0), 2))
    if bias_limit is None:
        e0 = z0 * np.sqrt(np.diag(ins_error_initial_covariance(params)))
        inc = zw * (np.array([params.sigma_x, params.sigma_y]) * np.sqrt(dt))
        limit = params.bias_limit
    else:
        limit = np.asarray(bias_limit, np.float64).reshape(-1)
        if limit.shape != (b,) or not (np.isfinite(limit).all() and (limit > 0).all()):
            raise ValueError(f"bias_limit must hold {b} finite positive values; got shape {limit.shape}")
        k = limit / params.bias_limit
        sb = params.sigma_bias0 * k
        sd0 = np.empty((b, 6))
        sd0[:, 0:2] = params.sigma_position0**2
        sd0[:, 2:4] = params.sigma_velocity0**2
        sd0[:, 4:6] = (sb**2)[:, None]
        e0 = z0 * np.sqrt(sd0)
        sig = np.stack([params.sigma_x * k, params.sigma_y * k], axis=-1)  # (B, 2)
        inc = zw * (sig * np.sqrt(dt))[:, None, :]
        limit = limit[:, None, None]
    bias = np.concatenate([e0[:, None, 4:6], e0[:, None, 4:6] + np.cumsum(inc, axis=1)], axis=1)
    bias = _reflect(bias, limit)

    c, s = np.cos(th), np.sin(th)
    u = np.stack([-c * bias[..., 0] - s * bias[..., 1], -s * bias[..., 0] + c * bias[..., 1]], axis=-1)
    x = np.empty((b, n, 2))
    x[:, 0] = e0[:, 2:4]
    x[:, 1:] = dt * u[:, :-1]
    vel = lfilter([1.0], [1.0, -(1.0 - params.K * dt)], x, axis=1)
    pos = np.empty((b, n, 2))
    pos[:, 0] = e0[:, 0:2]
    pos[:, 1:] = e0[:, None, 0:2] + dt * np.cumsum(vel[:, :-1], axis=1)
    return np.concatenate([pos, vel, bias], axis=-1)


def position_error_to_radians(
    errors_m: ArrayLike, lat: ArrayLike, h: ArrayLike = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Convert (east, north) position errors in metres to (longitude, latitude) errors [rad].

    ``e_lambda = e_E / ((R_N + h) cos lat)``, ``e_phi = e_N / (R_M + h)`` (Groves eq. 2.119).

    Args:
        errors_m: Errors whose last axis starts with ``[e_lambda, e_phi]`` in metres.
        lat: Latitude [rad], broadcastable with ``errors_m[..., 0]``.
        h: Height [m].

    Returns:
        ``(e_lambda, e_phi)`` in radians.

    """
    e = np.asarray(errors_m, np.float64)
    lat = np.asarray(lat, np.float64)
    e_lon = e[..., 0] / ((normal_radius(lat) + h) * np.cos(lat))
    e_lat = e[..., 1] / (meridian_radius(lat) + h)
    return e_lon, e_lat


def ins_indicated_position(
    lat: ArrayLike, lon: ArrayLike, errors_m: ArrayLike, h: ArrayLike = 0.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """INS-indicated coordinates of Carvalho et al. 1997, eq. 14.

    ``lambda_I = lambda_m + e_lambda`` and ``phi_I = phi_m + e_phi``.

    Args:
        lat: True latitude phi_m [rad], shape ``(...)``.
        lon: True longitude lambda_m [rad].
        errors_m: INS errors from :func:`simulate_ins_errors`, shape ``(..., 6)`` (or ``(..., 2)``).
        h: Height [m].

    Returns:
        ``(lat_I, lon_I)`` [rad].

    """
    e_lon, e_lat = position_error_to_radians(errors_m, lat, h)
    return np.asarray(lat, np.float64) + e_lat, np.asarray(lon, np.float64) + e_lon
