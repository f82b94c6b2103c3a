"""GPS constellation, measurements and single-point positioning, batched over B episodes.

Conventions: times are continuous GPS seconds (``week * 604800 + tow``, see
:mod:`navgym.gnss.gpstime`); positions ECEF metres; batch axis first; measurements on
``m_max`` rows (default 12) with a boolean mask ``(B, m_max)``, rows by decreasing elevation.
Randomness enters the per-step functions as arrays drawn from per-episode generators
(:class:`EpisodeStreams`), so batched runs equal single runs with seeds s, s+1, ...

Public API (one line each):

Constellation and ephemerides
    ``parse_yuma(path, reference_week=None, healthy_only=False) -> Almanac``
    ``load_default_almanac(healthy_only=True) -> Almanac`` (real almanac, GPS week 2086)
    ``almanac_orbit(almanac, t) -> OrbitState(position, velocity, eccentric_anomaly)``
    ``almanac_clock(almanac, t) -> dt_sv``;  ``take(almanac, index) -> Almanac``
    ``keplerian_orbit(tk, sqrt_a, e, m0, omega, i0, omega0, omega_dot, toe, ...) -> OrbitState``
    ``read_rinex_nav(path) -> NavigationData(ephemeris, ion_alpha, ion_beta)``
    ``read_rinex_obs(path) -> ObservationData(approx_position, obs_types, time, prn, values)``
    ``select_ephemeris(eph, prn, t) -> index``;  ``take_ephemeris(eph, index)``
    ``ephemeris_orbit(eph, t) -> OrbitState``;  ``ephemeris_clock(eph, t, E=None) -> dt_sv``

Visibility
    ``visible(elevation, mask_deg)``;  ``count_visible(elevation, mask_deg)``
    ``select_satellites(elevation, mask_deg, m_max=12) -> (index (B, m), mask (B, m))``
    ``dop(rx_ecef, sat_ecef, mask=None) -> Dop(gdop, pdop, hdop, vdop, tdop)``
    ``gdop(rx_ecef (B, 3), sat_ecef (B, m, 3), mask (B, m)) -> (B,)`` (fast, per-step)
    ``find_critical_window(almanac, mask_deg=50, duration_s=3600) -> CriticalWindow``
    ``default_critical_window(almanac) -> CriticalWindow`` (cached 3 -> 2 place and time)

Measurement models (pure)
    ``geometric_range(rx, sat_pos, sat_vel=None, earth_rotation=True)``
    ``pseudorange(rx, sat_pos, sat_vel, clock_bias_m, atmosphere_m=0, earth_rotation=True)``
    ``range_rate(rx, rx_vel, sat_pos, sat_vel)``;  ``delta_range(..., clock_drift_mps)``
    ``range_and_rate(rx, rx_vel, sat_pos, sat_vel, sat_acc=None)`` (both in one pass)
    ``ecef_acceleration(position, velocity)`` (two-body + Coriolis + centrifugal)
    ``sagnac_correction(rx, sat)``
    ``goad_goodman_delay(elevation)``;  ``saastamoinen_delay(elevation, lat, h)``
    ``klobuchar_delay(alpha, beta, lat, lon, elevation, azimuth, tow)``

Clock, noise, randomness
    ``clock_transition(dt, a, sigma_w) -> (Phi, Q)``;  ``clock_init(z, params)``;
    ``clock_step(state, dt, z, params) -> ClockState``
    ``make_regime(batch, sigma, sigma_dr, eps, var_ratio, jam_sigma, loss_prob,
    outlier_prob, outlier_scale, outlier_prns) -> NoiseRegime``;  ``where_regime(c, a, b)``
    ``sample_noise(regime, prn, z_pr, z_dr, u_mix, u_loss, u_out) -> NoiseSample``
    ``episode_generators(seed, batch)``;  ``EpisodeStreams(generators, n_normal, n_uniform)``

Simulator step and positioning
    ``constellation(almanac, t) -> OrbitState`` (all satellites, once per step)
    ``simulate_gnss_step(almanac, t, rx_ecef, rx_vel, clock, regime, normals, uniforms,
    mask_deg=10, m_max=12, orbit=None) -> GnssStep``; ``normals (B, 3 m_max)`` and
    ``uniforms (B, 3 m_max)`` are read block-wise (see :data:`NORMALS_PER_ROW`)
    ``solve_spp(pseudorange, sat_pos, mask, mask_deg=10, ...) -> SppSolution``
    ``spp_from_rinex(obs, nav, mask_deg=10, ionosphere=False, troposphere=False)``
    ``navgym.gnss.bench.measure_step_cost(batch) -> dict`` (timings; ``python -m
    navgym.gnss.bench``)

Typical simulator loop (B episodes sharing the GPS time ``t``)::

    alm = load_default_almanac()
    streams = EpisodeStreams(episode_generators(seed, B), n_normal=3 * 12 + 2,
                             n_uniform=3 * 12)
    z, u = streams.step()
    clock = clock_init(z[:, 36:38])
    for k in range(n_steps):
        z, u = streams.step()
        clock = clock_step(clock, dt, z[:, 36:38])
        meas = simulate_gnss_step(alm, t, rx, v, clock, regime, z[:, :36], u,
                                  orbit=constellation(alm, t))
"""

