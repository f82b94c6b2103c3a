"""The navgym registry: ``navgym/<Platform><Task>-v<k>`` ids, registered idempotently.

Each id has an ``entry_point`` (single env), a ``vector_entry_point`` (native batched env, the
default of ``gym.make_vec``) and ``max_episode_steps``. Variants are keyword arguments.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator
from typing import Any

import gymnasium as gym

#: What every ``-v1`` id changes against ``-v0``: ending an episode early never pays.
V1_PENALTY = {"penalize_remaining_steps": True}
#: What the ``-v1`` Resample ids change against ``-v0`` (see the env cards' Version History).
V1_RESAMPLE = {"roughening": 0.2, "log_ess_feature": True, **V1_PENALTY}

#: (id, platform module, class prefix, task, default episode steps, default kwargs)
V0_ENVIRONMENTS: list[tuple[str, str, str, str, int, dict]] = [
    ("navgym/GpsInsFading-v0", "navgym.gps_ins.env", "GpsIns", "fading", 300, {"filter": "ekf"}),
    ("navgym/GpsInsMixture-v0", "navgym.gps_ins.env", "GpsIns", "mixture", 300, {"filter": "ckf"}),
    (
        "navgym/GpsInsResample-v0",
        "navgym.gps_ins.env",
        "GpsIns",
        "resample",
        300,
        {"n_particles": 1000, "m_max": 8},
    ),
    ("navgym/QuadrotorFading-v0", "navgym.quadrotor.env", "Quadrotor", "fading", 600, {"filter": "ekf"}),
    ("navgym/QuadrotorMixture-v0", "navgym.quadrotor.env", "Quadrotor", "mixture", 600, {"filter": "ckf"}),
    ("navgym/Robot2dFading-v0", "navgym.robot2d.env", "Robot2d", "fading", 600, {"filter": "ekf"}),
    ("navgym/Robot2dMixture-v0", "navgym.robot2d.env", "Robot2d", "mixture", 600, {"filter": "ckf"}),
    ("navgym/Robot2dResample-v0", "navgym.robot2d.env", "Robot2d", "resample", 600, {"n_particles": 1000}),
]


def _v1(entry: tuple[str, str, str, str, int, dict]) -> tuple[str, str, str, str, int, dict]:
    """The ``-v1`` id of a ``-v0`` entry: its defaults plus V1_RESAMPLE or V1_PENALTY."""
    env_id, module, prefix, task, steps, defaults = entry
    changes = V1_RESAMPLE if task == "resample" else V1_PENALTY
    return (env_id.removesuffix("-v0") + "-v1", module, prefix, task, steps, {**defaults, **changes})


#: Platforms with v2 episodes (within-episode events unknown to the filter, the true noise kept
#: for the clairvoyant reference: DESIGN.md, "Tasks that reward learning (v2)"): the module of
#: their v2 declaration, by the module of their v0/v1 ids, and the tasks it registers.
V2_MODULES: dict[str, tuple[str, tuple[str, ...]]] = {
    "navgym.robot2d.env": ("navgym.robot2d.env_v2", ("fading", "noisescale", "mixture", "resample")),
    "navgym.gps_ins.env": ("navgym.gps_ins.env_v2", ("fading", "noisescale", "mixture", "resample")),
    "navgym.quadrotor.env": ("navgym.quadrotor.env_v2", ("fading", "noisescale", "mixture")),
}
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
#: Tasks new in v2 (no v0/v1 entry): their base defaults.
V2_NEW_TASKS: dict[str, tuple[str, dict[str, Any]]] = {
    "noisescale": ("NoiseScale", {"filter": "ekf", **V1_PENALTY}),
}


def _v2(entry: tuple[str, str, str, str, int, dict]) -> tuple[str, str, str, str, int, dict]:
    """The ``-v2`` id of a ``-v1`` entry: its defaults (the v1 penalty included) plus V2_CHANGES."""
    env_id, module, prefix, task, steps, defaults = entry
    new = env_id.removesuffix("-v1") + "-v2"
    return (new, V2_MODULES[module][0], prefix, task, steps, {**defaults, **V2_CHANGES[task]})


def _v2_entries() -> list[tuple[str, str, str, str, int, dict]]:
    """v1 of the tasks :data:`V2_MODULES` lists, then its tasks new in v2, per platform."""
    out = []
    for module, (_v2_module, tasks) in V2_MODULES.items():
        v1 = [e for e in _V1_ENVIRONMENTS if e[1] == module]
        out += [_v2(e) for e in v1 if e[3] in tasks]
        prefix, steps = v1[0][2], v1[0][4]
        for task in tasks:
            if task in V2_NEW_TASKS:
                title, defaults = V2_NEW_TASKS[task]
                out.append(_v2((f"navgym/{prefix}{title}-v1", module, prefix, task, steps, dict(defaults))))
    return out


_V1_ENVIRONMENTS = [_v1(e) for e in V0_ENVIRONMENTS]
#: The v2 ids: v1 of the tasks :data:`V2_MODULES` lists and the tasks new in v2, on their
#: platform's v2 episodes.
V2_ENVIRONMENTS: list[tuple[str, str, str, str, int, dict]] = _v2_entries()

#: Platforms registered at v2 only, from their own declaration (no v0/v1 ids, so not in
#: :data:`V2_MODULES`): Iridium (:mod:`navgym.iridium.env`; Benzerrouk 2014, §2.7d). Their
#: defaults are a v1 id's with :data:`V2_CHANGES`; the filter is the (exact, linear) Kalman filter.
V2_ENVIRONMENTS += [
    (f"navgym/Iridium{title}-v2", "navgym.iridium.env", "Iridium", task, 360,
     {"filter": "ekf", **V1_PENALTY, **V2_CHANGES[task]})
    for task, title in (("mixture", "Mixture"), ("noisescale", "NoiseScale"))
]  # fmt: skip
#: Pedestrian (:mod:`navgym.pedestrian.env`; Benzerrouk 2014, §2.7c), also v2 only: the
#: Quadrotor's strapdown EKF with zero-velocity updates and GPS/GLONASS fixes.
V2_ENVIRONMENTS += [
    (f"navgym/Pedestrian{title}-v2", "navgym.pedestrian.env", "Pedestrian", task, 180,
     {"filter": "ekf", **V1_PENALTY, **V2_CHANGES[task]})
    for task, title in (("fading", "Fading"), ("noisescale", "NoiseScale"), ("mixture", "Mixture"))
]  # fmt: skip

#: Jpa (:mod:`navgym.jpa.env`; Belles et al. 2022, §5): v2 only, the Robust task (the robust
#: threshold of the iterated ESKF) with the v2 penalty and memory features.
V2_ENVIRONMENTS += [
    ("navgym/JpaRobust-v2", "navgym.jpa.env", "Jpa", "robust", 120,
     {"weight": "huber", **V1_PENALTY, "memory_features": True}),
]  # fmt: skip

#: SignalTracking (:mod:`navgym.signal_tracking.env`; Dirac-Gauss DPF n.d., §3-4): v2 only, the Jumps
#: task (the jump prior of the random Dirac-Gauss PF) with the v2 penalty and memory features.
V2_ENVIRONMENTS += [
    ("navgym/SignalTrackingJumps-v2", "navgym.signal_tracking.env", "SignalTracking", "jumps", 100,
     {**V1_PENALTY, "memory_features": True}),
]  # fmt: skip

#: Replay ids (a real recording with injected v2 events, :mod:`navgym.recordings.env_v2`): v2 only.
REPLAY_ENVIRONMENTS: list[tuple[str, str, str, str, int, dict]] = [
    (f"navgym/Replay{title}-v2", "navgym.recordings.env_v2", "Replay", task, 240,
     {"filter": "ekf", **V1_PENALTY, **V2_CHANGES[task]})
    for task, title in (("fading", "Fading"), ("noisescale", "NoiseScale"))
]  # fmt: skip

#: Every id: the v0 ids, then v1 of the Fading and Mixture tasks (the remaining-steps penalty),
#: then v1 of the Resample tasks (roughening, remaining-steps penalty, log10 ESS/N), then the v2
#: ids, then the replay ids.
ENVIRONMENTS: list[tuple[str, str, str, str, int, dict]] = (
    V0_ENVIRONMENTS
    + [_v1(e) for e in V0_ENVIRONMENTS if e[3] != "resample"]
    + [_v1(e) for e in V0_ENVIRONMENTS if e[3] == "resample"]
    + V2_ENVIRONMENTS
    + REPLAY_ENVIRONMENTS
)


def register_all() -> list[str]:
    """Register every navgym environment (a second call changes nothing)."""
    ids = []
    for env_id, module, prefix, task, steps, defaults in ENVIRONMENTS:
        if env_id not in gym.registry:
            gym.register(
                id=env_id,
                entry_point=f"{module}:{prefix}Env",
                vector_entry_point=f"{module}:{prefix}VectorEnv",
                max_episode_steps=steps,
                kwargs={"task": task, **defaults},
            )
        ids.append(env_id)
    return ids


@contextlib.contextmanager
def superseded_ids_quiet() -> Iterator[None]:
    """Silence gymnasium's "out of date" notice for the superseded navgym ids inside the block.

    For tools that use a ``-v0`` id on purpose (a zoo agent trained on it, benchmarks whose
    targets were set on it); everywhere else the notice points users to the ``-v1`` ids.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", message=r".*navgym/\S*-v[01] is out of date", category=DeprecationWarning
        )
        yield
