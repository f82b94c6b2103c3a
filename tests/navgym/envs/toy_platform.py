"""A toy platform written as docs/add_a_platform.md says: one file, one registration line.

``ToyPlugin`` reuses ``toy.py``'s problem (a point in the plane with GNSS fixes) and declares
what a platform adds to be registered: a :class:`PlatformSpec` whose tasks include the toy task
of ``toy_task.py``, a card, the Env / VectorEnv classes and its registry entries
(:data:`ENTRIES`). Registering them is one line, ``register_platform(ENTRIES)``, or one
entry point of the group ``navgym.platforms`` naming ``ENTRIES`` in a package's metadata. Its
tests are in ``test_toy_registration.py``.
"""

from __future__ import annotations

from dataclasses import replace

from navgym.envs.ids import EnvEntry
from navgym.envs.platform import PlatformEnv, PlatformSpec, PlatformVectorEnv
from tests.navgym.envs import toy
from tests.navgym.envs.toy_task import R_SCALE

TOY_PLUGIN: PlatformSpec = replace(
    toy.TOY,
    name="ToyPlugin",
    tasks={"fading": {"outage_probability": 0.5, "outage_duration": (5.0, 20.0)}, R_SCALE.name: {}},
    platform_arguments=("sigma",),
)


class ToyPluginEnv(PlatformEnv, spec=TOY_PLUGIN):
    """A point in the plane, registered from outside navgym.

    ## Action Space
    {action_space}

    ## Observation Space
    {observation_table}

    ## Rewards
    {rewards}

    ## Episode End
    {episode_end}

    ## Arguments
    ``sigma=3.0`` [m]. {common_arguments}

    ## Version History
    {version_history}
    """


class ToyPluginVectorEnv(PlatformVectorEnv, spec=TOY_PLUGIN):
    """Native batched ToyPlugin environment."""


#: The platform's ids (their module is this one: the card lists them).
ENTRIES = [
    EnvEntry(f"navgym-test/ToyPlugin{title}-v0", __name__, "ToyPlugin", task, 60, defaults)
    for task, title, defaults in (
        ("fading", "Fading", {"filter": "ekf"}),
        ("rscale", "RScale", {"decades": 1.0}),
    )
]
