"""The navgym registry: ``navgym/<Platform><Task>-v<k>`` ids, registered idempotently.

Each id has an ``entry_point`` (single env), a ``vector_entry_point`` (native batched env, the
default of ``gym.make_vec``) and ``max_episode_steps``. Variants are keyword arguments.
"""

from __future__ import annotations

import contextlib
import textwrap
import warnings
from collections.abc import Callable, Iterator
from typing import Any

import gymnasium as gym

#: What every ``-v1`` id changes against ``-v0``: ending an episode early never pays.
V1_PENALTY = {"penalize_remaining_steps": True}
#: What the ``-v1`` Resample ids change against ``-v0`` (see the env cards' Version History).
V1_RESAMPLE = {"roughening": 0.2, "log_ess_feature": True, **V1_PENALTY}

#: Version History line of the Fading and Mixture ``-v1`` ids (every platform's card).
PENALTY_VERSION_HISTORY = """\
* v1 (Fading, Mixture): the divergence penalty also charges ``reward_clip`` per step not played
  of the simulated ``episode_steps`` (``penalize_remaining_steps=True``, as the Resample v1
  ids), so ending an episode early never pays. With v0's constant penalty (100, ten worst
  steps) a diverged filter costs less than a bad episode played out: on GpsInsFading-v0 (256
  episodes, ``python -m experiments.divergence_penalty``) a policy that fades at the maximum
  from step 150 on diverges in 41 % of the episodes and returns -166.7 on average against
  -249.3 for the plain filter; with the v1 penalty it returns -640.5.
"""

#: Version History of the env cards of platforms with a Resample task (GpsIns, Robot2d).
RESAMPLE_VERSION_HISTORY = """\
* v1 (Resample): the same remaining-steps penalty; the particles are roughened after each
  resampling (Gordon, Salmond & Smith 1993, ``roughening=0.2``): without it, states with almost
  no process noise collapse onto a few particles and every resampling policy loses to "never";
  the observation adds ``log_ess_frac = log10(ESS/N)`` (``log_ess_feature=True``).
* Library change of 2026-12-01 (no version bump: the distributions are unchanged): the
  Resample envs' particle filter draws its normals by Box-Muller from raw 64-bit words
  (``filters.core.normal``), component-major, into a float32 cloud (``particle_dtype``), so a
  given seed yields other particle draws than before that date (figures published before it
  are not bit-reproducible; ``particle_dtype="float64"`` restores the precision, not the
  draws).
"""


def version_history(resample: bool) -> str:
    """The Version History of a platform's env card (with the Resample lines where it has one)."""
    return (
        PENALTY_VERSION_HISTORY + (RESAMPLE_VERSION_HISTORY if resample else "") + "* v0: initial release.\n"
    )


def fill_card(doc: str, module: str, make_core: Callable[..., Any], resample: bool) -> str:
    """A platform's env card with its placeholders filled from the code it documents.

    ``{observation_table}`` (:func:`observation_card`), ``{SIGMA_DIVERGENCE}`` (the core's
    divergence rule) and ``{version_history}`` (:func:`version_history`).
    """
    from navgym.envs.core import SIGMA_DIVERGENCE

    return (
        doc.replace("{observation_table}", observation_card(module, make_core))
        .replace("{SIGMA_DIVERGENCE}", f"{SIGMA_DIVERGENCE:g}")
        .replace("{version_history}", version_history(resample).rstrip().replace("\n", "\n    "))
    )


def observation_card(module: str, make_core: Callable[..., Any]) -> str:
    """The env card's observations, computed from the cores of ``module``'s registered ids.

    The Fading table, then each other registered observation as its changes against that table
    (dropped, resized and added columns), so the cards cannot drift from the code. ``make_core``
    is the platform module's ``_core(task, num_envs, kwargs)``.
    """
    groups: dict[tuple, tuple[Any, list[str]]] = {}  # (name, size) signature -> (features, ids)
    for env_id, mod, _prefix, task, _steps, defaults in ENVIRONMENTS:
        if mod == module:
            fs = make_core(task, 1, defaults).obs_features
            key = tuple((f.name, f.size) for f in fs.features)
            groups.setdefault(key, (fs, []))[1].append(f"``{env_id.removeprefix('navgym/')}``")
    (ref, ref_ids), *others = sorted(groups.values(), key=lambda g: "Fading" not in g[1][0])
    size = {f.name: f.size for f in ref.features}
    lines = [f"{', '.join(ref_ids)} ({ref.dim} columns):", "", ref.table()]
    if others:
        lines += ["", "The other ids change this table as listed (the other columns keep their order):", ""]
    for fs, ids in others:
        dropped = [f"``{n}``" for n in ref.names if n not in fs.names]
        parts = [f"without {', '.join(dropped)}"] if dropped else []
        i = 0
        for f in fs.features:
            span = f"{i}" if f.size == 1 else f"{i}-{i + f.size - 1}"
            unit = "" if f.unit == "-" else f" {f.unit}"
            if f.name not in size:
                parts.append(
                    f"adds ``{f.name}`` (index {span}, [{f.low:g}, {f.high:g}]{unit}: {f.description})"
                )
            elif f.size != size[f.name]:
                parts.append(f"``{f.name}`` has {f.size} columns ({span})")
            i += f.size
        text = f"* {', '.join(ids)} ({fs.dim} columns): {'; '.join(parts)}."
        lines.append(textwrap.fill(text, 96, subsequent_indent="  ", break_on_hyphens=False))
    return "\n".join(lines).replace("\n", "\n    ").replace("\n    \n", "\n\n")


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


#: Every id: the v0 ids, then v1 of the Fading and Mixture tasks (the remaining-steps penalty),
#: then v1 of the Resample tasks (roughening, remaining-steps penalty, log10 ESS/N).
ENVIRONMENTS: list[tuple[str, str, str, str, int, dict]] = (
    V0_ENVIRONMENTS
    + [_v1(e) for e in V0_ENVIRONMENTS if e[3] != "resample"]
    + [_v1(e) for e in V0_ENVIRONMENTS if e[3] == "resample"]
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
    """Silence gymnasium's "out of date" notice for the navgym ``-v0`` ids inside the block.

    For tools that use a ``-v0`` id on purpose (a zoo agent trained on it, benchmarks whose
    targets were set on it); everywhere else the notice points users to the ``-v1`` ids.
    """
    with warnings.catch_warnings():
        warnings.filterwarnings(
            "ignore", message=r".*navgym/\S*-v0 is out of date", category=DeprecationWarning
        )
        yield
