"""GNSS joint position and attitude (JPA) of Belles et al. 2022: state, double differences, simulation.

State (Belles et al. 2022, eq. 4-5, ambiguities real-valued): attitude ``R`` (body to the local East-North-Up
frame of the base station, kept as a nominal rotation matrix per filter), float double-difference
ambiguities ``a`` [cycles], position ``p`` [m] and velocity ``v`` [m/s] of the master antenna
relative to the base station, gyroscope bias ``b`` [rad/s]. The filters work on the vector::

    x = [dpsi (3), a (M), p (3), v (3), b (3)],   R = R_nom Exp(dpsi)      (eq. 6-7)

with ``dpsi`` the attitude error in the tangent space (zero after each reset, when it is moved
into ``R_nom``: the error-state KF of eq. 13). ``M = n (N + 1)`` for ``n + 1`` satellites and
``N`` slave antennas.

Process (eq. 9-10): ``R+ = R Exp((w_m - b) dt)``, ``p+ = p + dt v``, ``a``, ``v``, ``b`` random
walks; the error transition is ``dpsi+ = Omega^T dpsi - dt db`` with ``Omega = Exp((w_m - b) dt)``.

Observations (eq. 11-12), short-baseline double differences (DD) against the highest
satellite, with ``u_i = e_i - e_ref`` the difference of the unit lines of sight::

    Phi_bm,i = -u_i^T p + lambda a_i          rho_bm,i = -u_i^T p
    Phi_jm,i = -u_i^T R b_j + lambda a_ji     rho_jm,i = -u_i^T R b_j

in the order ``[Phi_bm, rho_bm, Phi_1m .. Phi_Nm, rho_1m .. rho_Nm]`` (eq. 11a, 12a). Their
covariance is the double-differencing operator ``D`` applied to independent undifferenced
noises of elevation-dependent standard deviation ``sigma_zenith / sin(el)`` (Belles et al. 2022, §5 cites
Euler & Goad 1991 without giving the function; ``1 / sin(el)`` is the usual zenith-referenced
form), so ``Sigma = D diag(sigma^2) D^T`` is full: the DDs share the reference satellite and
the master antenna. The simulation draws the undifferenced noises and differences them, so the
observations have exactly this covariance.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from navgym import geo, gnss
from navgym.ins.attitude import rotation_matrix, skew

#: GPS L1 carrier wavelength [m].
WAVELENGTH_L1 = 299_792_458.0 / 1575.42e6
DEG = np.pi / 180.0


@dataclass(frozen=True)
class JpaConfig:
    """Belles et al. 2022, §5 and Table 1 (our reading where the source is silent, see the README)."""

    n_satellites: int = 10
    baselines: tuple[tuple[float, float, float], ...] = (
        (1.0, 0.0, 0.0),
        (0.0, 1.0, 0.0),
        (-0.7071067811865476, -0.7071067811865476, 0.0),
    )  # body frame [m]: 3 slaves 1 m from the master (geometry not given in Belles et al. 2022)
    dt: float = 1.0
    duration: float = 1000.0
    start_distance: float = 5000.0  # from the base station [m]
    # Table 1, initial standard deviations
    sigma0_position: float = 10.0
    sigma0_velocity: tuple[float, float, float] = (2.0, 2.0, 2e-3)
    sigma0_attitude: float = 10.0 * DEG
    sigma0_bias: float = 2e-3 * DEG  # rad/s
    sigma0_ambiguity: float = 4.0  # cycles
    # Table 1, process noise (per sqrt(s))
    sigma_velocity: tuple[float, float, float] = (1.0, 1.0, 1e-3)  # m/s, ENU
    sigma_gyro: float = 2e-3 * DEG  # angular random walk, rad/sqrt(s)
    sigma_bias: float = 2e-5 * DEG  # bias random walk, rad/s/sqrt(s)
    sigma_ambiguity: float = 1e-16  # cycles/sqrt(s)
    # Table 1, zenith-referenced undifferenced noise
    sigma_code: float = 0.3
    sigma_phase: float = 3e-3
    # the truth's own angular rate (not in Belles et al. 2022): a random walk per axis [rad/s/sqrt(s)]
    sigma_rate: tuple[float, float, float] = (0.02 * DEG, 0.02 * DEG, 0.2 * DEG)
    # outliers: cycle slips on the phases of two satellites at every vehicle antenna
    outlier_zones: tuple[tuple[float, float], ...] = ((300.0, 400.0), (600.0, 700.0))
    # two of the ten satellites (Belles et al. 2022: G20 and G24 of its skyplot, which this almanac does not
    # reproduce): ranks by elevation at the start, 0 = the highest (the DD reference)
    outlier_ranks: tuple[int, ...] = (3, 6)
    max_slip_cycles: int = 5
    site: tuple[float, float, float] = (43.5653 * DEG, 1.4746 * DEG, 150.0)  # base station
    mask_deg: float = 10.0

    @property
    def n_dd(self) -> int:
        """DDs per antenna pair (n = satellites - 1)."""
        return self.n_satellites - 1

    @property
    def n_ambiguities(self) -> int:
        return self.n_dd * (len(self.baselines) + 1)

    @property
    def n_states(self) -> int:
        return 3 + self.n_ambiguities + 9

    @property
    def n_obs(self) -> int:
        return 2 * self.n_ambiguities


# state slices
def slices(cfg: JpaConfig) -> dict[str, slice]:
    M = cfg.n_ambiguities
    return {
        "psi": slice(0, 3),
        "a": slice(3, 3 + M),
        "p": slice(3 + M, 6 + M),
        "v": slice(6 + M, 9 + M),
        "b": slice(9 + M, 12 + M),
    }


@dataclass(frozen=True)
class Geometry:
    """Satellites and lines of sight over the run (shared by the Monte Carlo runs)."""

    prn: np.ndarray  # (S,) tracked satellites, reference (highest) first
    elevation: np.ndarray  # (T, S) [rad]
    U: np.ndarray  # (T, n, 3) DD lines of sight u_i = e_i - e_ref (ENU)
    t0: float  # GPS seconds of the first epoch
    outlier_rows: np.ndarray  # (n,) bool: non-reference satellites that carry the outliers


def _enu_lines_of_sight(alm, t: float, site_ecef: np.ndarray, C_en: np.ndarray):
    pos = gnss.almanac_orbit(alm, t).position  # (S, 3)
    d = pos - site_ecef
    e = d / np.linalg.norm(d, axis=1, keepdims=True)
    ned = e @ C_en.T
    enu = np.stack([ned[:, 1], ned[:, 0], -ned[:, 2]], axis=1)
    return enu, np.arcsin(np.clip(enu[:, 2], -1.0, 1.0))


def make_geometry(
    cfg: JpaConfig, search_s: float = 86400.0, step_s: float = 60.0, start_s: float = 0.0
) -> Geometry:
    """The ``n_satellites`` highest satellites of the packaged almanac at the base station.

    From the first time (in ``step_s`` steps from ``start_s`` after the almanac reference) at which all
    of them stay above the mask for the whole run; the outlier satellites are those of
    ``outlier_ranks``.
    """
    ranks = np.asarray(cfg.outlier_ranks, dtype=int)
    if ((ranks < 1) | (ranks >= cfg.n_satellites)).any():
        top = cfg.n_satellites - 1
        raise ValueError(
            f"outlier_ranks must lie in 1..{top} (0 is the DD reference); got {cfg.outlier_ranks}"
        )
    alm = gnss.load_default_almanac()
    lat, lon, h = cfg.site
    site = geo.geodetic_to_ecef(np.array([lat]), np.array([lon]), np.array([h]))[0]
    C_en = geo.ecef_to_ned_matrix(lat, lon)
    T = int(round(cfg.duration / cfg.dt)) + 1
    t_ref = float(alm.t_ref[0])
    for t0 in t_ref + start_s + np.arange(0.0, search_s, step_s):
        _, el = _enu_lines_of_sight(alm, t0, site, C_en)
        top = np.argsort(-el)[: cfg.n_satellites]
        if el[top].min() < cfg.mask_deg * DEG:
            continue
        enu, els = [], []
        for k in range(T):
            e, elk = _enu_lines_of_sight(alm, t0 + k * cfg.dt, site, C_en)
            enu.append(e[top])
            els.append(elk[top])
        enu, els = np.array(enu), np.array(els)
        if els.min() < cfg.mask_deg * DEG:
            continue
        U = enu[:, 1:] - enu[:, :1]
        prn = alm.prn[top]
        rank = np.zeros(cfg.n_satellites, dtype=bool)
        rank[list(cfg.outlier_ranks)] = True
        return Geometry(prn, els, U, float(t0), rank[1:])
    raise ValueError(f"no epoch with {cfg.n_satellites} satellites above the mask for the whole run")


def dd_operator(n_sat: int, n_slaves: int) -> np.ndarray:
    """``D`` mapping undifferenced values to the DDs ``[bm (n), 1m (n), .., Nm (n)]``.

    Undifferenced values are ordered ``(receiver, satellite)`` (receivers: base, master, slaves;
    satellite 0 the reference).
    """
    R = n_slaves + 2
    n = n_sat - 1
    D = np.zeros(((n_slaves + 1) * n, R * n_sat))
    col = lambda r, s: r * n_sat + s  # noqa: E731
    pairs = [(1, 0)] + [(2 + j, 1) for j in range(n_slaves)]  # (rover, reference receiver)
    for q, (r, r0) in enumerate(pairs):
        for i in range(1, n_sat):
            row = q * n + i - 1
            D[row, col(r, i)] += 1.0
            D[row, col(r0, i)] -= 1.0
            D[row, col(r, 0)] -= 1.0
            D[row, col(r0, 0)] += 1.0
    return D


def observation_covariance(cfg: JpaConfig, elevation: np.ndarray, D: np.ndarray) -> np.ndarray:
    """``Sigma (m, m)`` of ``[Phi_bm, rho_bm, Phi_att, rho_att]`` at one epoch (elevations ``(S,)``)."""
    scale = _undifferenced_scale(elevation, len(cfg.baselines) + 2)
    S_phase = (D * (cfg.sigma_phase * scale) ** 2) @ D.T
    S_code = (D * (cfg.sigma_code * scale) ** 2) @ D.T
    order = _row_order(cfg)
    full = np.zeros((2 * D.shape[0], 2 * D.shape[0]))
    full[: D.shape[0], : D.shape[0]] = S_phase
    full[D.shape[0] :, D.shape[0] :] = S_code
    return full[np.ix_(order, order)]


def _undifferenced_scale(elevation: np.ndarray, receivers: int) -> np.ndarray:
    """``1 / sin(el)`` per undifferenced observation, receiver-major ``(receivers * S,)``."""
    return np.tile(1.0 / np.sin(elevation), receivers)


def _row_order(cfg: JpaConfig) -> np.ndarray:
    """Permutation from ``[phase DDs (all pairs), code DDs (all pairs)]`` to eq. 11a/12a order."""
    n, P = cfg.n_dd, len(cfg.baselines) + 1
    phase = np.arange(P * n)
    code = P * n + np.arange(P * n)
    return np.concatenate([phase[:n], code[:n], phase[n:], code[n:]])


def right_jacobian(phi: np.ndarray) -> np.ndarray:
    """``J_r(phi)`` of SO(3): ``d Exp(phi + d) = Exp(phi) Exp(J_r d)`` (Sola et al. 2018, eq. 143)."""
    th2 = (phi * phi).sum(axis=-1)
    th = np.sqrt(th2)
    small = th2 < 1e-10
    safe = np.where(small, 1.0, th)
    a = np.where(small, 0.5 - th2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    b = np.where(small, 1.0 / 6.0 - th2 / 120.0, (safe - np.sin(safe)) / safe**3)
    K = skew(phi)
    return np.eye(3) - a[..., None, None] * K + b[..., None, None] * (K @ K)


@dataclass
class JpaObservation:
    """The DD observation model at one epoch for B filters (``h``, ``H``, ``R``), eq. 11-12."""

    cfg: JpaConfig
    R_nom: np.ndarray  # (B, 3, 3) nominal attitudes
    U: np.ndarray  # (n, 3)
    R: np.ndarray  # (m, m)
    sl: dict[str, slice] = field(init=False)

    def __post_init__(self) -> None:
        self.sl = slices(self.cfg)
        self.Bm = np.asarray(self.cfg.baselines).T  # (3, N) body baselines as columns

    def _attitude(self, x: np.ndarray) -> np.ndarray:
        return self.R_nom @ rotation_matrix(x[:, self.sl["psi"]])

    def h(self, x: np.ndarray) -> np.ndarray:
        n, lam = self.cfg.n_dd, WAVELENGTH_L1
        a = x[:, self.sl["a"]]
        pos = -(x[:, self.sl["p"]] @ self.U.T)  # (B, n)
        Rb = self._attitude(x) @ self.Bm  # (B, 3, N)
        att = -np.swapaxes(self.U @ Rb, 1, 2).reshape(x.shape[0], -1)  # (B, N n), slave-major
        return np.concatenate([pos + lam * a[:, :n], pos, att + lam * a[:, n:], att], axis=1)

    def H(self, x: np.ndarray) -> np.ndarray:
        cfg, sl, lam = self.cfg, self.sl, WAVELENGTH_L1
        n, M = cfg.n_dd, cfg.n_ambiguities
        B, N = x.shape[0], self.Bm.shape[1]
        J = np.zeros((B, 2 * M, cfg.n_states))
        J[:, 0:n, sl["p"]] = -self.U
        J[:, n : 2 * n, sl["p"]] = -self.U
        a0 = sl["a"].start
        J[:, np.arange(n), a0 + np.arange(n)] = lam
        J[:, 2 * n + np.arange(N * n), a0 + n + np.arange(N * n)] = lam
        # d(-u^T R_nom Exp(psi) b)/dpsi = u^T R [b x] J_r(psi)
        psi = x[:, sl["psi"]]
        R = self._attitude(x)
        Jr = right_jacobian(psi)
        for j in range(N):
            G = R @ skew(self.Bm[:, j]) @ Jr  # (B, 3, 3)
            rows = self.U @ G  # (B, n, 3)
            J[:, 2 * n + j * n : 2 * n + (j + 1) * n, sl["psi"]] = rows
            J[:, 2 * n + N * n + j * n : 2 * n + N * n + (j + 1) * n, sl["psi"]] = rows
        return J


def transition(cfg: JpaConfig, w_hat: np.ndarray) -> np.ndarray:
    """Error-state transition ``F (B, n, n)`` of eq. 10 for bias-corrected rates ``w_hat (B, 3)``."""
    sl, dt = slices(cfg), cfg.dt
    F = np.broadcast_to(np.eye(cfg.n_states), (w_hat.shape[0], cfg.n_states, cfg.n_states)).copy()
    F[:, sl["psi"], sl["psi"]] = np.swapaxes(rotation_matrix(w_hat * dt), 1, 2)
    F[:, sl["psi"], sl["b"]] = -dt * np.eye(3)
    F[:, sl["p"], sl["v"]] = dt * np.eye(3)
    return F


def process_noise(cfg: JpaConfig) -> np.ndarray:
    """``Q (n, n)``: gyro noise on the attitude error, random walks of a, v and b (Table 1)."""
    sl, dt = slices(cfg), cfg.dt
    q = np.zeros(cfg.n_states)
    q[sl["psi"]] = cfg.sigma_gyro**2 * dt
    q[sl["a"]] = cfg.sigma_ambiguity**2 * dt
    q[sl["v"]] = np.square(cfg.sigma_velocity) * dt
    q[sl["b"]] = cfg.sigma_bias**2 * dt
    return np.diag(q)


def initial_covariance(cfg: JpaConfig) -> np.ndarray:
    sl = slices(cfg)
    d = np.zeros(cfg.n_states)
    d[sl["psi"]] = cfg.sigma0_attitude**2
    d[sl["a"]] = cfg.sigma0_ambiguity**2
    d[sl["p"]] = cfg.sigma0_position**2
    d[sl["v"]] = np.square(cfg.sigma0_velocity)
    d[sl["b"]] = cfg.sigma0_bias**2
    return np.diag(d)


@dataclass
class Truth:
    """Simulated runs: truth ``(T, B, ...)``, gyro samples and DD observations ``(T, B, m)``."""

    p: np.ndarray
    v: np.ndarray
    R: np.ndarray
    b: np.ndarray
    a: np.ndarray  # (B, M) integer ambiguities [cycles]
    gyro: np.ndarray  # (T, B, 3) measured rates over [t_k, t_k+1)
    z: np.ndarray  # (T, B, m) DD observations at t_k (z[0] unused)
    outlier: np.ndarray  # (T, m) bool: rows corrupted at t_k


def simulate(cfg: JpaConfig, geom: Geometry, runs: int, seed: int, outliers: bool) -> Truth:
    """``runs`` Monte Carlo runs of the vehicle, its gyroscope and the DD observations.

    Velocity and gyroscope bias follow random walks (Belles et al. 2022, §5), the body rate a random walk of
    its own; the undifferenced code and phase noises are independent Gaussians (elevation
    dependent) differenced by ``D``. With ``outliers``, during each outlier zone the phases of
    the outlier satellites carry a cycle slip at every vehicle antenna (master and slaves, not
    the base station): an integer of cycles drawn per run, zone and satellite from
    ``+-1 .. +-max_slip_cycles``, the same at every vehicle antenna, removed at the end of the
    zone (the noise itself unchanged, Belles et al. 2022, §5). It cancels in the master-slave DDs, so the
    corrupted rows are the base-master phase DDs of those satellites.
    """
    rng = np.random.default_rng(seed)
    T = geom.U.shape[0]
    S = cfg.n_satellites
    N = len(cfg.baselines)
    D = dd_operator(S, N)
    n, M, m = cfg.n_dd, cfg.n_ambiguities, cfg.n_obs
    order = _row_order(cfg)
    lam = WAVELENGTH_L1
    B = runs
    bearing = rng.uniform(0.0, 2 * np.pi, B)
    p = np.stack([cfg.start_distance * np.cos(bearing), cfg.start_distance * np.sin(bearing), np.zeros(B)], 1)
    v = rng.normal(0.0, 1.0, (B, 3)) * np.array([5.0, 5.0, 0.0])
    yaw = rng.uniform(-np.pi, np.pi, B)
    R = rotation_matrix(np.stack([np.zeros(B), np.zeros(B), yaw], 1))
    b = rng.normal(0.0, cfg.sigma0_bias, (B, 3))
    w = np.zeros((B, 3))
    a = rng.integers(-20, 21, (B, M)).astype(np.float64)
    sl = slices(cfg)
    x = np.zeros((B, cfg.n_states))  # the truth as the filters' state vector (zero attitude error)
    x[:, sl["a"]] = a
    slips = np.zeros((B, N + 2, S))
    out = {k: [] for k in ("p", "v", "R", "b", "gyro", "z")}
    outlier_rows = np.zeros((T, m), dtype=bool)
    sat_rows = np.concatenate([[False], geom.outlier_rows])  # undifferenced satellites
    for k in range(T):
        t = k * cfg.dt
        zone = outliers and any(t0 <= t < t1 for t0, t1 in cfg.outlier_zones)
        if zone and any(t - cfg.dt < t0 <= t for t0, _ in cfg.outlier_zones):
            # cycle slips of this zone: the same at every vehicle antenna (receivers 1..N+1),
            # none at the base station
            mag = rng.integers(1, cfg.max_slip_cycles + 1, (B, 1, S))
            sgn = rng.choice([-1.0, 1.0], (B, 1, S))
            slips[:, 1:, :] = np.where(sat_rows, mag * sgn, 0.0)
        if not zone:
            slips[:] = 0.0
        scale = _undifferenced_scale(geom.elevation[k], N + 2)
        e_phase = rng.standard_normal((B, (N + 2) * S)) * (cfg.sigma_phase * scale)
        e_code = rng.standard_normal((B, (N + 2) * S)) * (cfg.sigma_code * scale)
        e_phase = e_phase + lam * slips.reshape(B, -1)
        x[:, sl["p"]] = p
        clean = JpaObservation(cfg, R, geom.U[k], np.empty((0, 0))).h(x)  # eq. 11-12 at the truth
        z = clean + np.concatenate([e_phase @ D.T, e_code @ D.T], axis=1)[:, order]
        if zone:  # base-master phase DDs of the slipped satellites (the slip cancels between antennas)
            corrupted = np.zeros(2 * (N + 1) * n, dtype=bool)
            corrupted[:n] = geom.outlier_rows
            outlier_rows[k] = corrupted[order]
        out["p"].append(p)
        out["v"].append(v)
        out["R"].append(R)
        out["b"].append(b)
        out["z"].append(z)
        # advance to t_k+1: gyro samples the mean rate of the interval
        gyro = w + b + rng.standard_normal((B, 3)) * (cfg.sigma_gyro / np.sqrt(cfg.dt))
        out["gyro"].append(gyro)
        R = R @ rotation_matrix(w * cfg.dt)
        p = p + cfg.dt * v
        v = v + rng.standard_normal((B, 3)) * np.asarray(cfg.sigma_velocity) * np.sqrt(cfg.dt)
        b = b + rng.standard_normal((B, 3)) * cfg.sigma_bias * np.sqrt(cfg.dt)
        w = w + rng.standard_normal((B, 3)) * np.asarray(cfg.sigma_rate) * np.sqrt(cfg.dt)
    arr = {k: np.array(vv) for k, vv in out.items()}
    return Truth(arr["p"], arr["v"], arr["R"], arr["b"], a, arr["gyro"], arr["z"], outlier_rows)


# ------------------------------------------------------------------ the Jpa platform's filter models
# The platform (navgym.jpa.platform) keeps the nominal attitude in the filter's mean as a rotation
# vector ``theta`` (``R_nom = Exp(theta)``), so that a task's filter state stays a GaussianState:
#
#     mean  x = [theta (3), a (M), p (3), v (3), b (3)],   covariance over [dpsi, a, p, v, b]
#
# (the covariance is that of the error state of eq. 6-7: ``R = R_nom Exp(dpsi)``). The prediction
# (:class:`JpaTransitionModel`) moves the nominal (eq. 9) and the error covariance (eq. 10); the
# update runs on the error state (:meth:`JpaDDObservation.error_state`) and is injected back with
# the ESKF reset (:meth:`JpaDDObservation.inject`; Sola 2017, eq. 287).


def exp_so3(theta: np.ndarray) -> np.ndarray:
    """``Exp(theta)`` ``(B, 3, 3)`` of rotation vectors ``(B, 3)`` (Sola et al. 2018, eq. 77)."""
    return rotation_matrix(theta)


def log_so3(R: np.ndarray) -> np.ndarray:
    """``Log(R)`` ``(B, 3)``, angles in [0, pi] (via the unit quaternion: exact near pi too)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(np.asarray(R, np.float64)).as_rotvec()


