"""RINEX 2.x readers: GPS navigation (broadcast ephemeris) and observation files.

Own small fixed-column readers (RINEX 2.10/2.11, Gurtner & Estey, "RINEX: The Receiver
Independent Exchange Format Version 2.11", tables A1-A4). Loops run over lines only; the
results are arrays. Fields the readers do not return (spares, L2 codes, transmission time, fit
interval, the receiver clock offset, fields defined as blank ``nX``) are not parsed, so nothing
in them can fail a read (RINEX 2.11 §6.4: readers skip fields defined to be blank).

**Strict fields.** Every field the readers return is checked for the layout of its Fortran
format, not merely scanned for a number, so that a line cut in the middle of a field or shifted
by a column is refused instead of read as a different number:

* ``Dw.d`` (navigation records ``D19.12``, ``ION ALPHA/BETA`` ``D12.4``): the number ends in the
  field's last column (right-justified, blanks before it only), has at most one digit before the
  point, exactly ``d`` digits after it and an exponent of two or three digits after a letter
  ``D``/``E`` (any case) and a sign, or of three digits after a bare sign when the letter has no
  room (``0.499063314480-269``, Fortran's ``Dw.d`` output for |exponent| > 99);
* ``F14.3`` (observations): right-justified, exactly three decimals; the loss-of-lock and
  signal-strength columns after it (``I1`` each) are blank or a digit;
* integers (``I2``, ``I3``, ``I2.2``) right-justified digits; the seconds ``F5.1`` / ``F11.7``
  with exactly one / seven decimals.

A blank field is refused unless the format lets it be unknown (RINEX 2.11 §5.3, "items that
are not known at the file creation time can be set to zero or blank"; §6.3, empty fields at the
end of a record may be missing): in the navigation records only a_f2, T_GD, IODC and the SV
accuracy (read as 0.0, "not known"); blank observations are missing (NaN). Every number must
be finite and lie in its physical range (the navigation fields: the range of their IS-GPS-200
Table 20-I/20-III bit field, see :data:`NAV_FIELD_RANGES`).

**Duplicate navigation records** (one PRN, the same ``toc`` or the same ``toe``): a copy equal
in every returned field is dropped (broadcast files merged from several receivers repeat
records); two that differ are refused, naming both lines, since
:func:`~navgym.gnss.ephemeris.select_ephemeris` would otherwise take one of them silently.

**Event records** (epoch flags 2-5, RINEX 2.11 §5.4 and Table A2): the ``nsat`` special records
that follow must be header records (a label in columns 61-80), must all be in the file, and the
line after them must be an epoch record again; an event record that changes the
``# / TYPES OF OBSERV`` is refused (the reader keeps one set of types).

Malformed input raises ``ValueError`` of one shape: ``"<file>: line <n>: <what is wrong>;
expected <what the format asks for>"`` (1-based line numbers).

The readers live in :mod:`navgym.gnss.rinex_nav` (navigation), :mod:`navgym.gnss.rinex_obs`
(observations) and :mod:`navgym.gnss.rinex_fields` (the shared field readers and ranges); this
module is their public face.
"""

from __future__ import annotations

from navgym.gnss.rinex_fields import NAV_FIELD_RANGES
from navgym.gnss.rinex_nav import BroadcastEphemeris, NavigationData, read_rinex_nav
from navgym.gnss.rinex_obs import ObservationData, read_rinex_obs

__all__ = [
    "BroadcastEphemeris",
    "NAV_FIELD_RANGES",
    "NavigationData",
    "ObservationData",
    "read_rinex_nav",
    "read_rinex_obs",
]
