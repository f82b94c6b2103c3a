"""``navgym soak``: the figures of a soak run are counted right, and a long run stays clean."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, VectorEnv

from benchmarks.soak import SoakResult, navgym_ids, soak
from navgym.cli import main

#: RSS growth allowed over the 200,000 env-steps after the warm-up (slow test, GpsInsResample-v1,
#: B = 256, 782 calls). Measured: +8 MB in a fresh process (the heap's high-water mark rises at
#: the first autoresets, when a new episode's arrays are allocated before the old ones are
#: freed, then stays flat); a leak of 1 kB per env-step would add about 200 MB.
RSS_GROWTH_BOUND_MB = 64.0


class FlakyVectorEnv(VectorEnv):
    """A vector env whose faults are scheduled: NaN observations, inf rewards, raises, divergences.

    Call k (counted from 1 after each reset): obs of row 0 NaN when k % 5 == 0, reward of row 1
    inf when k % 7 == 0, row 0 ``diverged`` (terminated) when k % 4 == 0, ``RuntimeError`` when
    k % 11 == 0, and an observation above the box for row 1 when k % 13 == 0.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 2) -> None:
        self.num_envs = num_envs
        self.single_observation_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, num_envs)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, num_envs)
        self.k = 0

    def reset(self, *, seed=None, options=None):
        self.k = 0
        return np.zeros((self.num_envs, 3), np.float32), {}

    def step(self, actions):
        assert self.action_space.contains(np.asarray(actions, np.float32))
        self.k += 1
        k = self.k
        if k % 11 == 0:
            raise RuntimeError(f"scheduled failure at call {k}")
        obs = np.zeros((self.num_envs, 3), np.float32)
        reward = np.zeros(self.num_envs)
        diverged = np.zeros(self.num_envs, bool)
        if k % 5 == 0:
            obs[0, 1] = np.nan
        if k % 7 == 0:
            reward[1] = np.inf
        if k % 13 == 0:
            obs[1, 2] = 2.0
        if k % 4 == 0:
            diverged[0] = True
        info = {"diverged": diverged, "_diverged": np.ones(self.num_envs, bool)}
        return obs, reward, diverged.copy(), np.zeros(self.num_envs, bool), info


def _expected(calls: int) -> dict[str, int]:
    """The counts ``FlakyVectorEnv`` gives over ``calls`` step calls (its counter restarts after a raise)."""
    out = dict(exc=0, nan=0, inf=0, box=0, div=0)
    k = 0
    for _ in range(calls):
        k += 1
        if k % 11 == 0:
            out["exc"] += 1
            k = 0
            continue
        out["nan"] += k % 5 == 0
        out["inf"] += k % 7 == 0
        out["box"] += k % 13 == 0
        out["div"] += k % 4 == 0
    return out


@pytest.fixture
def flaky_id():
    env_id = "navgym_test/Flaky-v0"
    gym.register(id=env_id, vector_entry_point=FlakyVectorEnv)
    yield env_id
    del gym.registry[env_id]


def test_soak_counts_nonfinite_values_exceptions_divergences_and_continues(flaky_id):
    r = soak(flaky_id, steps=2 * 100, num_envs=2, seed=3, progress=False)
    want = _expected(100)
    assert r.calls == 100 and r.env_steps == 200 and not r.stopped_early and not r.aborted
    assert r.exceptions == {"RuntimeError": want["exc"]} and want["exc"] > 0
    assert r.exception_messages["RuntimeError"].startswith("scheduled failure at call 11")
    assert r.nonfinite_obs == want["nan"] and r.nonfinite_rewards == want["inf"]
    assert r.obs_out_of_bounds == want["box"]
    assert r.divergences == want["div"] == r.terminations == r.episodes
    assert not r.clean()


def test_tiny_soak_of_a_registered_id_is_clean_and_its_figures_add_up():
    r = soak(
        "navgym/Robot2dFading-v1",
        steps=400,
        num_envs=4,
        seed=0,
        progress=False,
        env_kwargs={"episode_steps": 25},
    )
    assert isinstance(r, SoakResult)
    assert r.calls == 100 and r.env_steps == 400 and r.warmup_env_steps == 40
    # 25-step episodes, and each autoreset takes a call (NEXT_STEP): 3 episodes per sub-env
    assert r.episodes == r.terminations + r.truncations == 12
    assert r.divergences <= r.terminations
    assert r.clean() and r.exceptions == {} and r.obs_out_of_bounds == 0
    assert r.rss_warm_mb > 0 and r.rss_end_mb > 0
    assert r.rss_growth_mb == pytest.approx(r.rss_end_mb - r.rss_warm_mb)
    assert r.seconds > 0 and r.env_steps_per_s > 0


def test_soak_command_prints_the_table_and_writes_json(tmp_path, capsys):
    out = tmp_path / "soak.json"
    argv = ["soak", "navgym/Robot2dFading-v1", "--steps", "64", "--num-envs", "8", "--seed", "5"]
    assert main([*argv, "--json", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "| navgym/Robot2dFading-v1 |" in text and "RSS growth MB" in text
    (rec,) = json.loads(out.read_text())["soak"]
    assert rec["env_id"] == "navgym/Robot2dFading-v1" and rec["num_envs"] == 8 and rec["seed"] == 5
    assert rec["env_steps"] == 64 and rec["clean"] and rec["n_exceptions"] == 0


def test_soak_command_rejects_unknown_ids_and_no_ids(capsys):
    assert main(["soak", "navgym/Nope-v0", "--steps", "8"]) == 2
    assert "unknown environment ids" in capsys.readouterr().err
    assert main(["soak", "--steps", "8"]) == 2
    assert "--all" in capsys.readouterr().err


def test_all_means_every_registered_navgym_id():
    ids = navgym_ids()
    assert ids and all(i.startswith("navgym/") for i in ids)
    assert set(ids) == {k for k in gym.registry if k.startswith("navgym/")}


@pytest.mark.slow
def test_soak_200k_env_steps_is_clean_and_does_not_leak():
    r = soak("navgym/GpsInsResample-v1", steps=200_000, num_envs=256, seed=0, progress=False)
    assert r.env_steps >= 200_000 and r.episodes > 0
    assert r.nonfinite_obs == 0 and r.nonfinite_rewards == 0 and r.obs_out_of_bounds == 0
    assert r.exceptions == {}, r.exception_messages
    assert r.rss_growth_mb < RSS_GROWTH_BOUND_MB, r
