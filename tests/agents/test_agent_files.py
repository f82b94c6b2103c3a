"""Saved-agent files: missing statistics, manifest hashes and spaces, no unpickling, the zoo format."""

from __future__ import annotations

import base64
import io
import json
import os
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("stable_baselines3")
torch = pytest.importorskip("torch")

from agents.training import AgentLoadError, load_agent, load_zoo_agent, train, zoo_agents  # noqa: E402
from agents.training.loading import (  # noqa: E402
    read_manifest,
    space_from_dict,
    verify_manifest,
    write_manifest,
)
from agents.training.zoo import ZOO_DIR  # noqa: E402

ENV = "navgym/GpsInsFading-v0"
SHORT = {"episode_steps": 50, "max_episode_steps": 50}
TINY = {
    "n_envs": 4,
    "n_timesteps": 512,
    "policy": "MlpPolicy",
    "normalize": {"norm_obs": True, "norm_reward": True},
    "env_kwargs": {"eval_info": False, **SHORT},
    "n_steps": 64,
    "batch_size": 128,
    "n_epochs": 2,
    "learning_rate": "lin_1e-3",  # a schedule: SB3 pickles it into the archive's data
    "clip_range": 0.3,
    "policy_kwargs": {"net_arch": [16, 16], "activation_fn": "tanh"},
    "checkpoint_freq": 256,
}
RECORDED = Path(__file__).parent / "data" / "zoo_actions_before_conversion.npz"


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("agent") / "ppo"
    return train(ENV, "ppo", config=TINY, seed=0, out_dir=out, progress=False, tensorboard=False)


@pytest.fixture
def agent_dir(run, tmp_path) -> Path:
    """A private copy of the run's final agent (the files a user would pass around)."""
    dest = tmp_path / "agent"
    shutil.copytree(run, dest, ignore=shutil.ignore_patterns("checkpoints", "tb"))
    return dest


def rewrite_manifest(folder: Path, drop: tuple[str, ...] = ()) -> None:
    """Make ``folder``'s manifest match its files as they are now (what a tamperer could do)."""
    old = read_manifest(folder)
    write_manifest(
        folder,
        [n for n in old["files"] if n not in drop and (folder / n).is_file()],
        algo=old["algo"],
        env_id=old["env_id"],
        num_timesteps=old["num_timesteps"],
        observation_space=space_from_dict(old["observation_space"]),
        action_space=space_from_dict(old["action_space"]),
    )


def _observations(agent, n: int = 64) -> np.ndarray:
    rng = np.random.default_rng(0)
    space = agent.observation_space
    return rng.uniform(space.low, space.high, size=(n, space.shape[0])).astype(np.float32)


# --- 1. missing normalization statistics -------------------------------------------------------


def test_missing_statistics_of_a_normalized_run_raise_naming_the_file(agent_dir):
    """Without vecnormalize.npz the agent would act on raw observations: refuse, naming the file."""
    (agent_dir / "vecnormalize.npz").unlink()
    with pytest.raises(AgentLoadError, match="vecnormalize.npz"):
        load_agent(agent_dir)  # listed in the manifest, missing
    rewrite_manifest(agent_dir)  # even when the manifest no longer lists it
    with pytest.raises(AgentLoadError, match=r"vecnormalize\.npz is missing.*normalized observations"):
        load_agent(agent_dir)
    # ``normalize: true`` (the short form of the configuration) means norm_obs too.
    cfg = (agent_dir / "config.yml").read_text()
    cfg = cfg.replace("normalize:\n  norm_obs: true\n  norm_reward: true\n", "normalize: true\n")
    assert "normalize: true\n" in cfg
    (agent_dir / "config.yml").write_text(cfg)
    rewrite_manifest(agent_dir)
    with pytest.raises(AgentLoadError, match=r"vecnormalize\.npz is missing"):
        load_agent(agent_dir)
    # A run that did not normalize observations loads without statistics.
    (agent_dir / "config.yml").write_text(cfg.replace("normalize: true\n", "normalize: false\n"))
    rewrite_manifest(agent_dir)
    assert load_agent(agent_dir).normalizer is None


