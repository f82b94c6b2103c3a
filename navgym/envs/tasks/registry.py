"""Tasks by name: a :class:`TaskSpec` per task, declared next to its code and registered once.

A task's spec holds everything about it that is not its filter step: its title in ids and cards,
its keyword arguments (each declared once with its rule and documentation,
:class:`~navgym.envs.arguments.Argument`), its card text, whether it offers the clairvoyant
reference, the options it takes from the platform, and the family of baselines that steer it
(the key of ``agents.baselines.registry.BASELINES``). The built-in tasks register theirs when
:mod:`navgym.envs.tasks` is imported; a platform registers its own special tasks from its own
package (SignalTracking's Jumps task, :mod:`navgym.signal_tracking.task`), so the core imports
no platform. ``docs/add_a_task.md`` is the checklist.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from navgym.envs.arguments import Argument
from navgym.envs.protocols import Platform, Task

if TYPE_CHECKING:
    from navgym.envs.platform import PlatformSpec


@dataclass(frozen=True)
class TaskSpec:
    """What a task declares besides its code (see the module docstring).

    Attributes:
        name: The task's key, the ``task=`` of the environments (``"noisescale"``).
        title: Its name in ids and cards (``"NoiseScale"``: ``navgym/GpsInsNoiseScale-v2``).
        cls: The task's class; ``cls(**options)`` builds it.
        arguments: Its keyword arguments of the environments, each with its rule.
        action_text: Its line of the cards' ``{action_space}`` (``{dt:g}``: the platform's step).
        argument_text: Its part of the cards' ``{common_arguments}``; ``{key}`` fields are filled
            from ``card_fields(platform_spec)``.
        baseline: The family of baselines that steer it (``agents.baselines.registry``).
        clairvoyant: Whether it takes ``clairvoyant=True`` (an evaluation-only reference).
        card_note: A paragraph of the cards after the task arguments (once per card, however
            many of the platform's tasks share it; e.g. what ``clairvoyant`` means).
        cost_text: The reward's cost term in the cards (``" - resample_cost * resampled"``).
        version_history: Lines of the cards' Version History about this task.
        scenario_defaults: Scenario keyword arguments every platform's episodes of this task
            default to, under the platform's own defaults for the task.
        platform_defaults: Options the task takes from the platform (``(platform_spec,
            platform) -> dict``), under the user's keyword arguments (e.g. the Mixture task's
            ``outlier_rows`` and ``m_max``).
        card_fields: The fields of ``argument_text`` for a platform (e.g. its ``lambda_max``).
        state_bytes: Bytes the task's own state of one episode takes at its peak in a step
            (``(task, platform) -> int``; a particle cloud and its temporaries), counted with the
            episodes against :data:`navgym.envs.build.MAX_EPISODE_BYTES` at ``make``; None: small.
        memory_arguments: The task's arguments ``state_bytes`` grows with (named in the error).
    """

    name: str
    title: str
    cls: Callable[..., Task]
    arguments: tuple[Argument, ...]
    action_text: str
    argument_text: str
    baseline: str
    clairvoyant: bool = False
    card_note: str = ""
    cost_text: str = ""
    version_history: str = ""
    scenario_defaults: Mapping[str, Any] = field(default_factory=dict)
    platform_defaults: Callable[[PlatformSpec, Platform], dict[str, Any]] | None = None
    card_fields: Callable[[PlatformSpec], Mapping[str, str]] | None = None
    state_bytes: Callable[[Any, Platform], int] | None = None
    memory_arguments: tuple[str, ...] = ()

    @property
    def argument_names(self) -> tuple[str, ...]:
        """The names of :attr:`arguments`, in their order."""
        return tuple(a.name for a in self.arguments)

    def argument(self, name: str) -> Argument:
        """The declared argument ``name`` (``KeyError`` if the task has none of that name)."""
        for a in self.arguments:
            if a.name == name:
                return a
        raise KeyError(f"the {self.title} task has no argument {name!r}")

    def options(self, platform_spec: PlatformSpec, platform: Platform, kwargs: Mapping[str, Any]) -> dict:
        """The task's options on ``platform``: its :attr:`platform_defaults` under ``kwargs``."""
        base = {} if self.platform_defaults is None else self.platform_defaults(platform_spec, platform)
        return {**base, **kwargs}

    def card_arguments(self, platform_spec: PlatformSpec) -> str:
        """:attr:`argument_text` with its fields filled for ``platform_spec``."""
        fields = {} if self.card_fields is None else self.card_fields(platform_spec)
        return self.argument_text.format(**fields)


_SPECS: dict[str, TaskSpec] = {}


def register_task(spec: TaskSpec) -> TaskSpec:
    """Register ``spec`` under ``spec.name`` (again the same spec: nothing changes); return it.

    Raises:
        ValueError: another spec is registered under that name, or the name is not lower case.
    """
    if spec.name != spec.name.lower():
        raise ValueError(
            f"a task's name is its lower-case key (task={spec.name.lower()!r}); got {spec.name!r}"
        )
    old = _SPECS.get(spec.name)
    if old is not None and old != spec:
        raise ValueError(f"another task is registered as {spec.name!r} ({old.cls.__qualname__})")
    _SPECS[spec.name] = spec
    return spec


def task_spec(name: str) -> TaskSpec:
    """The registered spec of task ``name`` (case-insensitive).

    Raises:
        ValueError: listing the registered tasks, when none is registered as ``name`` (a
            platform's own task is registered when its package's module is imported).
    """
    try:
        return _SPECS[name.lower()]
    except (KeyError, AttributeError):
        raise ValueError(f"task must be one of {sorted(_SPECS)}; got {name!r}") from None


def task_specs() -> tuple[TaskSpec, ...]:
    """Every registered spec, in the order of registration."""
    return tuple(_SPECS.values())


def task_title(name: str) -> str:
    """A task's title in ids and cards (``"noisescale"`` -> ``"NoiseScale"``).

    Its spec's :attr:`~TaskSpec.title`; ``name.capitalize()`` for a name not registered.
    """
    spec = _SPECS.get(name.lower())
    return name.capitalize() if spec is None else spec.title


def make_task(task: str, **kwargs: Any) -> Task:
    """Build the registered task ``task`` with its options ``kwargs`` (``ValueError`` if unknown).

    ``kwargs`` are the class's keyword arguments (an environment's task arguments with the
    options the spec takes from the platform, :meth:`TaskSpec.options`).
    """
    return task_spec(task).cls(**kwargs)
