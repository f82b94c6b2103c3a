"""A registry entry of an id, and the changes each version of the ids makes.

Each platform exports its own entries (``ENTRIES`` of its ``env_ids`` module, e.g.
:mod:`navgym.robot2d.env_ids`): an :class:`EnvEntry` per id, naming the classes that make it.
:mod:`navgym.envs.registration` collects them and registers them with Gymnasium. This module
imports nothing but the standard library, so loading a platform's entries costs nothing.

The versions: ``-v1`` adds the remaining-steps penalty (:data:`V1_PENALTY`; the Resample ids
also roughening and ``log10 ESS/N``, :data:`V1_RESAMPLE`); ``-v2`` runs the platform's v2
episodes (within-episode events unknown to the filter, the true noise kept for the clairvoyant
reference) with the changes of :data:`V2_CHANGES`; ``-v3`` runs them with the context a receiver
and an IMU report in the observation (per-row C/N0, the receiver's accuracy figures, IMU
statistics) and the RowScale knob (:func:`v3_rowscale`), or, where it passes gate G1, the NoiseScale
knob with ranges that do not bind (:func:`v3_noisescale`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

#: What every ``-v1`` id changes against ``-v0``: ending an episode early never pays.
V1_PENALTY: dict[str, Any] = {"penalize_remaining_steps": True}
#: What the ``-v1`` Resample ids change against ``-v0`` (see the env cards' Version History).
V1_RESAMPLE: dict[str, Any] = {"roughening": 0.2, "log_ess_feature": True, **V1_PENALTY}
#: What every ``-v2`` id changes against its ``-v1`` defaults: memory in the observation (NIS
#: averages at two time constants, per-row innovation averages, whiteness), and for the Mixture
#: task one outlier weight per measurement row (``per_row=True``); the Resample task keeps its v1
#: defaults (roughening, log10 ESS/N) and adds the memory.
V2_CHANGES: dict[str, dict[str, Any]] = {
    "fading": {"memory_features": True},
    "noisescale": {"memory_features": True},
    "mixture": {"memory_features": True, "per_row": True},
    "resample": {"memory_features": True},
}
#: The defaults of the ``-v3`` RowScale ids: the EKF, the v1 penalty and the v2 memory features.
V3_ROWSCALE: dict[str, Any] = {"filter": "ekf", **V1_PENALTY, "memory_features": True}
#: The defaults of the ``-v3`` NoiseScale ids (:func:`v3_noisescale`): the EKF, the v1 penalty, the
#: v2 memory features, ``s_q`` on the motion states only and ranges that do not bind (0.1 to 1e4).
V3_NOISESCALE: dict[str, Any] = {
    "filter": "ekf",
    **V1_PENALTY,
    "memory_features": True,
    "motion_q": True,
    "q_scale_range": (0.1, 1e4),
    "r_scale_range": (0.1, 1e4),
}
#: Gate G1 of the v3 ids (``python -m experiments.knob_reach --env ID --tune-episodes 256
#: --episodes 256``; 128 tuning episodes for Pedestrian and GpsIns): the regime oracle's RMSE
#: below the best tuned baseline's, in %, with the paired 95 % CI, on held-out episodes. An id
#: passes at >= 25 % with the CI above 0; ``navgym list`` marks the ids worth training on from it
#: (:func:`status`).
G1_REACH: dict[str, tuple[float, float, float]] = {
    "navgym/GpsInsRowScale-v3": (34.6, 30.5, 39.4),
    "navgym/PedestrianNoiseScale-v3": (40.3, 33.2, 47.7),
    "navgym/PedestrianRowScale-v3": (49.9, 36.1, 66.2),
    "navgym/QuadrotorRowScale-v3": (54.0, 34.9, 84.3),
    "navgym/Robot2dRowScale-v3": (30.6, 25.2, 36.5),
}
#: The v3 ids that replay real data: evaluation only (no gate, nothing is trained on them).
EVALUATION_ONLY: frozenset[str] = frozenset({"navgym/ReplayRowScale-v3"})
#: G1's margin [%].
G1_MARGIN_PCT = 25.0
#: The ``release`` of an entry that does not give one: after every id navgym ships.
LATER = 1000

#: The fields of an entry as a tuple, in the order tools unpack them.
ENTRY_FIELDS = ("id", "module", "prefix", "task", "steps", "defaults")


@dataclass(frozen=True)
class EnvEntry:
    """One registered id: ``navgym/<Prefix><Task>-v<k>``, the classes that make it, its defaults.

    Iterates and indexes as the tuple ``(id, module, prefix, task, steps, defaults)``
    (:data:`ENTRY_FIELDS`) that tools and tests unpack.

    Attributes:
        id: The Gymnasium id.
        module: The module of the environment classes.
        prefix: The platform's name in the id (``"Robot2d"``).
        task: The task's name, the ``task=`` keyword argument (``"fading"``).
        steps: ``max_episode_steps`` of the id (the TimeLimit of ``gym.make``).
        defaults: The id's keyword arguments besides ``task``.
        env_class: The single environment's class in ``module`` (default ``<prefix>Env``).
        vector_class: The native vector environment's class (default ``<prefix>VectorEnv``).
        release: Where the id comes in :data:`~navgym.envs.registration.ENVIRONMENTS`: ids are
            listed by release (the order navgym added them, 0 first), then by platform, then in
            the platform's own order.
    """

    id: str
    module: str
    prefix: str
    task: str
    steps: int
    defaults: Mapping[str, Any] = field(default_factory=dict)
    env_class: str = ""
    vector_class: str = ""
    release: int = LATER

    def __post_init__(self) -> None:
        if not self.env_class:
            object.__setattr__(self, "env_class", f"{self.prefix}Env")
        if not self.vector_class:
            object.__setattr__(self, "vector_class", f"{self.prefix}VectorEnv")

    @property
    def entry_point(self) -> str:
        """``module:EnvClass`` of ``gym.make``."""
        return f"{self.module}:{self.env_class}"

    @property
    def vector_entry_point(self) -> str:
        """``module:VectorEnvClass`` of ``gym.make_vec``."""
        return f"{self.module}:{self.vector_class}"

    def as_tuple(self) -> tuple[str, str, str, str, int, Mapping[str, Any]]:
        """``(id, module, prefix, task, steps, defaults)``."""
        return (self.id, self.module, self.prefix, self.task, self.steps, self.defaults)

    def __iter__(self) -> Iterator[Any]:
        return iter(self.as_tuple())

    def __getitem__(self, i: int) -> Any:
        return self.as_tuple()[i]

    def __len__(self) -> int:
        return len(ENTRY_FIELDS)


def v1(entry: EnvEntry) -> EnvEntry:
    """The ``-v1`` id of a ``-v0`` entry: its defaults plus :data:`V1_RESAMPLE` or :data:`V1_PENALTY`.

    Released after the ``-v0`` ids: the Fading and Mixture ids first, the Resample ids next.
    """
    resample = entry.task == "resample"
    changes = V1_RESAMPLE if resample else V1_PENALTY
    return replace(
        entry,
        id=entry.id.removesuffix("-v0") + "-v1",
        defaults={**entry.defaults, **changes},
        release=entry.release + (2 if resample else 1),
    )


def v2(entry: EnvEntry, module: str, release: int) -> EnvEntry:
    """The ``-v2`` id of a ``-v1`` entry: its defaults plus :data:`V2_CHANGES`, classes of ``module``."""
    return replace(
        entry,
        id=entry.id.removesuffix("-v1") + "-v2",
        module=module,
        defaults={**entry.defaults, **V2_CHANGES[entry.task]},
        release=release,
    )


def v3_rowscale(prefix: str, module: str, steps: int, release: int = 11) -> EnvEntry:
    """The ``navgym/<prefix>RowScale-v3`` entry of a platform whose v3 classes are in ``module``."""
    return EnvEntry(
        f"navgym/{prefix}RowScale-v3", module, prefix, "rowscale", steps, V3_ROWSCALE, release=release
    )


def v3_noisescale(prefix: str, module: str, steps: int, release: int = 12) -> EnvEntry:
    """The ``navgym/<prefix>NoiseScale-v3`` entry (:data:`V3_NOISESCALE`), classes of ``module``.

    Registered only on the platforms where gate G1 holds (``experiments/knob_reach``: Pedestrian;
    the GpsIns, Quadrotor and Robot2d variants miss it and are left out).
    """
    return EnvEntry(
        f"navgym/{prefix}NoiseScale-v3", module, prefix, "noisescale", steps, V3_NOISESCALE, release=release
    )


def _name_and_version(env_id: str) -> tuple[str, int]:
    name, _, version = env_id.rpartition("-v")
    return name, int(version)


def status(env_id: str, ids: Iterable[str]) -> str:
    """What ``navgym list`` says of ``env_id`` among the registered ``ids``.

    ``superseded by -vK`` where the same name is registered at a later version; for a v3 id,
    ``train: G1 +X %`` where gate G1 (:data:`G1_REACH`) passed, ``G1 failed (+X %)`` where it
    did not, ``G1 not measured`` where no figure is recorded, ``evaluation: real data`` for the
    replay ids of :data:`EVALUATION_ONLY`; ``""`` otherwise.
    """
    name, version = _name_and_version(env_id)
    later = [v for n, v in map(_name_and_version, ids) if n == name and v > version]
    if later:
        return f"superseded by -v{max(later)}"
    if version < 3:
        return ""
    if env_id in EVALUATION_ONLY:
        return "evaluation: real data"
    if env_id not in G1_REACH:
        return "G1 not measured"
    reach, low, _high = G1_REACH[env_id]
    if reach >= G1_MARGIN_PCT and low > 0.0:
        return f"train: G1 {reach:+.0f} %"
    return f"G1 failed ({reach:+.0f} %)"