def dd_values(R: np.ndarray, p: np.ndarray, a: np.ndarray, U: np.ndarray, Bm: np.ndarray) -> np.ndarray:
    """Noise-free DDs of eq. 11-12, batched: ``(B, 2 M)`` in the order of :func:`_row_order`.

    Args:
        R: attitudes ``(B, 3, 3)``.
        p: positions ``(B, 3)`` [m] (ENU from the base station).
        a: ambiguities ``(B, M)`` [cycles].
        U: DD lines of sight ``(B, n, 3)``.
        Bm: body baselines as columns ``(3, N)`` [m].
    """
    n, lam = U.shape[1], WAVELENGTH_L1
    B = p.shape[0]
    pos = -np.einsum("bij,bj->bi", U, p)  # (B, n)
    Rb = R @ Bm  # (B, 3, N)
    att = -np.swapaxes(U @ Rb, 1, 2).reshape(B, -1)  # (B, N n), slave-major
    return np.concatenate([pos + lam * a[:, :n], pos, att + lam * a[:, n:], att], axis=1)


def error_transition(M: int, w_hat: np.ndarray, dt: float) -> np.ndarray:
    """Error-state transition ``F (B, 12 + M, 12 + M)`` of eq. 10 (as :func:`transition`)."""
    B, ns = w_hat.shape[0], 12 + M
    F = np.broadcast_to(np.eye(ns), (B, ns, ns)).copy()
    F[:, 0:3, 0:3] = np.swapaxes(rotation_matrix(w_hat * dt), 1, 2)
    F[:, 0:3, 9 + M : 12 + M] = -dt * np.eye(3)
    F[:, 3 + M : 6 + M, 6 + M : 9 + M] = dt * np.eye(3)
    return F


