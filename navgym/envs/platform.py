"""The platform skeleton: a platform declares what differs, this module provides the rest.

A platform (an estimation problem: GpsIns, Quadrotor, Robot2d) writes

* its problem, a frozen dataclass deriving from :class:`PlatformBase` that implements the
  :class:`~navgym.envs.protocols.Platform` members specific to it (``simulate``,
  ``initial_belief``, ``step_models``, ``position_error``, its features);
* a :class:`PlatformSpec`: its name, tasks with their scenario defaults, default horizon and
  reward scales, and ``build``, which makes the problem from the platform's own keyword
  arguments (read with :mod:`navgym.envs.arguments`);
* its env card (the class docstring) and two one-line classes::

      class GpsInsEnv(PlatformEnv, spec=GPS_INS):
          '''card'''

      class GpsInsVectorEnv(PlatformVectorEnv, spec=GPS_INS):
          '''Native batched GpsIns environment.'''

Everything else is shared: the keyword arguments common to all environments (task, filter,
horizon, reward, scenario distribution), the core (:class:`~navgym.envs.core.NavCore`), the
single and vector environment shells (:mod:`navgym.envs.base`), the innovation / NIS /
covariance features (:mod:`navgym.envs.features`), the divergence rules and the common card
paragraphs (:mod:`navgym.envs.cards`).

Every keyword argument is checked when the environment is made, before anything is simulated
(:mod:`navgym.envs.arguments`; the scenario arguments by
:class:`~navgym.scenarios.ScenarioDistribution`): a value of the wrong type, a non-finite or
out-of-range one raises a ``TypeError`` or ``ValueError`` naming it. So is the memory the
episodes of one batch will take: ``num_envs * platform.episode_bytes(episode_steps)`` must not
exceed :data:`MAX_EPISODE_BYTES` (4 GiB), so a horizon or batch too large for the machine is
refused at ``make`` rather than failing (or swapping) at ``reset``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, NamedTuple

import numpy as np

from navgym.envs import arguments
from navgym.envs.arguments import UnknownKeywordError
from navgym.envs.base import NavEnv, NavVectorEnv
from navgym.envs.core import NavCore
from navgym.envs.tasks import make_task
from navgym.scenarios import Scenario, ScenarioDistribution

#: Most memory [bytes] the simulated episodes of one batch may take: ``num_envs *
#: platform.episode_bytes(episode_steps)`` (truth, sensor data and the peak of their simulation at
#: reset; a task's own state, such as a particle cloud, is the task's) must not exceed it, or
#: ``make`` raises a ``ValueError``. Read when an environment is made: assign to it to allow more.
MAX_EPISODE_BYTES = 4 * 2**30
#: Keyword arguments every platform reads through the skeleton (``dt`` only where
#: :attr:`PlatformSpec.dt_argument`).
COMMON_PLATFORM_ARGUMENTS = ("episode_steps", "dt", "error_scale_m", "divergence_m")
#: Longest simulated horizon ``episode_steps`` of any platform (a bound on the numbers; the memory
#: bound :data:`MAX_EPISODE_BYTES` usually refuses far shorter ones).
MAX_EPISODE_STEPS = 10**8


class PlatformBase:
    """Members of the :class:`~navgym.envs.protocols.Platform` protocol with shared defaults.

    Subclasses are frozen dataclasses with at least the fields ``scenarios``
    (:class:`ScenarioDistribution`), ``dt``, ``m_max``, ``error_scale_m`` and ``divergence_m``.
    """

    #: Fields of the episodes that ``step_models`` advances (none by default).
    episode_cursors: ClassVar[tuple[str, ...]] = ()
    scenarios: ScenarioDistribution
    m_max: int
    error_scale_m: float
    divergence_m: float

    @property
    def gnss_rows(self) -> tuple[int, ...]:
        """Measurement rows that are GNSS (default: every row)."""
        return tuple(range(self.m_max))

    @property
    def outlier_rows(self) -> tuple[int, ...]:
        """Rows subject to impulsive noise, which the Mixture task inflates (default: the GNSS rows)."""
        return self.gnss_rows

    def sample_scenario(self, rng: np.random.Generator) -> Scenario:
        """One scenario of the platform's distribution."""
        return self.scenarios.sample(rng)

    def sample_scenarios(self, rngs: Sequence[np.random.Generator]) -> list[Scenario]:
        """``[self.sample_scenario(r) for r in rngs]``, the same draws, batched."""
        return list(self.scenarios.sample_many(list(rngs)))

    def episode_bytes(self, T: int) -> int:
        """Bytes one episode of ``T`` steps takes at reset (a rough default for new platforms).

        Platforms override it with the size of their per-episode arrays; this default counts
        ``T + 1`` steps of the state, the measurements and their mask, times four for the
        temporaries of the simulation.
        """
        n = int(getattr(self, "n", 1))
        return 4 * (T + 1) * (8 * n + 9 * int(self.m_max))

    def check_reward_scales(self) -> None:
        """``error_scale_m`` and ``divergence_m`` are finite and positive (``ValueError`` otherwise)."""
        arguments.real("error_scale_m", self.error_scale_m, 0.0, low_open=True)
        arguments.real("divergence_m", self.divergence_m, 0.0, low_open=True)


