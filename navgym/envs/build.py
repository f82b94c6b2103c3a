"""Building a platform's core from the keyword arguments of an environment.

:func:`build_core` is what every platform's ``Env`` and ``VectorEnv`` run when they are made: it
reads the keyword arguments in three groups, each checked before anything is simulated (a value
of the wrong type, a non-finite or out-of-range one raises a ``TypeError`` or ``ValueError``
naming it; an unknown keyword an :class:`~navgym.envs.arguments.UnknownKeywordError`):

* the platform's (:func:`make_platform`): ``episode_steps``, ``dt`` where the platform takes it,
  the scenario arguments over the task's defaults (checked by
  :class:`~navgym.scenarios.ScenarioDistribution`), ``error_scale_m``, ``divergence_m`` and the
  platform's own (its ``PlatformSpec.build``);
* the task's: the arguments its :class:`~navgym.envs.tasks.TaskSpec` declares, over the options
  the task takes from the platform (:meth:`~navgym.envs.tasks.TaskSpec.options`);
* the core's (:data:`navgym.envs.core.CORE_ARGUMENTS`).

So is the memory the episodes of one batch will take: ``num_envs *
platform.episode_bytes(episode_steps)`` must not exceed :data:`MAX_EPISODE_BYTES` (4 GiB), so a
horizon or batch too large for the machine is refused at ``make`` rather than failing (or
swapping) at ``reset``; with a task that declares its state's size (a particle cloud,
``TaskSpec.state_bytes``) the episodes and the task states of the batch together. The task's
options must fit the platform (:func:`check_task_fits`: a filter that runs on its state size,
``clairvoyant`` only where it gives the true noise), and an unknown keyword is named with the
closest known one or the task it belongs to (:func:`unknown_keywords`). This module reads a
:class:`~navgym.envs.platform.PlatformSpec` and imports no platform.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, NamedTuple

from filters.registry import state_dim_error
from navgym.envs import arguments
from navgym.envs.arguments import UnknownKeywordError
from navgym.envs.core import CORE_ARGUMENTS, NavCore
from navgym.envs.protocols import Platform
from navgym.envs.tasks import make_task, task_spec, task_specs
from navgym.scenarios import ScenarioDistribution
from navgym.scenarios.pinned import modelled_events

if TYPE_CHECKING:
    from navgym.envs.platform import PlatformSpec
    from navgym.envs.tasks import TaskSpec

#: Most memory [bytes] the simulated episodes of one batch may take: ``num_envs *
#: platform.episode_bytes(episode_steps)`` (truth, sensor data and the peak of their simulation at
#: reset) must not exceed it, nor, for a task that declares its state's size (a particle cloud:
#: ``TaskSpec.state_bytes``), ``num_envs`` times the episode and the task's state together, or
#: ``make`` raises a ``ValueError``. Read when an environment is made: assign to it to allow more.
MAX_EPISODE_BYTES = 4 * 2**30
#: Keyword arguments every platform reads through the skeleton (``dt`` only where
#: ``PlatformSpec.dt_argument``).
COMMON_PLATFORM_ARGUMENTS = ("episode_steps", "dt", "error_scale_m", "divergence_m")
#: Longest simulated horizon ``episode_steps`` of any platform (a bound on the numbers; the memory
#: bound :data:`MAX_EPISODE_BYTES` usually refuses far shorter ones).
MAX_EPISODE_STEPS = 10**8


class PlatformArgs(NamedTuple):
    """What ``PlatformSpec.build`` receives: the task and the arguments already resolved."""

    task: str  #: the task's name ("fading", "mixture", ...)
    kwargs: dict[str, Any]  #: the remaining keyword arguments; ``build`` pops its own
    steps: int  #: simulated horizon ``episode_steps``
    dt: float  #: filter step [s]
    scenarios: ScenarioDistribution
    error_scale_m: float
    divergence_m: float


def make_platform(spec: PlatformSpec, task: str, kwargs: dict[str, Any]) -> tuple[Any, int]:
    """The platform of ``spec`` for ``task`` and its horizon, popping their arguments from ``kwargs``.

    Reads ``episode_steps``, ``dt`` (where the platform takes it), the scenario arguments (over
    the task's defaults: the task spec's ``scenario_defaults`` under the platform's for the
    task), ``error_scale_m``, ``divergence_m``, then the platform's own arguments
    (``spec.build``). What remains in ``kwargs`` is for the task and the core.

    ``episode_steps`` lies in ``[1, MAX_EPISODE_STEPS]`` and ``dt`` in ``(0, spec.dt_max]``; the
    scenario arguments are checked by :class:`ScenarioDistribution`, the platform's own by
    ``build``.
    """
    arguments.choice("task", task, spec.tasks)
    if spec.prepare is not None:
        spec.prepare(task, kwargs)
    steps = arguments.integer(
        "episode_steps", kwargs.pop("episode_steps", spec.episode_steps), 1, MAX_EPISODE_STEPS
    )
    dt = spec.dt
    if spec.dt_argument:
        dt = arguments.real("dt", kwargs.pop("dt", spec.dt), 0.0, spec.dt_max, low_open=True)
    scenario = {**task_spec(task).scenario_defaults, **spec.tasks[task]}
    scenario.update({k: kwargs.pop(k) for k in spec.scenario_arguments if k in kwargs})
    scenario["duration"] = steps * dt
    scenario.setdefault("start_margin", min(spec.start_margin_s, 0.1 * steps * dt))
    scale = arguments.real(
        "error_scale_m", kwargs.pop("error_scale_m", spec.error_scale_m), 0.0, low_open=True
    )
    bound = arguments.real("divergence_m", kwargs.pop("divergence_m", spec.divergence_m), 0.0, low_open=True)
    if spec.platform_arguments is None:
        own = kwargs
    else:
        own = {k: kwargs.pop(k) for k in spec.platform_arguments if k in kwargs}
    args = PlatformArgs(task, own, steps, dt, ScenarioDistribution(**scenario), scale, bound)
    platform = spec.build(args)
    if spec.platform_arguments is not None and own:
        raise RuntimeError(
            f"the {spec.name} platform declares {sorted(own)} in platform_arguments but build "
            "did not read them"
        )
    return platform, steps


def check_episode_memory(platform: Platform, num_envs: int, steps: int) -> None:
    """Refuse a batch whose episodes would take more than :data:`MAX_EPISODE_BYTES` (``ValueError``).

    ``platform.episode_bytes(steps)`` estimates one episode (before anything is allocated).
    """
    per = int(platform.episode_bytes(steps))
    need = num_envs * per
    if need > MAX_EPISODE_BYTES:
        raise ValueError(
            f"episode_steps={steps} with num_envs={num_envs} would take about {need / 2**30:.3g} GiB "
            f"for the simulated episodes ({per / 2**20:.3g} MiB each), more than MAX_EPISODE_BYTES = "
            f"{MAX_EPISODE_BYTES / 2**30:.3g} GiB (navgym.envs.build.MAX_EPISODE_BYTES): lower "
            "episode_steps or num_envs"
        )


def check_task_fits(declared: TaskSpec, options: Mapping[str, Any], platform: Platform) -> None:
    """Refuse task options that cannot run on ``platform`` (``ValueError`` naming the argument).

    * ``filter``: a Gaussian filter must run on the platform's state size (a Gauss-Hermite rule
      takes ``p**n`` points: ``"ghkf"`` and ``"ghkf5"`` on a 15-state platform are refused,
      :func:`filters.registry.state_dim_error`);
    * ``clairvoyant=True`` needs the step's true noise, which a platform made with
      ``true_noise=False`` (the v0/v1 ids) does not give.
    """
    name = options.get("filter")
    if isinstance(name, str):
        why = state_dim_error(name, int(platform.n))
        if why is not None:
            raise ValueError(f"{why}; choose another filter (e.g. 'ukf' or 'ckf', 2n points)")
    if options.get("clairvoyant") is True and getattr(platform, "true_noise", True) is False:
        raise ValueError(
            f"clairvoyant=True runs the filter with the step's true noise, which the {declared.title} "
            f"task's platform here does not give (true_noise=False: the v0/v1 ids); use a v2 id"
        )


def check_task_memory(declared: TaskSpec, task: Any, platform: Platform, num_envs: int, steps: int) -> None:
    """Refuse a batch whose episodes and task states would take more than :data:`MAX_EPISODE_BYTES`.

    The task's state of one episode is ``declared.state_bytes(task, platform)`` (a particle
    cloud at its peak in a step; tasks that declare none are small); with the episodes'
    ``platform.episode_bytes(steps)``, ``num_envs`` of them must fit. The ``ValueError`` names
    the task's :attr:`~navgym.envs.tasks.TaskSpec.memory_arguments` and ``num_envs``.
    """
    if declared.state_bytes is None:
        return
    per_task = int(declared.state_bytes(task, platform))
    per_episode = int(platform.episode_bytes(steps))
    need = num_envs * (per_task + per_episode)
    if need > MAX_EPISODE_BYTES:
        values = [f"{a}={_shown(getattr(task, a, None))}" for a in declared.memory_arguments]
        names = " or ".join([*declared.memory_arguments, "num_envs"])
        raise ValueError(
            f"{', '.join(values)} with num_envs={num_envs} would take about {need / 2**30:.3g} GiB "
            f"({per_task / 2**20:.3g} MiB of {declared.title} state at its peak in a step and "
            f"{per_episode / 2**20:.3g} MiB of simulated episode per sub-env), more than "
            f"MAX_EPISODE_BYTES = {MAX_EPISODE_BYTES / 2**30:.3g} GiB (navgym.envs.build.MAX_EPISODE_BYTES): "
            f"lower {names}"
        )


def _shown(value: Any) -> str:
    """``value`` as its keyword argument is written (a NumPy dtype as its name)."""
    return repr(value) if isinstance(value, (int, float, str)) else repr(str(value))


def unknown_keywords(spec: PlatformSpec, task: str, unknown: Mapping[str, Any]) -> UnknownKeywordError:
    """The error for the keyword arguments ``unknown`` of ``spec``'s platform under ``task``.

    It lists them and, for each, where it belongs: another task's argument names that task (a
    Mixture argument on a Fading id), otherwise the closest known keyword is suggested
    (``filtr`` -> ``filter``).
    """
    declared = task_spec(task)
    known = (
        "task",
        *spec.keyword_arguments,
        *declared.argument_names,
        *(a.name for a in CORE_ARGUMENTS),
    )
    notes = []
    for name in sorted(unknown):
        owners = [s.title for s in task_specs() if s.name != declared.name and name in s.argument_names]
        close = difflib.get_close_matches(name, known, n=1)
        if owners:
            notes.append(
                f"{name!r} is an argument of the {' and '.join(owners)} task"
                f"{'s' if len(owners) > 1 else ''}, not of {declared.title} (this id's task)"
            )
        elif close:
            notes.append(f"{name!r}: did you mean {close[0]!r}?")
    text = f"unexpected keyword arguments: {sorted(unknown)}"
    return UnknownKeywordError(text + ("; " + "; ".join(notes) if notes else ""))


def build_core(spec: PlatformSpec, task: str, num_envs: int, kwargs: Mapping[str, Any]) -> NavCore:
    """A :class:`NavCore` of ``spec``'s platform under ``task`` from the env keyword arguments.

    ``episode_steps`` is the simulated horizon (truth, scenario timing); ``max_episode_steps``
    (when given, as ``gym.make_vec`` does) only truncates earlier. ``gym.make`` keeps
    ``max_episode_steps`` for its ``TimeLimit`` wrapper, so a single env and a vector env built
    with the same keyword arguments simulate identical episodes. Unknown keyword arguments
    raise :class:`~navgym.envs.arguments.UnknownKeywordError`.
    """
    kwargs = dict(kwargs)
    num_envs = arguments.integer("num_envs", num_envs, 1)
    platform, steps = make_platform(spec, task, kwargs)
    check_episode_memory(platform, num_envs, steps)
    declared = task_spec(task)
    task_opts = {k: kwargs.pop(k) for k in declared.argument_names if k in kwargs}
    core_opts = {a.name: kwargs.pop(a.name) for a in CORE_ARGUMENTS if a.name in kwargs}
    if kwargs:
        raise unknown_keywords(spec, task, kwargs)
    truncate = core_opts.pop("max_episode_steps", None)
    options = declared.options(spec, platform, task_opts)
    check_task_fits(declared, options, platform)
    task_obj = make_task(task, **options)
    check_task_memory(declared, task_obj, platform, num_envs, steps)
    core = NavCore(platform, task_obj, num_envs, steps, truncate_steps=truncate, **core_opts)
    core.modelled_events = modelled_events(spec.scenario_arguments, spec.tasks.values())
    return core
