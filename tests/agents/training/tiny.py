"""A tiny RowScale-v3 PPO entry (one rollout of 2 x 64 steps on 40-step episodes) for the tests."""

from __future__ import annotations

from typing import Any

ENV = "navgym/Robot2dRowScale-v3"
SUPERVISED = "agents/zoo/Robot2dRowScale-v3-supervised"


def tiny_row_scale_entry(**extra: Any) -> dict[str, Any]:
    """The entry: RowSharedPolicy, a residual over the zoo's supervised agent; ``extra`` keys added."""
    return {
        "n_envs": 2,
        "n_timesteps": 128,
        "policy": "RowSharedPolicy",
        "normalize": {"norm_obs": True, "norm_reward": True},
        "env_kwargs": {"eval_info": False, "episode_steps": 40, "max_episode_steps": 40},
        "n_steps": 64,
        "batch_size": 64,
        "n_epochs": 1,
        "policy_kwargs": {"hidden": 8},
        "residual": {"baseline": "supervised", "agent": SUPERVISED, "scale": 0.5, "observe_base": True},
        **extra,
    }
