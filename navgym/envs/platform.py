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
horizon, reward, scenario distribution) and the core, built from them by
:func:`~navgym.envs.build.build_core` (which checks every argument and the memory of a batch's
episodes before anything is simulated), the single and vector environment shells
(:mod:`navgym.envs.base`), the innovation / NIS / covariance features
(:mod:`navgym.envs.features`), the divergence rules and the common card paragraphs
(:mod:`navgym.envs.cards`, filled when a card is first read). The ids are the platform's own
registry entries (``docs/add_a_platform.md``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from navgym.envs import arguments
from navgym.envs.arguments import UnknownKeywordError
from navgym.envs.base import NavEnv, NavVectorEnv
from navgym.envs.build import (
    COMMON_PLATFORM_ARGUMENTS,
    MAX_EPISODE_STEPS,
    PlatformArgs,
    build_core,
    check_episode_memory,
    make_platform,
)
from navgym.envs.cards import EnvCard
from navgym.envs.core import NavCore
from navgym.scenarios import Scenario, ScenarioDistribution

__all__ = [
    "COMMON_PLATFORM_ARGUMENTS",
    "MAX_EPISODE_STEPS",
    "PlatformArgs",
    "PlatformBase",
    "PlatformEnv",
    "PlatformSpec",
    "PlatformVectorEnv",
    "build_core",
    "check_episode_memory",
    "make_platform",
]


class PlatformBase:
    """Members of the :class:`~navgym.envs.protocols.Platform` protocol with shared defaults.

    Subclasses are frozen dataclasses with at least the fields ``scenarios``
    (:class:`ScenarioDistribution`), ``dt``, ``n``, ``m_max``, ``error_scale_m`` and ``divergence_m``.
    """

    #: Fields of the episodes that ``step_models`` advances (none by default).
    episode_cursors: ClassVar[tuple[str, ...]] = ()
    scenarios: ScenarioDistribution
    n: int
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

    @property
    def process_noise_states(self) -> tuple[int, ...]:
        """States whose process noise the RowScale task's ``s_q`` scales (default: every state).

        A platform whose unmodelled motion enters through some states only (GpsIns' velocity
        errors) names those, so that the knob scales the part of ``Q`` that the events change.
        """
        return tuple(range(self.n))

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
        return 4 * (T + 1) * (8 * int(self.n) + 9 * int(self.m_max))

    def check_reward_scales(self) -> None:
        """``error_scale_m`` and ``divergence_m`` are finite and positive (``ValueError`` otherwise)."""
        arguments.real("error_scale_m", self.error_scale_m, 0.0, low_open=True)
        arguments.real("divergence_m", self.divergence_m, 0.0, low_open=True)


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


class PlatformEnv(NavEnv):
    """A platform's single environment: ``class XEnv(PlatformEnv, spec=X): '''card'''``."""

    platform_spec: ClassVar[PlatformSpec]

    def __init_subclass__(cls, spec: PlatformSpec | None = None, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if spec is not None:
            cls.platform_spec = spec
            # the card's placeholders are filled when it is first read (it builds a core per id)
            cls.__doc__ = EnvCard(cls.__dict__.get("__doc__") or "", spec, cls.__module__)  # type: ignore[assignment]

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