from navgym.gnss.almanac import (
    Almanac,
    almanac_clock,
    almanac_orbit,
    load_default_almanac,
    parse_yuma,
    take,
)
from navgym.gnss.clock import (
    CLOCK_A,
    CLOCK_SIGMA_W,
    ClockParams,
    ClockState,
    clock_init,
    clock_step,
    clock_transition,
)
from navgym.gnss.critical import CriticalWindow, default_critical_window, find_critical_window
from navgym.gnss.ephemeris import (
    ephemeris_clock,
    ephemeris_orbit,
    select_ephemeris,
    take_ephemeris,
)
from navgym.gnss.gpstime import SECONDS_PER_WEEK, gps_seconds, week_and_tow
from navgym.gnss.ionosphere import klobuchar_delay
from navgym.gnss.measurements import (
    delta_range,
    geometric_range,
    pseudorange,
    range_and_rate,
    range_rate,
    sagnac_correction,
)
from navgym.gnss.noise import NoiseRegime, NoiseSample, make_regime, sample_noise, where_regime
from navgym.gnss.orbit import OrbitState, ecef_acceleration, keplerian_orbit
from navgym.gnss.rinex import (
    BroadcastEphemeris,
    NavigationData,
    ObservationData,
    read_rinex_nav,
    read_rinex_obs,
)
from navgym.gnss.simulate import (
    NORMALS_PER_ROW,
    UNIFORMS_PER_ROW,
    GnssStep,
    constellation,
    simulate_gnss_step,
)
from navgym.gnss.spp import SppSolution, solve_spp, spp_from_rinex
from navgym.gnss.streams import EpisodeStreams, episode_generators
from navgym.gnss.troposphere import goad_goodman_delay, saastamoinen_delay
from navgym.gnss.visibility import (
    DEFAULT_M_MAX,
    Dop,
    count_visible,
    dop,
    gdop,
    select_satellites,
    visible,
)

__all__ = [
    "Almanac",
    "BroadcastEphemeris",
    "CLOCK_A",
    "CLOCK_SIGMA_W",
    "ClockParams",
    "ClockState",
    "CriticalWindow",
    "DEFAULT_M_MAX",
    "Dop",
    "EpisodeStreams",
    "GnssStep",
    "NORMALS_PER_ROW",
    "NavigationData",
    "NoiseRegime",
    "NoiseSample",
    "ObservationData",
    "OrbitState",
    "SECONDS_PER_WEEK",
    "SppSolution",
    "UNIFORMS_PER_ROW",
    "almanac_clock",
    "almanac_orbit",
    "clock_init",
    "clock_step",
    "clock_transition",
    "constellation",
    "count_visible",
    "default_critical_window",
    "delta_range",
    "dop",
    "gdop",
    "ecef_acceleration",
    "ephemeris_clock",
    "ephemeris_orbit",
    "episode_generators",
    "find_critical_window",
    "geometric_range",
    "goad_goodman_delay",
    "gps_seconds",
    "keplerian_orbit",
    "klobuchar_delay",
    "load_default_almanac",
    "make_regime",
    "parse_yuma",
    "pseudorange",
    "range_and_rate",
    "range_rate",
    "read_rinex_nav",
    "read_rinex_obs",
    "saastamoinen_delay",
    "sagnac_correction",
    "sample_noise",
    "select_ephemeris",
    "select_satellites",
    "simulate_gnss_step",
    "solve_spp",
    "spp_from_rinex",
    "take",
    "take_ephemeris",
    "visible",
    "week_and_tow",
    "where_regime",
]
