"""Compiled pseudo-range epoch of the GpsIns env: satellites, selection, noise, observation model.

Every step the GpsIns env simulates one GNSS epoch per episode and builds the filter's
observation model from it (:meth:`navgym.gps_ins.platform.GpsInsPlatform.step_models`). In NumPy
that is some 150 array operations on ``(B, S)`` and ``(B, m)`` arrays, each paying call
overhead and a pass over memory: together more than the EKF that consumes the epoch
(``docs/performance.md``, "Figures behind the code"). This module does the same arithmetic per episode in one
loop compiled by Numba; speed is the reason it is hand-written. The NumPy path
(:func:`navgym.gnss.simulate_gnss_step`, :meth:`navgym.gps_ins.models.PseudorangeModel.build`)
stays the reference and the fallback (times outside the orbit table), and
``tests/navgym/gps_ins/test_epoch_kernel.py`` holds the two equal to rounding.

Per episode ``b`` at GPS time ``t`` (the operations and their order are those of the NumPy
functions, so results agree to the last bits but for the satellite positions, below):

1. **Constellation** (:mod:`navgym.gnss.orbit_cache`): ``r_s = c0 + c1 s + c2 s^2 + c3 s^3`` of
   the grid interval's Hermite cubic for every satellite, ``v_s = (c1 + 2 c2 s + 3 c3 s^2) / h``
   for the selected ones. (NumPy evaluates these with a matrix product whose summation order
   is BLAS's, so positions agree to a few 1e-9 m, not bit for bit.)
2. **Selection** (:func:`navgym.gnss.visibility.rank_satellites`): score ``sin(el)|sin(el)| =
   su |su| / d^2`` with ``su = u.(r_s - r)``, visible above the mask, the ``m`` highest first,
   ties by satellite index (the same integer keys as NumPy: index in the 6 low mantissa bits).
3. **Noise** (Benzerrouk 2014, eq. 71; :func:`navgym.gnss.noise.sample_noise`): mixture component,
   jamming, outliers on chosen PRNs, losses, from the episode's buffered normals and uniforms;
   the v2 events (:mod:`navgym.gps_ins.episodes`): the canyon's factor on the nominal sigma, and
   the multipath segments of the row's satellite (bias and variance added); with the v3
   context the row's variance follows its C/N0 instead (:mod:`navgym.gps_ins.context`). The row's true
   variance (the troposphere model's included) and mean error go to ``true_var``/``true_bias``.
4. **Pseudo-range** (Carvalho et al. 1997, eq. 10/15; :func:`navgym.gnss.measurements.geometric_range`):
   ``|r_s - v_s tau - r| + (w_e/c)(x_s' y - y_s' x) + c dtau + e + T (1 + 0.05 nu)`` with the
   Goad-Goodman troposphere ``T`` (§IV-C-3).
5. **Observation model** (:class:`navgym.gps_ins.models.PseudorangeModel`): the satellite moved
   back by the light time from the INS point, ``d0 = s' - p_INS``, ``|d0|^2``, ``E.d0``,
   ``N.d0``, the Sagnac rows and the constant term.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from navgym.geo import C_LIGHT, OMEGA_E

if TYPE_CHECKING:
    from navgym.gps_ins.context import GpsInsContext
    from navgym.gps_ins.episodes import GpsInsEpisodes

__all__ = ["pseudorange_epoch"]


@njit(cache=True)
def _kernel(
    coef, s, step, k, rx, up, thr, prn_table, regime, sigma, prns,
    noise_n, noise_u, ptr, clock, row_cap, gnss_ok, p_ins, east, north,
    rows, m, k_sagnac, c_light, tropo_c, tropo_noise,
    mp_start, mp_end, mp_sat, mp_bias, mp_var, dt,
    ctx, sat_off, seg_loss, canyon_db, jam_lin, fade, c_h, c_span, a_sq, v_ref_inv,
    z, mask, sat, rho0_sq, A, W, c0, true_var, true_bias, cn0_out,
):  # fmt: skip  # pragma: no cover - compiled; exercised through pseudorange_epoch
    B, S = coef.shape[0], coef.shape[1]
    pos = np.empty((S, 3))
    score = np.empty(S)
    keys = np.empty(S)
    bits = keys.view(np.int64)
    order = np.empty(S, dtype=np.int64)
    big = np.iinfo(np.int64).max
    kd, ad, kw, aw, r_e = tropo_c[0], tropo_c[1], tropo_c[2], tropo_c[3], tropo_c[4]
    L = mp_sat.shape[1]
    for b in range(B):
        sb = s[b]
        s2 = sb * sb
        s3 = s2 * sb
        w1, w2, w3 = 1.0 / step, 2.0 * sb / step, 3.0 * sb * sb / step  # d/dt of 1, s, s^2, s^3
        kb = k[b]
        rxx, rxy, rxz = rx[b, kb, 0], rx[b, kb, 1], rx[b, kb, 2]
        ux, uy, uz = up[b, kb, 0], up[b, kb, 1], up[b, kb, 2]
        n_vis = 0
        for i in range(S):
            for c in range(3):  # no array views in the loop (each costs a reference count)
                pos[i, c] = (
                    coef[b, i, c, 0] + coef[b, i, c, 1] * sb + coef[b, i, c, 2] * s2 + coef[b, i, c, 3] * s3
                )
            dx, dy, dz = pos[i, 0] - rxx, pos[i, 1] - rxy, pos[i, 2] - rxz
            su = dx * ux
            su += dy * uy
            su += dz * uz
            d2 = dx * dx
            d2 += dy * dy
            d2 += dz * dz
            sc = su * abs(su) / d2
            score[i] = sc
            if sc > thr[b]:
                n_vis += 1
            keys[i] = 2.0 - sc
        for i in range(S):  # keys' bit patterns order like the floats (all positive)
            bits[i] = (bits[i] & ~np.int64(63)) | i
        n_vis = min(n_vis, m)
        # the m smallest keys in order: m branch-free min-reductions (keys are unique; the
        # satellite index sits in the low bits, so the chosen entry is struck out by index)
        for r in range(m):
            lo = bits[0]
            for i in range(1, S):
                lo = min(lo, bits[i])
            order[r] = lo & 63
            bits[lo & 63] = big
        eps, var_ratio, jam, loss = regime[b, kb, 0], regime[b, kb, 1], regime[b, kb, 2], regime[b, kb, 3]
        p_out, out_scale = regime[b, kb, 4], regime[b, kb, 5]
        sg = sigma * regime[b, kb, 6]  # the canyon's factor (1 outside: sigma exactly)
        var1 = sg * sg
        tk = kb * dt
        pb = ptr[b]
        cap = row_cap[b, kb]
        ok = gnss_ok[b, kb]
        bias_m = c_light * clock[b, kb, 0]
        px, py, pz = p_ins[b, kb, 0], p_ins[b, kb, 1], p_ins[b, kb, 2]
        ex, ey, ez = east[b, kb, 0], east[b, kb, 1], east[b, kb, 2]
        nx, ny, nz = north[b, kb, 0], north[b, kb, 1], north[b, kb, 2]
        for r in range(m):
            i = order[r]
            sc = score[i]
            sin_el = math.copysign(math.sqrt(abs(sc)), sc) if sc != 0.0 else 0.0
            sx, sy, sz = pos[i, 0], pos[i, 1], pos[i, 2]
            # velocity: (c1 + 2 c2 s + 3 c3 s^2) / h
            vx = coef[b, i, 0, 1] * w1 + coef[b, i, 0, 2] * w2 + coef[b, i, 0, 3] * w3
            vy = coef[b, i, 1, 1] * w1 + coef[b, i, 1, 2] * w2 + coef[b, i, 1, 3] * w3
            vz = coef[b, i, 2, 1] * w1 + coef[b, i, 2, 2] * w2 + coef[b, i, 2, 3] * w3
            # 3. noise of the episode's regime
            z_pr = noise_n[b, pb, r]
            z_tr = noise_n[b, pb, 2 * rows + r]
            u_mix = noise_u[b, pb, r]
            u_loss = noise_u[b, pb, rows + r]
            u_out = noise_u[b, pb, 2 * rows + r]
            var = var1 * var_ratio if u_mix < eps else var1
            var = var + jam * jam
            mpb = 0.0
            mpv = 0.0
            att = 0.0
            hit = False
            for j in range(L):  # multipath segments of this satellite active at the epoch
                if mp_sat[b, j] == i and mp_start[b, j] <= tk and tk < mp_end[b, j]:
                    mpb += mp_bias[b, j]
                    mpv += mp_var[b, j]
                    hit = True
                    if ctx:
                        att += seg_loss[b, j]
            if ctx:  # v3: the row's noise follows its C/N0 (navgym.gps_ins.context)
                att += canyon_db[b, kb]
                att = max(att + fade[b, kb, r], 0.0) if att > 0.0 else 0.0
                c_clear = c_h + c_span * min(max(sin_el, 0.0), 1.0) + sat_off[b, i] - att
                u = 10.0 ** (-c_clear / 10.0) + jam_lin[b, kb]
                cn0_out[b, r] = -10.0 * math.log10(u)
                var = sigma * sigma * u * (1.0 + a_sq * u) * v_ref_inv
                if u_mix < eps:
                    var = var * var_ratio
            elif hit:
                var = var + mpv
            e_pr = math.sqrt(var) * z_pr
            gross = 0.0
            prn = prn_table[i]
            if prns[b, min(max(prn, 0), 32)] and u_out < p_out:
                gross = out_scale if u_out < 0.5 * p_out else -out_scale
                e_pr = e_pr + gross
            if hit:
                e_pr = e_pr + mpb
            lost = u_loss < loss
            # 4. pseudo-range: light time, Sagnac, clock, noise, troposphere
            dx, dy, dz = sx - rxx, sy - rxy, sz - rxz
            tau = math.sqrt(dx * dx + dy * dy + dz * dz) / c_light
            tx, ty, tz = sx - vx * tau, sy - vy * tau, sz - vz * tau
            dx, dy, dz = tx - rxx, ty - rxy, tz - rxz
            rho = math.sqrt(dx * dx + dy * dy + dz * dz) + k_sagnac * (tx * rxy - ty * rxx)
            rs = r_e * sin_el
            rs2 = rs * rs
            t_r = kd * (math.sqrt(ad + rs2) - rs)
            t_r += kw * (math.sqrt(aw + rs2) - rs)
            pr = rho + bias_m + e_pr
            pr += t_r * (1.0 + tropo_noise * z_tr)
            usable = (r < n_vis) and (not lost) and (r < cap) and ok
            e_tr = tropo_noise * t_r
            true_var[b, r] = var + e_tr * e_tr
            true_bias[b, r] = gross + mpb
            mask[b, r] = usable
            z[b, r] = pr if usable else np.nan
            # 5. observation model about the INS point
            dx, dy, dz = sx - px, sy - py, sz - pz
            tau = math.sqrt(dx * dx + dy * dy + dz * dz) / c_light
            qx, qy, qz = sx - vx * tau, sy - vy * tau, sz - vz * tau
            sat[b, r, 0], sat[b, r, 1], sat[b, r, 2] = qx, qy, qz
            dx, dy, dz = qx - px, qy - py, qz - pz
            rho0_sq[b, r] = dx * dx + dy * dy + dz * dz
            A[b, 0, r] = dx * ex + dy * ey + dz * ez
            A[b, 1, r] = dx * nx + dy * ny + dz * nz
            wx, wy = -k_sagnac * qy, k_sagnac * qx
            W[b, 0, r] = wx * ex + wy * ey
            W[b, 1, r] = wx * nx + wy * ny
            c0[b, r] = k_sagnac * (qx * py - qy * px) + t_r


def pseudorange_epoch(
    coef: np.ndarray,
    s: np.ndarray,
    step: float,
    k: np.ndarray,
    ep: GpsInsEpisodes,
    prn: np.ndarray,
    sigma: float,
    m: int,
    troposphere: tuple[float, float, float, float, float],
    tropo_noise: float,
    dt: float = 1.0,
    context: GpsInsContext | None = None,
) -> tuple[np.ndarray, ...]:
    """Pseudo-range epoch ``k (B,)`` of B GpsIns episodes and its observation model (module docstring).

    Reads the episodes' truth, scenario and noise buffers at epoch ``k[b]`` and noise row
    ``ep.noise_ptr[b]`` (block-wise as :data:`navgym.gnss.simulate.NORMALS_PER_ROW` says); the
    caller refills the buffers and advances the pointer.

    Args:
        coef: Orbit-grid coefficients ``(B, S, 3, 4)`` of the interval at the epoch's GPS time
            (:meth:`~navgym.gnss.orbit_cache.OrbitCache.interval_coefficients`).
        s: Position in that interval, ``(B,)`` in [0, 1).
        step: Grid spacing [s].
        k: Epoch of each episode ``(B,)``.
        ep: The :class:`~navgym.gps_ins.episodes.GpsInsEpisodes`.
        prn: PRN of each satellite ``(S,)``.
        sigma: Nominal pseudo-range sigma [m] (the regime's sigma_1).
        m: Measurement rows (``min(m_max, S)``).
        troposphere: :func:`~navgym.gnss.troposphere.goad_goodman_coefficients`.
        tropo_noise: Relative sigma of the troposphere's model error (Carvalho et al. 1997, §IV-C-3: 0.05).
        dt: The episodes' step [s] (epoch ``k`` is at ``k dt`` s: the multipath segments' clock).
        context: The v3 context (``ep.context``): each row's noise variance follows its C/N0
            (:func:`navgym.gps_ins.context.row_cn0_and_variance`, replacing the canyon factor,
            the jamming and the multipath variance); None: v0-v2, the arithmetic above exactly.

    Returns:
        ``(z, mask, sat, rho0_sq, A, W, c0, true_var, true_bias, cn0)``: pseudo-ranges ``(B, m)``
        (NaN where not usable), the usable mask, light-time-corrected satellites ``(B, m, 3)``,
        the :class:`~navgym.gps_ins.models.PseudorangeModel` fields (``c0`` holds the modelled
        troposphere), each row's true error variance and mean ``(B, m)`` (truth: evaluation
        only) and, with ``context``, each row's true C/N0 [dB-Hz] ``(B, m)`` (else None).
    """
    B, S = coef.shape[:2]
    if S > 64:
        raise ValueError(f"the compiled epoch ranks at most 64 satellites; got {S}")
    rows = ep.noise_n.shape[-1] // 3
    if not 1 <= m <= min(rows, S):
        raise ValueError(f"m must lie in [1, {min(rows, S)}]; got {m}")
    z = np.empty((B, m))
    mask = np.empty((B, m), dtype=np.bool_)
    sat = np.empty((B, m, 3))
    rho0_sq = np.empty((B, m))
    A = np.empty((B, 2, m))
    W = np.empty((B, 2, m))
    c0 = np.empty((B, m))
    true_var = np.empty((B, m))
    true_bias = np.empty((B, m))
    if context is None:
        one, cube = np.zeros((1, 1)), np.zeros((1, 1, 1))
        cx = (False, one, one, one, one, cube, 0.0, 0.0, 0.0, 0.0)
        cn0 = one
    else:
        from navgym.gnss.signal_quality import nominal_cn0_dbhz
        from navgym.gps_ins.context import DLL_SQUARING_HZ, jitter_reference_variance

        c_h, c_z = float(nominal_cn0_dbhz(0.0)), float(nominal_cn0_dbhz(np.pi / 2))
        cx = (
            True, context.sat_offset_db, context.seg_loss_db, context.canyon_loss_db, context.jam_lin,
            context.fade_db, c_h, c_z - c_h, DLL_SQUARING_HZ, 1.0 / jitter_reference_variance(),
        )  # fmt: skip
        cn0 = np.empty((B, m))
    _kernel(
        coef, s, float(step), np.ascontiguousarray(k, dtype=np.int64), ep.rx_ecef, ep.up,
        ep.mask_score, np.ascontiguousarray(prn, dtype=np.int64), ep.regime,
        float(sigma), ep.outlier_prns, ep.noise_n, ep.noise_u, ep.noise_ptr, ep.clock, ep.row_cap,
        ep.gnss_ok, ep.p_ins, ep.east, ep.north, int(rows), int(m),
        OMEGA_E / C_LIGHT, C_LIGHT, np.asarray(troposphere, dtype=np.float64), float(tropo_noise),
        ep.mp_start, ep.mp_end, ep.mp_sat, ep.mp_bias, ep.mp_var, float(dt),
        *cx,
        z, mask, sat, rho0_sq, A, W, c0, true_var, true_bias, cn0,
    )  # fmt: skip
    return z, mask, sat, rho0_sq, A, W, c0, true_var, true_bias, (cn0 if context is not None else None)