class JpaTransitionModel(NamedTuple):
    """Prediction of eq. 9-10 on the platform's mean ``[theta, a, p, v, b]`` (see above).

    ``f``: ``R_nom+ = R_nom Exp((w_m - b) dt)`` (``theta+ = Log(R_nom+)``), ``p+ = p + dt v``,
    ``a, v, b`` kept; ``F``: the error transition of eq. 10 (the covariance's), so that
    :func:`filters.kalman.predict` gives ``P- = F P F^T + Q``.
    """

    gyro: np.ndarray  # (B, 3) measured rate over the step [rad/s] (the sensor, not truth)
    Q: np.ndarray  # (B, n, n)
    M: int

    def f(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        M = self.M
        out = np.array(x, dtype=np.float64, copy=True)
        w_hat = self.gyro - x[:, 9 + M : 12 + M]
        out[:, 0:3] = log_so3(exp_so3(x[:, 0:3]) @ rotation_matrix(w_hat * dt))
        out[:, 3 + M : 6 + M] += dt * x[:, 6 + M : 9 + M]
        return out

    def F(self, x: np.ndarray, u: np.ndarray | None = None, dt: float = 1.0) -> np.ndarray:
        return error_transition(self.M, self.gyro - x[:, 9 + self.M : 12 + self.M], dt)


class JpaErrorObservation(NamedTuple):
    """The DDs as a function of the error state ``dx`` about the nominal ``x0`` (eq. 11-12).

    ``h(dx)`` evaluates eq. 11-12 at ``R = R_nom Exp(dpsi)`` and ``x0 + dx`` elsewhere; ``H`` is
    its exact Jacobian (the right Jacobian of SO(3) on the attitude columns), so the iterated
    update's fixed point is the manifold MAP estimate (eq. 16).
    """

    x0: np.ndarray  # (B, n) nominal mean (theta in the first 3 entries)
    R_nom: np.ndarray  # (B, 3, 3)
    U: np.ndarray  # (B, n_dd, 3)
    Bm: np.ndarray  # (3, N)
    R: np.ndarray  # (B, m, m)

    def h(self, dx: np.ndarray) -> np.ndarray:
        M = self.x0.shape[1] - 12
        x = self.x0 + dx
        R = self.R_nom @ rotation_matrix(dx[:, 0:3])
        return dd_values(R, x[:, 3 + M : 6 + M], x[:, 3 : 3 + M], self.U, self.Bm)

    def H(self, dx: np.ndarray) -> np.ndarray:
        B, ns = dx.shape
        M = ns - 12
        n, N, lam = self.U.shape[1], self.Bm.shape[1], WAVELENGTH_L1
        J = np.zeros((B, 2 * M, ns))
        J[:, 0:n, 3 + M : 6 + M] = -self.U
        J[:, n : 2 * n, 3 + M : 6 + M] = -self.U
        J[:, np.arange(n), 3 + np.arange(n)] = lam
        J[:, 2 * n + np.arange(N * n), 3 + n + np.arange(N * n)] = lam
        psi = dx[:, 0:3]
        R = self.R_nom @ rotation_matrix(psi)
        Jr = right_jacobian(psi)
        for j in range(N):  # N antennas (2-3), not the batch
            rows = self.U @ (R @ skew(self.Bm[:, j]) @ Jr)  # (B, n, 3)
            J[:, 2 * n + j * n : 2 * n + (j + 1) * n, 0:3] = rows
            J[:, 2 * n + N * n + j * n : 2 * n + N * n + (j + 1) * n, 0:3] = rows
        return J


class JpaDDObservation(NamedTuple):
    """The DD observation of one epoch for the platform's filters (eq. 11-12), in ESKF form.

    A task updates it on the error state: :meth:`error_state` gives the prior ``N(0, P-)`` and
    :class:`JpaErrorObservation` about the predicted mean; :meth:`inject` moves the error
    posterior into the mean (``R_nom <- R_nom Exp(dpsi)``, the rest added) and carries the
    covariance with the reset Jacobian ``G = I - [dpsi / 2 x]`` (Sola 2017, eq. 287).
    """

    U: np.ndarray  # (B, n_dd, 3)
    Bm: np.ndarray  # (3, N)
    R: np.ndarray  # (B, m, m)

    def error_state(self, m: np.ndarray) -> JpaErrorObservation:
        return JpaErrorObservation(m, exp_so3(m[:, 0:3]), self.U, self.Bm, self.R)

    def inject(self, m: np.ndarray, dx: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(mean, P)`` after the reset of the error posterior ``N(dx, P)`` about ``m``."""
        dpsi = dx[:, 0:3]
        out = m + dx
        out[:, 0:3] = log_so3(exp_so3(m[:, 0:3]) @ rotation_matrix(dpsi))
        G = np.broadcast_to(np.eye(m.shape[1]), P.shape).copy()
        G[:, 0:3, 0:3] -= skew(0.5 * dpsi)
        GP = G @ P @ np.swapaxes(G, 1, 2)
        return out, 0.5 * (GP + np.swapaxes(GP, 1, 2))
