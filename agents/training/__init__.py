"""Training SB3 agents on navgym environments, and loading them back.

* :func:`train` — PPO / SAC / DQN / A2C from ``agents/configs/<algo>.yml`` (rl-zoo3 layout, keyed
  by env id) on the native batched env, with TensorBoard, checkpoints, resume and fixed seeds.
* :func:`load_agent` — a trained agent whose ``predict`` takes raw observations (normalization
  statistics applied inside). Its ``manifest.json`` (file hashes, spaces) is checked and nothing
  is unpickled unless ``trust=True`` (:mod:`agents.training.loading`).
* :func:`load_zoo_agent` — the shipped agent of an env id (``agents/zoo/<env name>``), its
  spaces checked against the environment's.
* :func:`convert_agent` — one-off: an agent saved with ``vecnormalize.pkl`` and no manifest to
  the current format (unpickles it once: trusted agents only).
* :func:`train_cli`, :func:`add_train_arguments` — the ``navgym train`` command.

Importing this package needs torch and stable-baselines3 (the ``agents`` extra).
"""

from agents.training.cli import add_train_arguments, train_cli
from agents.training.config import UnknownEnvError, load_config
from agents.training.loading import AgentLoadError, TrainedAgent, convert_agent, load_agent
from agents.training.train import latest_checkpoint, make_vec_env, train

__all__ = [
    "ZOO_DIR",
    "AgentLoadError",
    "TrainedAgent",
    "UnknownEnvError",
    "add_train_arguments",
    "convert_agent",
    "latest_checkpoint",
    "load_agent",
    "load_config",
    "load_zoo_agent",
    "make_vec_env",
    "train",
    "train_cli",
    "zoo_agents",
    "zoo_path",
]

_ZOO = ("ZOO_DIR", "load_zoo_agent", "zoo_agents", "zoo_path")


def __getattr__(name: str):
    # Lazy, so that ``python -m agents.training.zoo`` does not import the module twice.
    if name in _ZOO:
        from agents.training import zoo

        return getattr(zoo, name)
    raise AttributeError(f"module 'agents.training' has no attribute {name!r}")