# --- 2. manifest: hashes and spaces ------------------------------------------------------------


def _rewrite_zip(path: Path, edit) -> None:
    with zipfile.ZipFile(path) as z:
        entries = {n: z.read(n) for n in z.namelist()}
    edit(entries)
    with zipfile.ZipFile(path, "w") as z:
        for name, data in entries.items():
            z.writestr(name, data)


def test_changed_weights_are_refused_naming_the_file(agent_dir):
    manifest = json.loads((agent_dir / "manifest.json").read_text())
    assert set(manifest["files"]) == {"model.zip", "vecnormalize.npz", "config.yml", "meta.json"}
    assert manifest["observation_space"]["shape"] == [25] and manifest["action_space"]["type"] == "Box"

    def perturb(entries):
        state = torch.load(io.BytesIO(entries["policy.pth"]), weights_only=True)
        for v in state.values():
            v.add_(0.1)
        buf = io.BytesIO()
        torch.save(state, buf)
        entries["policy.pth"] = buf.getvalue()

    _rewrite_zip(agent_dir / "model.zip", perturb)
    with pytest.raises(AgentLoadError, match=r"model\.zip does not match its SHA-256"):
        load_agent(agent_dir)
    with pytest.raises(AgentLoadError, match=r"model\.zip"):
        load_agent(agent_dir / "model.zip")  # the archive itself: the manifest beside it applies


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_non_finite_weights_are_refused_at_load_naming_the_file(agent_dir, value):
    """Weights with NaN or inf (manifest rewritten to match) are refused at load, not at predict."""

    def poison(entries):
        state = torch.load(io.BytesIO(entries["policy.pth"]), weights_only=True)
        name = next(k for k, v in state.items() if v.is_floating_point())
        state[name].view(-1)[0] = value
        buf = io.BytesIO()
        torch.save(state, buf)
        entries["policy.pth"] = buf.getvalue()

    _rewrite_zip(agent_dir / "model.zip", poison)
    rewrite_manifest(agent_dir)
    with pytest.raises(AgentLoadError, match=r"model\.zip: the policy's weights have non-finite entries"):
        load_agent(agent_dir)


@pytest.mark.parametrize("key", ["mean", "var", "count", "ret_var"])
def test_non_finite_statistics_are_refused_at_load_naming_the_file(agent_dir, key):
    """Normalization statistics with NaN (manifest rewritten to match) are refused at load."""
    path = agent_dir / "vecnormalize.npz"
    with np.load(path) as z:
        data = {k: np.asarray(z[k]).copy() for k in z.files}
    data[key] = np.asarray(data[key], dtype=np.float64)
    data[key].reshape(-1)[0] = np.nan
    np.savez(path, **data)
    rewrite_manifest(agent_dir)
    with pytest.raises(
        AgentLoadError, match=rf"vecnormalize\.npz: the normalization statistic {key} has non-finite"
    ):
        load_agent(agent_dir)


def test_changed_env_id_in_config_is_refused(agent_dir):
    cfg = agent_dir / "config.yml"
    cfg.write_text(cfg.read_text().replace(f"env_id: {ENV}", "env_id: navgym/GpsInsResample-v1"))
    with pytest.raises(AgentLoadError, match=r"config\.yml does not match its SHA-256"):
        load_agent(agent_dir)
    rewrite_manifest(agent_dir)  # a consistent manifest still records the env id it was saved for
    with pytest.raises(AgentLoadError, match="env_id"):
        load_agent(agent_dir)


