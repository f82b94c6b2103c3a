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

The task paragraphs come from each task's :class:`~navgym.envs.tasks.TaskSpec`. A platform's
``Env`` class holds its card as an :class:`EnvCard`, which fills the placeholders when the card
is first read (``Env.__doc__``, ``help``): the observation table builds a core per registered
id, which defining the class does not pay.
"""

from __future__ import annotations

import textwrap
from typing import TYPE_CHECKING, Any

from navgym.envs.build import build_core
from navgym.envs.core import SIGMA_DIVERGENCE
from navgym.envs.registration import ENVIRONMENTS
from navgym.envs.tasks import task_spec, task_title

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


def version_history(spec: PlatformSpec) -> str:
    """The Version History of a platform's env card (with its tasks' lines, e.g. the Resample's)."""
    tasks = "".join(task_spec(t).version_history for t in spec.tasks)
    return PENALTY_VERSION_HISTORY + tasks + "* v0: initial release.\n"


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


def _fill(text: str, indent: str = "    ") -> str:
    return textwrap.fill(text, 96, subsequent_indent=indent, break_on_hyphens=False, break_long_words=False)


def _value(v: object) -> str:
    if isinstance(v, tuple):
        return "(" + ", ".join(f"{x:g}" for x in v) + ")"
    return f"{v:g}" if isinstance(v, float) else repr(v)


def shared_paragraphs(spec: PlatformSpec) -> dict[str, str]:
    """The text of the shared placeholders for ``spec`` (see the module docstring)."""
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
    tasks = [task_spec(t) for t in spec.tasks]
    notes = "".join(n + " " for n in dict.fromkeys(t.card_note for t in tasks if t.card_note))
    return {
        "{action_space}": _fill(
            " ".join(t.action_text.format(dt=spec.dt) for t in tasks) + " " + ACTION_CHECKS
        ),
        "{rewards}": _fill(
            REWARDS.format(cost="".join(dict.fromkeys(t.cost_text for t in tasks)), scale=spec.error_scale_m)
        ),
        "{episode_end}": _fill(EPISODE_END.format(divergence=spec.divergence_m, sigma=SIGMA_DIVERGENCE)),
        "{common_arguments}": _fill(
            COMMON_ARGUMENTS.format(
                tasks="; ".join(t.card_arguments(spec) for t in tasks),
                clairvoyant=notes,
                steps=spec.episode_steps,
                scale=spec.error_scale_m,
                divergence=spec.divergence_m,
                scenario=", ".join(f"``{k}``" for k in spec.scenario_arguments),
                task_scenarios=task_scen,
            )
        ),
        "{version_history}": version_history(spec).rstrip().replace("\n", "\n    "),
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
    for fs, names in others:
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
        text = f"* {', '.join(names)} ({fs.dim} columns): {'; '.join(parts)}."
        lines.append(textwrap.fill(text, 96, subsequent_indent="  ", break_on_hyphens=False))
    return "\n".join(lines).replace("\n", "\n    ").replace("\n    \n", "\n\n")


def span(value: tuple[float, float], unit: str = "") -> str:
    """A scenario range ``(lo, hi)`` as card text ``"lo-hi unit"`` (one value where equal)."""
    lo, hi = value
    text = f"{lo:g}" if lo == hi else f"{lo:g}-{hi:g}"
    return f"{text} {unit}" if unit else text


class EnvCard:
    """A platform's env card, filled when first read (a descriptor held as the class's ``__doc__``).

    ``Env.__doc__`` and ``env.__doc__`` give :func:`fill_card` of the template, computed once.
    """

    def __init__(self, template: str, spec: PlatformSpec, module: str) -> None:
        self.template, self.spec, self.module = template, spec, module
        self._text: str | None = None

    def __get__(self, obj: object, owner: type | None = None) -> str:
        if self._text is None:
            self._text = fill_card(self.template, self.spec, self.module)
        return self._text

    def __str__(self) -> str:
        return self.__get__(None)


def with_paragraph(card: str, text: str, before: str = "## Action Space") -> str:
    """``card`` with ``text`` wrapped (96 columns, the cards' indent) as a paragraph before ``before``.

    The v3 classes add their context paragraph to their platform's card this way.
    """
    wrapped = textwrap.fill(
        text, 96, subsequent_indent="    ", break_on_hyphens=False, break_long_words=False
    )
    return card.replace(f"\n    {before}", f"\n    {wrapped}\n\n    {before}", 1)
