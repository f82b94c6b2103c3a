import numpy as np
import pytest

from navgym import geo
from navgym.gnss import (
    almanac_clock,
    almanac_orbit,
    load_default_almanac,
    parse_yuma,
    take,
)
from navgym.gnss.gpstime import gps_seconds, resolve_week, week_and_tow

from .tolerances import ORBIT_VELOCITY_MPS

BLOCK = """******** Week 38 almanac for PRN-07 ********
ID:                         07
Health:                     000
Eccentricity:               0.1489162445E-001
Time of Applicability(s):  503808.0000
Orbital Inclination(rad):   0.9539549351
Rate of Right Ascen(r/s):  -0.7977475151E-008
SQRT(A)  (m 1/2):           5153.653809
Right Ascen at Week(rad):   0.4547393990E+000
Argument of Perigee(rad):  -2.208557010
Mean Anom(rad):             0.1284785271E+001
Af0(s):                    -0.2098083496E-003
Af1(s/s):                   0.0000000000E+000
week:                        38
"""


def test_default_almanac(almanac):
    full = load_default_almanac(healthy_only=False)
    assert full.prn.shape == (31,)
    assert almanac.prn.shape == (30,) and 4 not in almanac.prn  # PRN 4 health 063
    assert np.all(almanac.week == 2086) and np.all(almanac.toa == 503808.0)
    assert np.all((almanac.e > 0) & (almanac.e < 0.03))


def test_week_resolution_and_time():
    assert resolve_week(38, 2086) == 2086
    assert resolve_week(38, 1100) == 1062
    assert resolve_week(2086, 0) == 2086
    t = gps_seconds(2086, 503808.0)
    w, tow = week_and_tow(t + 200000.0)
    assert int(w) == 2087 and float(tow) == pytest.approx(503808.0 + 200000.0 - 604800.0)


def test_radius_bounded_by_perigee_apogee(almanac):
    t = almanac.t_ref[0] + np.linspace(0, 86400, 97)
    r = np.linalg.norm(almanac_orbit(almanac, t).position, axis=-1)  # (T, S)
    a = almanac.semi_major_axis
    assert r.shape == (97, 30)
    assert np.all(r >= a * (1 - almanac.e) - 1e-3) and np.all(r <= a * (1 + almanac.e) + 1e-3)
    assert np.all(np.abs(a - 26_560e3) < 100e3)


def test_period_from_semi_major_axis(almanac):
    # Without nodal precession the inertial position repeats after T = 2 pi sqrt(A^3 / GM).
    alm = almanac._replace(omega_dot=np.zeros_like(almanac.omega_dot))
    period = 2 * np.pi * np.sqrt(alm.semi_major_axis**3 / geo.GM)
    assert np.all(np.abs(period - 43_080) < 200)  # half a sidereal day
    t0 = alm.t_ref + 1234.5

    def inertial(t):
        # Per-satellite times: gather the almanac as (1, S) and pass t as (1, S).
        p = almanac_orbit(take(alm, np.arange(30)[None]), t[None]).position[0]  # (S, 3)
        ang = geo.OMEGA_E * (t - alm.t_ref[0])
        c, s = np.cos(ang), np.sin(ang)
        return np.stack([c * p[:, 0] - s * p[:, 1], s * p[:, 0] + c * p[:, 1], p[:, 2]], -1)

    np.testing.assert_allclose(inertial(t0 + period), inertial(t0), atol=1e-3)


def test_velocity_is_derivative_of_position(almanac):
    t = almanac.t_ref[0] + 3000.0
    h = 0.5
    s = almanac_orbit(almanac, t)
    fd = (almanac_orbit(almanac, t + h).position - almanac_orbit(almanac, t - h).position) / (2 * h)
    np.testing.assert_allclose(s.velocity, fd, atol=ORBIT_VELOCITY_MPS)
    assert np.all(np.abs(np.linalg.norm(s.velocity, axis=-1) - 3.2e3) < 0.7e3)


def test_batched_gather_equals_full(almanac):
    idx = np.array([[0, 5, 7], [29, 1, 1]])
    t = almanac.t_ref[0] + np.array([[10.0], [5000.0]])
    sub = almanac_orbit(take(almanac, idx), t).position
    full = almanac_orbit(almanac, t[:, 0]).position  # (2, S, 3)
    np.testing.assert_array_equal(sub, np.take_along_axis(full, idx[..., None], axis=1))
    clk = almanac_clock(take(almanac, idx), t)
    np.testing.assert_allclose(clk[0, 0], almanac.af0[0] + almanac.af1[0] * 10.0)


def test_parse_seed_style_block(tmp_path):
    f = tmp_path / "alm.txt"
    f.write_text(BLOCK.replace("Right Ascen at Week", "Right Ascen at TOA") + "\n" + BLOCK)
    alm = parse_yuma(f, reference_week=2086)
    assert alm.prn.tolist() == [7, 7] and alm.week.tolist() == [2086, 2086]


@pytest.mark.parametrize(
    ("mutate", "line", "what"),
    [
        (lambda s: s.replace("0.9539549351", "0.95x39"), 6, "bad number"),
        (lambda s: s.replace("Mean Anom(rad):", "Mean Anomaly"), 11, "Key: value"),
        (lambda s: s.replace("Af0(s):", "Bogus(s):"), 12, "unknown almanac key"),
        (lambda s: s.replace("week:                        38\n", ""), 13, "without week"),
        (lambda s: s.replace("0.1489162445E-001", "1.5"), 14, "elliptic"),
    ],
)
def test_malformed_almanac_names_file_and_line(tmp_path, mutate, line, what):
    f = tmp_path / "bad_alm.txt"
    f.write_text(mutate(BLOCK))
    with pytest.raises(ValueError, match=rf"bad_alm\.txt: line {line}: .*{what}"):
        parse_yuma(f)


def test_empty_almanac(tmp_path):
    f = tmp_path / "empty.txt"
    f.write_text("\n\n")
    with pytest.raises(ValueError, match=r"empty\.txt: line 2: no almanac"):
        parse_yuma(f)
