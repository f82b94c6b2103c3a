"""``navgym dataset``: a small Minari dataset round-trips (the rewards and actions of a direct rollout)."""

import numpy as np
import pytest

pytest.importorskip("minari")
pytest.importorskip("h5py")

import gymnasium as gym

from agents.dataset.command import rollout, write_dataset
from agents.evaluation.cli import parse_policies

ENV_ID = "navgym/Robot2dFading-v2"
KWARGS = {"episode_steps": 6}


def test_a_small_dataset_round_trips_through_minari(tmp_path, monkeypatch):
    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "unused"))
    ds = write_dataset(ENV_ID, "strong_tracking", 3, tmp_path, seed_offset=4, env_kwargs=KWARGS)
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    loaded = minari.load_dataset(ds.spec.dataset_id)
    assert loaded.total_episodes == 3
    assert any(tmp_path.rglob("*.hdf5"))
    meta = list(loaded.storage.get_episode_metadata(range(3)))
    assert [m["seed"] for m in meta] == [1_000_004, 1_000_005, 1_000_006]  # tuning seeds
    (policy,) = parse_policies(["strong_tracking"], ENV_ID, KWARGS).values()
    env = gym.make(ENV_ID, **KWARGS)
    for ep, m in zip(loaded.iterate_episodes(), meta, strict=True):
        direct = rollout(env, policy, m["seed"])
        np.testing.assert_array_equal(ep.rewards, direct["rewards"])
        np.testing.assert_array_equal(ep.actions, direct["actions"])
        np.testing.assert_array_equal(ep.observations, direct["observations"])
        assert ep.infos["pos_err_m"].shape == (KWARGS["episode_steps"] + 1,)
        np.testing.assert_array_equal(ep.infos["pos_err_m"][1:], direct["infos"]["pos_err_m"][1:])


def test_evaluation_seeds_are_refused(tmp_path):
    with pytest.raises(ValueError, match="evaluation seeds"):
        write_dataset(ENV_ID, "plain", 1, tmp_path, seed_list=[2_000_000_001], env_kwargs=KWARGS)