class PlatformArgs(NamedTuple):
    """What :attr:`PlatformSpec.build` receives: the task and the arguments already resolved."""

    task: str  #: "fading", "mixture", "resample", "noisescale" or "robust"
    kwargs: dict[str, Any]  #: the remaining keyword arguments; ``build`` pops its own
    steps: int  #: simulated horizon ``episode_steps``
    dt: float  #: filter step [s]
    scenarios: ScenarioDistribution
    error_scale_m: float
    divergence_m: float


@dataclass(frozen=True)
class PlatformSpec:
    """What a platform declares to get its environments (see the module docstring).

    Attributes:
        name: Platform name, the prefix of its ids (``navgym/<name><Task>-v<k>``).
        build: Makes the platform from :class:`PlatformArgs`, popping its own keyword arguments.
        tasks: Scenario defaults per supported task (the degradations that make its knob matter).
        scenario_arguments: Keyword arguments passed to :class:`ScenarioDistribution`.
        platform_arguments: The platform's own keyword arguments, those ``build`` reads (it then
            sees only these; None: every keyword argument the skeleton leaves, as before).
        episode_steps: Default simulated horizon [steps].
        dt: Default filter step [s].
        dt_argument: Whether ``dt`` is a keyword argument (else fixed at ``dt``).
        dt_max: Largest ``dt`` [s] the platform accepts (``dt`` lies in ``(0, dt_max]``).
        error_scale_m: Default position error giving reward -1 [m].
        divergence_m: Default position error ending an episode [m].
        start_margin_s: No degradation starts before ``min(start_margin_s, 10 % of the episode)``.
        lambda_max_per_second: The Fading task's default ``lambda_max`` is this to the power
            ``dt`` (None: the task's own default).
        prepare: Optional check or rewrite of the raw keyword arguments before anything is
            read (e.g. GpsIns' fixed critical scenario).

    """

    name: str
    build: Callable[[PlatformArgs], Any]
    tasks: Mapping[str, Mapping[str, Any]]
    scenario_arguments: tuple[str, ...]
    episode_steps: int
    dt: float
    error_scale_m: float
    divergence_m: float
    dt_argument: bool = True
    dt_max: float = math.inf
    start_margin_s: float = 10.0
    lambda_max_per_second: float | None = None
    prepare: Callable[[str, dict[str, Any]], None] | None = None
    platform_arguments: tuple[str, ...] | None = None

    @property
    def keyword_arguments(self) -> tuple[str, ...]:
        """Every keyword argument of the platform: the common ones, its own, the scenario's."""
        common = tuple(k for k in COMMON_PLATFORM_ARGUMENTS if k != "dt" or self.dt_argument)
        return common + tuple(self.platform_arguments or ()) + tuple(self.scenario_arguments)

    def core(self, task: str, num_envs: int = 1, kwargs: Mapping[str, Any] | None = None) -> NavCore:
        """:func:`build_core` of this platform (for tests, baselines and benchmarks)."""
        return build_core(self, task, num_envs, kwargs or {})

    def platform(self, task: str, kwargs: Mapping[str, Any] | None = None) -> Any:
        """:func:`make_platform` of this platform; every keyword argument must be the platform's."""
        kwargs = dict(kwargs or {})
        out, _ = make_platform(self, task, kwargs)
        if kwargs:
            raise UnknownKeywordError(f"not arguments of the {self.name} platform: {sorted(kwargs)}")
        return out

    #: Keyword arguments of the tasks (shared by every platform): :data:`TASK_ARGUMENTS` and
    #: the opt-in :data:`V2_TASK_ARGUMENTS`.
    task_arguments: Mapping[str, tuple[str, ...]] = field(
        default_factory=lambda: {t: a + V2_TASK_ARGUMENTS.get(t, ()) for t, a in TASK_ARGUMENTS.items()},
        compare=False,
    )


