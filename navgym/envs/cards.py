"""Env cards: the paragraphs every platform shares, and the placeholders filled from the code.

A platform's card (its ``Env`` class docstring, in Gymnasium's sections) writes what is its own
and uses these placeholders for the rest, so the cards cannot drift from the code or from
each other:

* ``{action_space}``: one line per task of the platform (knob, mapping, non-finite actions);
* ``{observation_table}``: the observation of every registered id of the platform;
* ``{rewards}``: the reward, its scale and the divergence penalty;
* ``{episode_end}``: the divergence rules and what ``episode_steps`` means;
* ``{common_arguments}``: the task, core and scenario keyword arguments with their defaults;
* ``{version_history}``: the Version History section.
"""

from __future__ import annotations

import textwrap
from typing import TYPE_CHECKING, Any

from navgym.envs.core import SIGMA_DIVERGENCE
from navgym.envs.registration import ENVIRONMENTS

if TYPE_CHECKING:
    from navgym.envs.platform import PlatformSpec

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


#: One line per task of ``{action_space}``.
TASK_ACTIONS = {
    "fading": (
        "``Fading``: ``Box(-1, 1, (1,), float32)``, ``lambda = lambda_max ** ((a + 1) / 2)`` applied as "
        "``P- = lambda F P F^T + Q`` at every {dt:g} s step (``a = -1``: the plain filter)."
    ),
    "mixture": (
        "``Mixture``: ``Box(-1, 1, (1,), float32)``, ``eps = eps_max (a + 1) / 2``, measurement noise "
        "``(1 - eps) N(0, R) + eps N(0, variance_ratio R)`` on the outlier rows (Benzerrouk 2014, eq. 71); "
        "with ``per_row=True`` one weight per measurement row, ``Box(-1, 1, (m_max,), float32)``, "
        "``eps_i = eps_max (a_i + 1) / 2`` on the outlier rows (0 on the others, masked rows ignored), "
        "applied row by row (``filters.row_mixture``)."
    ),
    "resample": "``Resample``: ``Discrete(2)``, 1 = resample the particles now.",
    "noisescale": (
        "``NoiseScale``: ``Box(-1, 1, (2,), float32)``, ``s = 10 ** (lo + (a + 1) / 2 (hi - lo))`` for "
        "``[s_q, s_r]`` with ``lo, hi = log10`` of ``q_scale_range`` / ``r_scale_range`` (default 0.1 to "
        "100: ``lo = -1``, ``hi = 2``), applied as ``Q' = s_q Q`` in the prediction and ``R' = s_r R`` in "
        "the update of every {dt:g} s step (after Gao et al. 2020, Remote Sensing 12:1704); "
        "``a = -1 + 2 (-lo) / (hi - lo)`` (``-1/3`` by default) is the plain filter."
    ),
    "robust": (
        "``Robust``: ``Box(-1, 1, (1,), float32)``, the threshold ``c = 10 ** (lo + (a + 1) / 2 (hi - lo))`` "
        "with ``lo, hi = log10`` of ``threshold_range`` (default 0.5 to 1000) for ``a < 1`` and ``c = inf`` "
        "at ``a = 1`` (the plain iterated filter, the neutral action), applied as the threshold of the "
        "Huber (or Tukey, ``weight``) weights of the robust iterated update of every {dt:g} s step "
        "(Belles et al. 2022, eq. 20 and Algorithm 1; ``filters.robust.iterated_update``)."
    ),
    "jumps": (
        "``Jumps``: ``Box(-1, 1, (1,), float32)``, the jump probability per code period "
        "``p = 10 ** (lo + (a + 1) / 2 (hi - lo))`` with ``lo, hi = log10`` of ``jump_range`` (default 1e-5 "
        "to 0.1) of every particle of the random Dirac-Gauss PF over the {dt:g} s step (Dirac-Gauss DPF "
        "n.d., §2.1; ``navgym.signal_tracking.task``); ``a = 0.1505`` (``p = 2e-3``) is the plain filter."
    ),
}
ACTION_CHECKS = (
    "Non-finite actions raise ``ValueError``; Box actions outside [-1, 1] are clipped and counted in "
    '``info["action_clipped"]``.'
)
REWARDS = (
    "``r = -min(pos_err_m / error_scale_m, reward_clip){cost}``, with the horizontal position error "
    "``pos_err_m``, ``error_scale_m = {scale:g}`` m and ``reward_clip = 10``: 0 is perfect, -1 is a "
    '{scale:g} m horizontal error. The terms are in ``info["reward_terms"]``. Divergence (see Episode '
    "End) ends the episode with an extra ``-divergence_penalty = -100``."
)
EPISODE_END = (
    "Termination on divergence: the filter's health flag is False, the horizontal error exceeds "
    "``divergence_m = {divergence:g}`` m, or the filter's horizontal sigma ``sqrt(tr P_ne)`` exceeds "
    "``SIGMA_DIVERGENCE x divergence_m`` (``navgym.envs.core.SIGMA_DIVERGENCE = {sigma:g}``: a runaway "
    "covariance, e.g. extreme fading through an outage, ended before it overflows, however small the "
    "error). ``episode_steps`` sets the simulated episode (truth and scenario timing); "
    "``max_episode_steps`` only cuts it short, so a single env and a vector env built with the same "
    "keyword arguments simulate the same episodes."
)
#: The ``clairvoyant`` argument of the Fading, Mixture and NoiseScale tasks (see CLAIRVOYANT_TEXT).
CLAIRVOYANT = "``clairvoyant=False``"
#: Tasks with a ``clairvoyant`` argument.
CLAIRVOYANT_TASKS = frozenset({"fading", "mixture", "noisescale", "robust"})
#: What ``clairvoyant`` means (in ``{common_arguments}``).
CLAIRVOYANT_TEXT = (
    "``clairvoyant=True`` (Fading, Mixture, NoiseScale, Robust) is for evaluation only: the upper reference, "
    "never a baseline; the knob is ignored and the plain filter runs with the step's true ``Q``, ``R`` "
    "and measurement bias (``StepModels.truth`` of a v2 platform; it raises "
    "``navgym.envs.tasks.NoTruthError`` where the platform gives none)."
)
TASK_ARGUMENT_TEXT = {
    "fading": (
        '``Fading``: ``filter="ekf"`` (any Gaussian filter of :mod:`filters.registry`: ``"ekf"``, '
        '``"ukf"``, ``"ckf"``, ``"ghkf"``, ...), ``lambda_max={lambda_max}``, ' + CLAIRVOYANT
    ),
    "mixture": (
        '``Mixture``: ``filter="ckf"``, ``eps_max=0.5``, ``variance_ratio=100``, ``per_row=False`` '
        "(True: one weight per row, observing each row's posterior outlier weight), " + CLAIRVOYANT
    ),
    "noisescale": (
        '``NoiseScale``: ``filter="ekf"`` (any Gaussian filter of :mod:`filters.registry`), '
        "``q_scale_range=(0.1, 100)``, ``r_scale_range=(0.1, 100)`` (``(s_lo, s_hi)`` with "
        "``0 < s_lo <= 1 <= s_hi``), " + CLAIRVOYANT
    ),
    "robust": (
        '``Robust``: ``weight="huber"`` (or ``"tukey"``), ``threshold_range=(0.5, 1000)`` (``(c_lo, c_hi)``, '
        "``0 < c_lo < c_hi < inf``), " + CLAIRVOYANT
    ),
    "jumps": (
        "``Jumps``: ``n_particles=128``, ``jump_range=(1e-5, 0.1)`` (``(p_lo, p_hi)``, ``0 < p_lo <= 2e-3 <= "
        "p_hi <= 1``), ``ess_threshold=0.5``, ``clairvoyant=False`` (True, evaluation only: the knob set "
        "from the true jump steps, see the Description)"
    ),
    "resample": (
        '``Resample``: ``n_particles=1000``, ``resample_cost=0.05``, ``method="systematic"``, '
        '``roughening=0.0`` (v1: 0.2), ``log_ess_feature=False`` (v1: True), ``particle_dtype="float32"`` '
        "(the cloud's precision; weights, moments and diagnostics stay float64)"
    ),
}
COMMON_ARGUMENTS = (
    "Task arguments: {tasks}. {clairvoyant}Core arguments: ``max_episode_steps``, ``episode_steps={steps}``, "
    "``error_scale_m={scale:g}``, ``divergence_m={divergence:g}``, ``reward_clip=10.0``, "
    "``divergence_penalty=100.0``, ``eval_info=True``, ``render_mode=None``, "
    "``memory_features=False`` (True: the observation also carries averages of the innovations over "
    "past steps, see :mod:`navgym.envs.memory`) and "
    "``penalize_remaining_steps=False`` (v1: True): the divergence penalty becomes "
    "``divergence_penalty + reward_clip x steps not played`` (of the simulated ``episode_steps``, also "
    "where ``max_episode_steps`` truncates earlier: a single env cannot see gym.make's ``TimeLimit``, "
    "and single and vector envs give the same reward). Scenario arguments (durations in seconds, see "
    ":class:`navgym.scenarios.ScenarioDistribution`): {scenario}; task defaults: {task_scenarios}. "
    '``reset(options={{"scenario": navgym.scenarios.Scenario(...)}})`` pins a scenario.'
)