def test_spaces_are_checked_against_the_env(agent_dir):
    import gymnasium as gym

    with pytest.raises(AgentLoadError, match="observation space"):
        load_agent(agent_dir, env="navgym/GpsInsResample-v1")
    env = gym.make(ENV, **SHORT)
    assert load_agent(agent_dir, env=env).env_id == ENV
    env.close()
    vec = gym.make_vec(ENV, num_envs=2, vectorization_mode="vector_entry_point", **SHORT)
    load_agent(agent_dir, env=vec)
    vec.close()
    # Bounds count: an agent saved for other observation bounds does not fit this env.
    manifest = json.loads((agent_dir / "manifest.json").read_text())
    manifest["observation_space"]["low"][0] -= 1.0
    (agent_dir / "manifest.json").write_text(json.dumps(manifest))
    with pytest.raises(AgentLoadError, match=r"observation space .*low bound \[0\]"):
        load_agent(agent_dir, env=ENV)


def test_zoo_agent_spaces_are_checked_against_its_env(tmp_path, monkeypatch):
    import agents.training.zoo as zoo

    shutil.copytree(ZOO_DIR / "GpsInsResample-v1", tmp_path / "GpsInsResample-v1")
    monkeypatch.setattr(zoo, "ZOO_DIR", tmp_path)
    assert load_zoo_agent("navgym/GpsInsResample-v1").env_id == "navgym/GpsInsResample-v1"
    path = tmp_path / "GpsInsResample-v1" / "manifest.json"
    manifest = json.loads(path.read_text())
    manifest["action_space"]["n"] = 3
    path.write_text(json.dumps(manifest))
    with pytest.raises(AgentLoadError, match="action"):
        load_zoo_agent("navgym/GpsInsResample-v1")


# --- 3. no unpickling by default ---------------------------------------------------------------


class _Payload:
    """Unpickling this creates the folder ``marker`` (stands for arbitrary code)."""

    def __init__(self, marker: Path) -> None:
        self.marker = str(marker)

    def __reduce__(self):
        return (os.makedirs, (self.marker,))


def _plant(folder: Path, marker: Path, extra_entry: bool = False) -> list[str]:
    """Replace every pickled entry of model.zip's data (and vecnormalize.pkl) by the payload."""
    payload = base64.b64encode(pickle.dumps(_Payload(marker))).decode()
    planted = []

    def edit(entries):
        data = json.loads(entries["data"])
        for key, item in data.items():
            if isinstance(item, dict) and ":serialized:" in item:
                item[":serialized:"] = payload
                planted.append(key)
        if extra_entry:
            data["evil"] = {":type:": "<class 'object'>", ":serialized:": payload}
        entries["data"] = json.dumps(data).encode()

    _rewrite_zip(folder / "model.zip", edit)
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    return planted


@pytest.fixture
def no_unpickling(monkeypatch):
    """Any cloudpickle / pickle load during the test fails it."""
    import cloudpickle

    def refuse(*args, **kwargs):
        raise AssertionError("something was unpickled")

    for mod in (cloudpickle, pickle):
        monkeypatch.setattr(mod, "loads", refuse)
    monkeypatch.setattr(pickle, "load", refuse)
    return monkeypatch


def test_default_load_never_unpickles_model_data_or_statistics(agent_dir, tmp_path, no_unpickling):
    marker = tmp_path / "PWNED"
    before = load_agent(agent_dir)
    obs = _observations(before)
    planted = _plant(agent_dir, marker)
    assert {"lr_schedule", "clip_range", "learning_rate", "policy_class", "observation_space"} <= set(planted)
    rewrite_manifest(agent_dir)  # a manifest that matches the planted files
    after = load_agent(agent_dir)
    assert not marker.exists()
    np.testing.assert_array_equal(after.predict(obs)[0], before.predict(obs)[0])
    assert after.model.learning_rate(0.5) == pytest.approx(5e-4)  # the schedule, from config.yml
    # Statistics only as a pickle: refused (naming the file and trust=True), not unpickled.
    (agent_dir / "vecnormalize.npz").unlink()
    rewrite_manifest(agent_dir)
    with pytest.raises(AgentLoadError, match=r"vecnormalize\.pkl.*trust=True"):
        load_agent(agent_dir)
    assert not marker.exists()


