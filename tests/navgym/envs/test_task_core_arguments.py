"""Task and core keyword arguments are checked at construction, and the error names them.

Before, ``lambda_max=inf`` failed at the first step, ``resample_cost=inf`` and
``divergence_penalty=inf`` gave NaN or -inf rewards, and ``log_ess_feature="no"`` became True.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import navgym  # noqa: F401  (registers the ids)
from navgym.envs.tasks import MAX_PARTICLES, MAX_ROUGHENING, FadingTask, MixtureTask, ResampleTask

FADING, MIXTURE, RESAMPLE = "navgym/Robot2dFading-v1", "navgym/Robot2dMixture-v1", "navgym/Robot2dResample-v1"
SHORT = {"episode_steps": 5}

BAD = [
    # (id, argument, value)
    (FADING, "lambda_max", np.inf),
    (FADING, "lambda_max", np.nan),
    (FADING, "lambda_max", 1.0),
    (FADING, "lambda_max", 0.5),
    (FADING, "lambda_max", "10"),
    (FADING, "lambda_max", True),
    (FADING, "filter", "kalman"),
    (FADING, "filter", None),
    (MIXTURE, "eps_max", 0.0),
    (MIXTURE, "eps_max", 1.0),
    (MIXTURE, "eps_max", np.nan),
    (MIXTURE, "eps_max", "0.5"),
    (MIXTURE, "variance_ratio", 1.0),
    (MIXTURE, "variance_ratio", np.inf),
    (MIXTURE, "variance_ratio", np.nan),
    (MIXTURE, "filter", "pf"),
    (RESAMPLE, "n_particles", 0),
    (RESAMPLE, "n_particles", MAX_PARTICLES + 1),
    (RESAMPLE, "n_particles", 100.0),
    (RESAMPLE, "n_particles", True),
    (RESAMPLE, "resample_cost", np.inf),
    (RESAMPLE, "resample_cost", -0.1),
    (RESAMPLE, "resample_cost", np.nan),
    (RESAMPLE, "method", "importance"),
    (RESAMPLE, "method", 1),
    (RESAMPLE, "roughening", np.inf),
    (RESAMPLE, "roughening", MAX_ROUGHENING * 2),
    (RESAMPLE, "roughening", -1.0),
    (RESAMPLE, "log_ess_feature", "no"),
    (RESAMPLE, "log_ess_feature", 2),
    (RESAMPLE, "log_ess_feature", np.nan),
    (RESAMPLE, "log_ess_feature", 0),
    (RESAMPLE, "particle_dtype", "float16"),
    (RESAMPLE, "particle_dtype", 32),
    (FADING, "reward_clip", 0.0),
    (FADING, "reward_clip", np.inf),
    (FADING, "reward_clip", np.nan),
    (FADING, "reward_clip", "10"),
    (FADING, "divergence_penalty", np.inf),
    (FADING, "divergence_penalty", -1.0),
    (FADING, "divergence_penalty", np.nan),
    (RESAMPLE, "penalize_remaining_steps", "no"),
    (RESAMPLE, "penalize_remaining_steps", 1),
    (RESAMPLE, "eval_info", "yes"),
    (RESAMPLE, "eval_info", np.nan),
]


@pytest.mark.parametrize(("env_id", "name", "value"), BAD, ids=[f"{n}={v!r}" for _, n, v in BAD])
@pytest.mark.parametrize("vector", [False, True], ids=["single", "vector"])
def test_a_bad_argument_fails_at_construction_naming_it(env_id, name, value, vector):
    with pytest.raises((TypeError, ValueError), match=name) as caught:
        if vector:
            kwargs = {**SHORT, name: value}
            gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", **kwargs)
        else:
            gym.make(env_id, **SHORT, **{name: value})
    assert "got" in str(caught.value)  # and the value given


@pytest.mark.parametrize("value", [0, 2.5, True, "10", np.nan])
def test_max_episode_steps_of_a_vector_env_is_an_integer_of_at_least_one(value):
    with pytest.raises((TypeError, ValueError), match="max_episode_steps"):
        gym.make_vec(FADING, num_envs=2, vectorization_mode="vector_entry_point", max_episode_steps=value)


def test_the_error_gives_the_accepted_range():
    with pytest.raises(ValueError, match=r"lambda_max must be a finite number in \(1, inf\); got inf"):
        FadingTask(lambda_max=np.inf)
    with pytest.raises(ValueError, match=r"eps_max must be a finite number in \(0, 1\); got 1.0"):
        MixtureTask(eps_max=1.0)
    with pytest.raises(ValueError, match=rf"n_particles must be an integer in \[1, {MAX_PARTICLES}\]"):
        ResampleTask(n_particles=0)
    with pytest.raises(ValueError, match=r"method must be one of \['multinomial', 'residual'"):
        ResampleTask(method="x")
    with pytest.raises(TypeError, match="log_ess_feature must be True or False; got 'no'"):
        ResampleTask(log_ess_feature="no")


def test_valid_values_of_numpy_types_are_accepted():
    env = gym.make_vec(
        RESAMPLE,
        num_envs=2,
        vectorization_mode="vector_entry_point",
        n_particles=np.int64(50),
        resample_cost=np.float32(0.5),
        roughening=np.float64(MAX_ROUGHENING),
        log_ess_feature=np.bool_(False),
        particle_dtype=np.dtype("float64"),
        reward_clip=np.float64(5.0),
        divergence_penalty=0,
        max_episode_steps=np.int64(3),
        **SHORT,
    )
    task = env.unwrapped.core.task
    assert (task.n_particles, task.resample_cost, task.roughening) == (50, 0.5, MAX_ROUGHENING)
    assert task.log_ess_feature is False and task.particle_dtype == np.float64
    assert ResampleTask(**task.options).options == task.options
    env.reset(seed=0)
    env.step(np.array([1, 0]))
    fading = gym.make(FADING, lambda_max=1e300, filter="ckf", **SHORT)
    assert fading.unwrapped.core.task.lambda_max == 1e300