def task_title(task: str) -> str:
    """A task's name in ids and cards: ``"fading"`` -> ``"Fading"``, ``"noisescale"`` -> ``"NoiseScale"``."""
    return TASK_TITLES.get(task, task.capitalize())


#: Task names that :meth:`str.capitalize` does not spell.
TASK_TITLES = {"noisescale": "NoiseScale"}


def _fill(text: str, indent: str = "    ") -> str:
    return textwrap.fill(text, 96, subsequent_indent=indent, break_on_hyphens=False, break_long_words=False)


def _value(v: object) -> str:
    if isinstance(v, tuple):
        return "(" + ", ".join(f"{x:g}" for x in v) + ")"
    return f"{v:g}" if isinstance(v, float) else repr(v)


def shared_paragraphs(spec: PlatformSpec) -> dict[str, str]:
    """The text of the shared placeholders for ``spec`` (see the module docstring)."""
    lam = "10.0" if spec.lambda_max_per_second is None else f"{spec.lambda_max_per_second**spec.dt:.4g}"
    # tasks with the same defaults (the v2 ids': one set of events) are listed once
    groups: list[tuple[list[str], Any]] = []
    for t, d in spec.tasks.items():
        same = [g for g in groups if g[1] == d]
        if same:
            same[0][0].append(f"``{task_title(t)}``")
        else:
            groups.append(([f"``{task_title(t)}``"], d))
    task_scen = "; ".join(
        (names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]} each")
        + " "
        + ", ".join(f"``{k}={_value(v)}``" for k, v in d.items())
        for names, d in groups
    )
    return {
        "{action_space}": _fill(
            " ".join(TASK_ACTIONS[t].format(dt=spec.dt) for t in spec.tasks) + " " + ACTION_CHECKS
        ),
        "{rewards}": _fill(
            REWARDS.format(
                cost=" - resample_cost * resampled" if "resample" in spec.tasks else "",
                scale=spec.error_scale_m,
            )
        ),
        "{episode_end}": _fill(EPISODE_END.format(divergence=spec.divergence_m, sigma=SIGMA_DIVERGENCE)),
        "{common_arguments}": _fill(
            COMMON_ARGUMENTS.format(
                tasks="; ".join(TASK_ARGUMENT_TEXT[t].format(lambda_max=lam) for t in spec.tasks),
                clairvoyant=CLAIRVOYANT_TEXT + " " if CLAIRVOYANT_TASKS & set(spec.tasks) else "",
                steps=spec.episode_steps,
                scale=spec.error_scale_m,
                divergence=spec.divergence_m,
                scenario=", ".join(f"``{k}``" for k in spec.scenario_arguments),
                task_scenarios=task_scen,
            )
        ),
        "{version_history}": version_history("resample" in spec.tasks).rstrip().replace("\n", "\n    "),
    }