def test_unknown_pickled_entry_is_refused(agent_dir, tmp_path, no_unpickling):
    marker = tmp_path / "PWNED"
    _plant(agent_dir, marker, extra_entry=True)
    rewrite_manifest(agent_dir)
    with pytest.raises(AgentLoadError, match=r"'evil'.*trust=True"):
        load_agent(agent_dir)
    assert not marker.exists()


def test_trust_true_does_unpickle(agent_dir, tmp_path):
    """The planted payload is live: loading with ``trust=True`` runs it (so the tests above mean it)."""
    marker = tmp_path / "PWNED"
    (agent_dir / "vecnormalize.npz").unlink()
    (agent_dir / "manifest.json").unlink()
    _plant(agent_dir, marker)
    with pytest.raises(AgentLoadError, match="manifest.json.*trust=True"):
        load_agent(agent_dir)
    assert not marker.exists()
    with pytest.raises(Exception):  # noqa: B017 - the payload's None breaks the model afterwards
        load_agent(agent_dir, trust=True)
    assert marker.exists()


def test_checkpoints_are_agents_too(run, no_unpickling):
    """A checkpoint folder has its own manifest and loads without unpickling."""
    (folder,) = [p for p in (run / "checkpoints").iterdir() if p.name == "step_512"]
    assert verify_manifest(folder)["num_timesteps"] == 512
    assert load_agent(folder).model.num_timesteps == 512


# --- 5. the shipped zoo agents -----------------------------------------------------------------


#: The zoo agents that were pickled once and converted (their actions were recorded before).
CONVERTED = ("navgym/GpsInsFading-v0", "navgym/GpsInsResample-v1", "navgym/QuadrotorMixture-v0")


@pytest.fixture
def zoo_observations():
    """``{env_id: (observations of 3 resets, action space)}`` of every zoo agent's env, built before
    ``no_unpickling`` (making an env may load Numba's cache, which unpickles)."""
    import gymnasium as gym

    import navgym  # noqa: F401

    out = {}
    for env_id in zoo_agents():
        env = gym.make(env_id)
        out[env_id] = (np.stack([env.reset(seed=s)[0] for s in range(3)]), env.action_space)
        env.close()
    return out


def test_every_zoo_agent_loads_without_unpickling_and_acts_in_its_space(zoo_observations, no_unpickling):
    """Every shipped agent (the v2 ones included): manifest-checked files, no pickle, and a
    deterministic action in its env's action space for a batch of its env's observations."""
    files = {"model.zip", "vecnormalize.npz", "config.yml", "meta.json"}
    assert len(zoo_observations) >= 7
    for env_id, (obs, space) in zoo_observations.items():
        folder = ZOO_DIR / env_id.split("/")[-1]
        assert not list(folder.glob("*.pkl"))
        assert set(verify_manifest(folder)["files"]) == files
        agent = load_zoo_agent(env_id)
        first, _ = agent.predict(obs, deterministic=True)
        again, _ = agent.predict(obs, deterministic=True)
        np.testing.assert_array_equal(first, again)
        assert all(space.contains(np.asarray(a, dtype=space.dtype)) for a in first), env_id


def test_zoo_agents_are_converted_and_act_as_before(no_unpickling):
    """Converted (npz statistics, manifest) and loaded without unpickling, each zoo agent gives the
    actions the pickled originals gave on the same observations (recorded before conversion)."""
    recorded = np.load(RECORDED, allow_pickle=False)
    assert set(CONVERTED) <= set(zoo_agents())
    for env_id in CONVERTED:
        folder = ZOO_DIR / env_id.split("/")[-1]
        assert not (folder / "vecnormalize.pkl").exists()
        assert set(verify_manifest(folder)["files"]) == {
            "model.zip",
            "vecnormalize.npz",
            "config.yml",
            "meta.json",
        }
        agent = load_zoo_agent(env_id)
        name = env_id.split("/")[-1]
        obs, want = recorded[f"{name}/obs"], recorded[f"{name}/actions"]
        assert obs.shape[0] >= 300
        got, _ = agent.predict(obs, deterministic=True)
        if want.dtype.kind in "iu":
            np.testing.assert_array_equal(got, want)
        else:
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-5)
