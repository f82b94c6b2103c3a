"""RINEX 2.11 text as writers format it (Tables A2-A4), for the reader tests."""

from __future__ import annotations

from pathlib import Path

#: Navigation record fields in file order: the PRN/epoch/clock line's three, then the seven
#: broadcast-orbit lines' four each (underscore: a field the reader does not return).
NAV_LINES = (
    ("af0", "af1", "af2"),
    ("iode", "crs", "delta_n", "m0"),
    ("cuc", "e", "cus", "sqrt_a"),
    ("toe_sow", "cic", "omega0", "cis"),
    ("i0", "crc", "omega", "omega_dot"),
    ("idot", "_l2codes", "week", "_l2p"),
    ("sv_accuracy", "health", "tgd", "iodc"),
    ("_ttm", "_fit", "_spare1", "_spare2"),
)

#: A valid record (record 1 of the GEONET file 07590920.05n, PRN 1, toc 2005-04-02 02:00).
RECORD = {
    "af0": 3.966595977540e-04,
    "af1": 1.705302565820e-12,
    "af2": 0.0,
    "iode": 140.0,
    "crs": -52.1875,
    "delta_n": 4.026596389650e-09,
    "m0": 2.871534990340,
    "cuc": -2.676621079440e-06,
    "e": 5.957618006510e-03,
    "cus": 4.174187779430e-06,
    "sqrt_a": 5153.636478420,
    "toe_sow": 525600.0,
    "cic": 1.061707735060e-07,
    "omega0": -2.493184817740,
    "cis": -9.313225746150e-08,
    "i0": 0.9833919144490,
    "crc": 309.375,
    "omega": -1.650496813270,
    "omega_dot": -7.889971342930e-09,
    "idot": -8.571785642400e-12,
    "_l2codes": 1.0,
    "week": 1316.0,
    "_l2p": 0.0,
    "sv_accuracy": 1.0,
    "health": 0.0,
    "tgd": -3.259629011150e-09,
    "iodc": 396.0,
    "_ttm": 519576.0,
    "_fit": 0.0,
    "_spare1": 0.0,
    "_spare2": 0.0,
}


def d19(x: float) -> str:
    """One ``D19.12`` field as RINEX 2 writers format it (``1PD19.12``)."""
    return f"{x:19.12E}".replace("E", "D")


def nav_header() -> str:
    """A RINEX 2.11 navigation header with the Klobuchar coefficients (Table A3)."""

    def hdr(label: str, body: str = "") -> str:
        return f"{body:<60}{label}\n"

    return (
        hdr("RINEX VERSION / TYPE", "     2.11           N: GPS NAV DATA")
        + hdr("ION ALPHA", "    0.1118D-07  0.1490D-07 -0.5960D-07 -0.5960D-07")
        + hdr("ION BETA", "    0.8806D+05  0.1638D+05 -0.1966D+06 -0.1311D+06")
        + hdr("END OF HEADER")
    )


def nav_record(values: dict[str, float], prn: int = 1, hour: int = 2) -> list[str]:
    """The 8 lines (with newlines) of one navigation record, toc 2005-04-02 ``hour``:00."""
    v = {**RECORD, **values}
    out = [f"{prn:2d} 05  4  2 {hour:2d}  0  0.0" + "".join(d19(v[n]) for n in NAV_LINES[0]) + "\n"]
    out += ["   " + "".join(d19(v[n]) for n in names) + "\n" for names in NAV_LINES[1:]]
    return out


def nav_file(path: Path, records: list[list[str]]) -> Path:
    """Write a navigation file of ``records`` (each :func:`nav_record`'s lines) to ``path``."""
    path.write_text(nav_header() + "".join("".join(r) for r in records))
    return path


def field_columns(name: str) -> tuple[int, int]:
    """Line offset in the record (0-7) and first column (0-based) of field ``name``."""
    for j, names in enumerate(NAV_LINES):
        if name in names:
            k = names.index(name)
            return j, (22 if j == 0 else 3) + 19 * k
    raise KeyError(name)


def obs_header(types: tuple[str, ...] = ("L1", "C1", "L2", "P2")) -> str:
    """A RINEX 2.11 observation header (Table A1) with ``types``."""

    def hdr(label: str, body: str = "") -> str:
        return f"{body:<60}{label}\n"

    return (
        hdr("RINEX VERSION / TYPE", "     2.11           OBSERVATION DATA    G (GPS)")
        + hdr("APPROX POSITION XYZ", f"{-3976219.5082:14.4f}{3382372.5671:14.4f}{3652512.9849:14.4f}")
        + hdr("# / TYPES OF OBSERV", f"{len(types):6d}" + "".join(f"{t:>6}" for t in types))
        + hdr("END OF HEADER")
    )


def epoch_line(sec: float, flag: int, sats: list[str], count: int | None = None) -> str:
    """An epoch record's first line (Table A2): ``count`` overrides the number announced."""
    n = len(sats) if count is None else count
    return f" 05  4  2  0  0{sec:11.7f}  {flag:1d}{n:3d}" + "".join(sats) + "\n"


def obs_line(values: list[float], lli: str = " ", ssi: str = " ") -> str:
    """One observation line: F14.3 values, each with its LLI and signal-strength column."""
    return "".join(f"{v:14.3f}{lli}{ssi}" for v in values).rstrip() + "\n"
