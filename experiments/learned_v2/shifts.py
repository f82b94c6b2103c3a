"""The shifted event distributions of ``experiments.learned_v2``, fixed before any result.

A shift is a rule applied to a platform's v2 event defaults (``V2_EVENTS`` of
:mod:`navgym.robot2d.env`, :mod:`navgym.gps_ins.env`, :mod:`navgym.quadrotor.env`,
:mod:`navgym.pedestrian.env`; the v3 ids share them), never a
number per platform. Each range ``(low, high)`` whose key matches a pattern is transformed at both
ends:

* ``"longer events"``: every ``*_duration`` range x 2, each end capped at the longest event that
  fits the default episode after the start margin, ``T - min(start_margin_s, 0.1 T)`` with
  ``T = episode_steps * dt`` of the platform's v2 declaration (the scenario starts no event
  before the margin; a longer one would run past the end and be cut);
* ``"stronger events"``: ``burst_velocity_sigma``, ``multipath_bias``, ``jamming_sigma`` x 2,
  ``canyon_noise_scale`` x 1.5 (where the platform has the key);
* ``"more events"``: every ``*_count`` range + 2 at both ends, capped at a platform's count limit
  (GpsIns holds at most ``MULTIPATH_SLOTS`` multipath segments per episode).

:data:`SHIFT_KWARGS` holds the resulting env keyword arguments per platform: only the keys a
shift changes, as ``(low, high)`` tuples (floats for durations and strengths, ints for counts).
"""

from __future__ import annotations

import fnmatch
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from navgym.envs.platform import PlatformSpec
from navgym.gps_ins import env as gps_ins_env
from navgym.gps_ins.env_v2 import GPS_INS_V2
from navgym.gps_ins.platform import MULTIPATH_SLOTS
from navgym.pedestrian import env as pedestrian_env
from navgym.quadrotor import env as quadrotor_env
from navgym.quadrotor.env_v2 import QUADROTOR_V2
from navgym.robot2d import env as robot2d_env
from navgym.robot2d.env_v2 import ROBOT2D_V2

__all__ = ["PLATFORMS", "SHIFTS", "SHIFT_KWARGS", "Platform", "Shift", "apply_shift", "platform_of"]


@dataclass(frozen=True)
class Shift:
    """A rule on event ranges: ``low, high -> low * f + o, high * f + o`` on the matching keys.

    Attributes:
        description: one line for the tables.
        factors: ``{fnmatch pattern: factor f}`` (e.g. ``{"*_duration": 2.0}``).
        offsets: ``{fnmatch pattern: offset o}`` (e.g. ``{"*_count": 2}``).
        cap_durations: cap ``*_duration`` ends at the longest event that fits the episode.
    """

    description: str
    factors: Mapping[str, float] = field(default_factory=dict)
    offsets: Mapping[str, int] = field(default_factory=dict)
    cap_durations: bool = False


#: The three shifts (module docstring). Chosen before any result of the study was seen.
SHIFTS: dict[str, Shift] = {
    "longer events": Shift(
        "every *_duration range x2 (capped at the longest event that fits the episode)",
        factors={"*_duration": 2.0},
        cap_durations=True,
    ),
    "stronger events": Shift(
        "burst_velocity_sigma, multipath_bias, jamming_sigma x2; canyon_noise_scale x1.5",
        factors={
            "burst_velocity_sigma": 2.0,
            "multipath_bias": 2.0,
            "jamming_sigma": 2.0,
            "canyon_noise_scale": 1.5,
        },
    ),
    "more events": Shift("every *_count range +2 at both ends", offsets={"*_count": 2}),
}


@dataclass(frozen=True)
class Platform:
    """A platform's v2 event defaults, its v2 declaration (horizon) and its count limits."""

    events: Mapping[str, Any]
    spec: PlatformSpec
    count_caps: Mapping[str, int] = field(default_factory=dict)

    @property
    def longest_event_s(self) -> float:
        """``T - min(start_margin_s, 0.1 T)``, ``T = episode_steps * dt`` (as the scenario's margin)."""
        T = self.spec.episode_steps * self.spec.dt
        return T - min(self.spec.start_margin_s, 0.1 * T)


#: Platforms with v2 ids, keyed by the id prefix (``navgym/<name><Task>-v2``).
PLATFORMS: dict[str, Platform] = {
    "Robot2d": Platform(robot2d_env.V2_EVENTS, ROBOT2D_V2),
    "GpsIns": Platform(gps_ins_env.V2_EVENTS, GPS_INS_V2, {"multipath_count": MULTIPATH_SLOTS}),
    "Quadrotor": Platform(quadrotor_env.V2_EVENTS, QUADROTOR_V2),
    "Pedestrian": Platform(pedestrian_env.V2_EVENTS, pedestrian_env.PEDESTRIAN_V2),
}


def _matches(key: str, patterns: Mapping[str, Any]) -> Any:
    return next((v for p, v in patterns.items() if fnmatch.fnmatchcase(key, p)), None)


def apply_shift(
    shift: Shift,
    events: Mapping[str, Any],
    longest_event_s: float | None = None,
    count_caps: Mapping[str, int] | None = None,
) -> dict[str, tuple[float, float] | tuple[int, int]]:
    """The env keyword arguments of ``shift`` on the event defaults ``events``.

    For each ``(low, high)`` range whose key matches a pattern: ``(low * f, high * f)`` for a
    factor ``f``, ``(low + o, high + o)`` for an offset ``o``; a ``*_duration`` end is then
    ``min(end, longest_event_s)`` when ``shift.cap_durations``, a ``*_count`` end
    ``min(end, count_caps[key])``. Keys the shift does not touch are left out.
    """
    caps = dict(count_caps or {})
    out: dict[str, Any] = {}
    for key, value in events.items():
        f, o = _matches(key, shift.factors), _matches(key, shift.offsets)
        if f is None and o is None:
            continue
        if not (isinstance(value, tuple) and len(value) == 2):
            raise ValueError(f"shift of {key!r} needs a (low, high) range; the default is {value!r}")
        is_count = key.endswith("_count")
        ends = [v * (1.0 if f is None else f) + (0 if o is None else o) for v in value]
        if shift.cap_durations and key.endswith("_duration") and longest_event_s is not None:
            ends = [min(e, longest_event_s) for e in ends]
        if is_count:
            ends = [int(round(e)) for e in ends]
            if key in caps:
                ends = [min(e, caps[key]) for e in ends]
            out[key] = (int(ends[0]), int(ends[1]))
        else:
            out[key] = (float(ends[0]), float(ends[1]))
    return out


def platform_of(env_id: str) -> str:
    """The platform name of a v2 id (``navgym/Robot2dNoiseScale-v2`` -> ``Robot2d``)."""
    name = env_id.split("/")[-1]
    for p in PLATFORMS:
        if name.startswith(p):
            return p
    raise KeyError(f"{env_id}: no v2 platform of {sorted(PLATFORMS)}")


#: ``{platform: {shift: env kwargs}}``, from :data:`SHIFTS` and :data:`PLATFORMS`.
SHIFT_KWARGS: dict[str, dict[str, dict[str, Any]]] = {
    name: {s: apply_shift(rule, p.events, p.longest_event_s, p.count_caps) for s, rule in SHIFTS.items()}
    for name, p in PLATFORMS.items()
}