def fill_card(doc: str, spec: PlatformSpec, module: str) -> str:
    """A platform's env card with every placeholder filled (see the module docstring)."""
    for key, text in shared_paragraphs(spec).items():
        doc = doc.replace(key, text)
    return doc.replace("{observation_table}", observation_card(spec, module))


def observation_card(spec: PlatformSpec, module: str) -> str:
    """The env card's observations, computed from the cores of ``module``'s registered ids.

    (Of the platform's tasks with default arguments when ``module`` has no registered id.)

    The Fading table, then each other registered observation as its changes against that table
    (dropped, resized and added columns), so the cards cannot drift from the code.
    """
    from navgym.envs.platform import build_core

    registered = [(e[0], e[3], e[5]) for e in ENVIRONMENTS if e[1] == module]
    # a platform not (yet) registered: its tasks with the default arguments
    ids = registered or [(f"{spec.name}{task_title(task)}", task, {}) for task in spec.tasks]
    groups: dict[tuple, tuple[Any, list[str]]] = {}  # (name, size) signature -> (features, ids)
    for env_id, task, defaults in ids:
        fs = build_core(spec, task, 1, defaults).obs_features
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


def span(value: tuple[float, float], unit: str = "") -> str:
    """A scenario range ``(lo, hi)`` as card text ``"lo-hi unit"`` (one value where equal)."""
    lo, hi = value
    text = f"{lo:g}" if lo == hi else f"{lo:g}-{hi:g}"
    return f"{text} {unit}" if unit else text
