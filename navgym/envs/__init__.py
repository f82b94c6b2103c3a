"""navgym environments: the core, the platform skeleton, the tasks and the registry of ids.

``docs/architecture.md`` describes the layers and a step's data flow; ``docs/add_a_platform.md``
and ``docs/add_a_task.md`` are the checklists for a new platform or task.
"""

from navgym.envs.registration import ENVIRONMENTS, register_all

__all__ = ["ENVIRONMENTS", "register_all"]