#: Task keyword arguments and the task option they set.
TASK_ARGUMENTS: dict[str, tuple[str, ...]] = {
    "fading": ("filter", "lambda_max"),
    "mixture": ("filter", "eps_max", "variance_ratio"),
    "resample": ("n_particles", "resample_cost", "method", "roughening", "log_ess_feature", "particle_dtype"),
    "noisescale": ("filter", "q_scale_range", "r_scale_range", "clairvoyant"),
    "robust": ("weight", "threshold_range", "clairvoyant"),
    "jumps": ("n_particles", "jump_range", "ess_threshold", "clairvoyant"),
}
#: Opt-in (v2) arguments of the v0/v1 tasks, whose defaults keep their behaviour: the per-row
#: Mixture (``per_row``) and the clairvoyant reference (``clairvoyant``, evaluation only). Read
#: like :data:`TASK_ARGUMENTS` (``PlatformSpec.task_arguments`` holds both); kept apart because
#: the keyword fuzz (``tests/navgym/envs/test_kwargs_fuzz.py``) fuzzes every name of
#: :data:`TASK_ARGUMENTS` and :data:`CORE_ARGUMENTS` of the registered ids from its own table.
V2_TASK_ARGUMENTS: dict[str, tuple[str, ...]] = {
    "fading": ("clairvoyant",),
    "mixture": ("per_row", "clairvoyant"),
}
#: Keyword arguments of the core (reward, horizon, evaluation info).
CORE_ARGUMENTS = (
    "max_episode_steps",
    "reward_clip",
    "divergence_penalty",
    "penalize_remaining_steps",
    "eval_info",
)
#: Opt-in (v2) core arguments, default off (see :data:`V2_TASK_ARGUMENTS`): the memory features
#: of :mod:`navgym.envs.memory`.
V2_CORE_ARGUMENTS = ("memory_features",)


def make_platform(spec: PlatformSpec, task: str, kwargs: dict[str, Any]) -> tuple[Any, int]:
    """The platform of ``spec`` for ``task`` and its horizon, popping their arguments from ``kwargs``.

    Reads ``episode_steps``, ``dt`` (where the platform takes it), the scenario arguments (over
    the task's defaults), ``error_scale_m``, ``divergence_m``, then the platform's own arguments
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
    scenario = dict(spec.tasks[task])
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


def check_episode_memory(platform: Any, num_envs: int, steps: int) -> None:
    """Refuse a batch whose episodes would take more than :data:`MAX_EPISODE_BYTES` (``ValueError``).

    ``platform.episode_bytes(steps)`` estimates one episode (before anything is allocated).
    """
    per = int(platform.episode_bytes(steps))
    need = num_envs * per
    if need > MAX_EPISODE_BYTES:
        raise ValueError(
            f"episode_steps={steps} with num_envs={num_envs} would take about {need / 2**30:.3g} GiB "
            f"for the simulated episodes ({per / 2**20:.3g} MiB each), more than MAX_EPISODE_BYTES = "
            f"{MAX_EPISODE_BYTES / 2**30:.3g} GiB (navgym.envs.platform.MAX_EPISODE_BYTES): lower "
            "episode_steps or num_envs"
        )


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
    task_opts = {k: kwargs.pop(k) for k in spec.task_arguments[task] if k in kwargs}
    if task == "fading" and spec.lambda_max_per_second is not None:
        task_opts.setdefault("lambda_max", spec.lambda_max_per_second**platform.dt)
    core_opts = {k: kwargs.pop(k) for k in CORE_ARGUMENTS + V2_CORE_ARGUMENTS if k in kwargs}
    if kwargs:
        raise UnknownKeywordError(f"unexpected keyword arguments: {sorted(kwargs)}")
    truncate = core_opts.pop("max_episode_steps", None)
    task_obj = make_task(task, outlier_rows=platform.outlier_rows, m_max=platform.m_max, **task_opts)
    return NavCore(platform, task_obj, num_envs, steps, truncate_steps=truncate, **core_opts)


class PlatformEnv(NavEnv):
    """A platform's single environment: ``class XEnv(PlatformEnv, spec=X): '''card'''``."""

    platform_spec: ClassVar[PlatformSpec]

    def __init_subclass__(cls, spec: PlatformSpec | None = None, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if spec is not None:
            cls.platform_spec = spec
            from navgym.envs.cards import fill_card  # the card needs the registry

            cls.__doc__ = fill_card(cls.__doc__ or "", spec, cls.__module__)

    def __init__(self, task: str = "fading", render_mode: str | None = None, **kwargs: Any) -> None:
        super().__init__(build_core(self.platform_spec, task, 1, kwargs), render_mode=render_mode)


class PlatformVectorEnv(NavVectorEnv):
    """A platform's native vector environment: ``class XVectorEnv(PlatformVectorEnv, spec=X)``."""

    platform_spec: ClassVar[PlatformSpec]

    def __init_subclass__(cls, spec: PlatformSpec | None = None, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if spec is not None:
            cls.platform_spec = spec

    def __init__(
        self, num_envs: int = 1, task: str = "fading", render_mode: str | None = None, **kwargs: Any
    ) -> None:
        # gym.make_vec passes render_mode when given; the vector env renders nothing.
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode must be None for a navgym vector env (it renders nothing; render "
                f"modes: {self.metadata['render_modes']}); got {render_mode!r}"
            )
        num_envs = arguments.integer("num_envs", num_envs, 1)
        super().__init__(build_core(self.platform_spec, task, num_envs, kwargs))
