"""The shipped configurations: rl-zoo3 reads them as they are, navgym reads them as before."""

import inspect

import pytest
import yaml

pytest.importorskip("stable_baselines3")

from agents.training.config import (
    CONFIG_DIR,
    DEFAULTS_KEY,
    NAVGYM_ONLY_KEYS,
    SIDECAR_KEY,
    build_hyperparameters,
    merge_sidecar,
    read_config_file,
    split_entry,
    zoo_policy_kwargs,
)
from agents.training.loading import algo_class

#: Keys rl-zoo3 2.9 takes out of an entry before passing the rest to the algorithm's constructor
#: (rl_zoo3/exp_manager.py, _preprocess_hyperparams and read_hyperparameters).
ZOO_RUN_KEYS = {
    "n_envs",
    "n_timesteps",
    "normalize",
    "env_kwargs",
    "frame_stack",
    "env_wrapper",
    "vec_env_wrapper",
    "callback",
    "monitor_kwargs",
    "noise_type",
    "noise_std",
}
FILES = sorted(CONFIG_DIR.glob("*.yml"))


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_entries_hold_only_keys_rl_zoo3_knows(path):
    raw = yaml.safe_load(path.read_text())
    params = set(inspect.signature(algo_class(path.stem).__init__).parameters) - {"self", "env"}
    for env_id, entry in raw.items():
        if env_id in (SIDECAR_KEY, DEFAULTS_KEY):
            continue
        extra = set(entry) - ZOO_RUN_KEYS - params
        assert not extra, (path.name, env_id, extra)
        assert not set(entry) & set(NAVGYM_ONLY_KEYS), (path.name, env_id)
        # rl-zoo3 calls int() on n_timesteps: a YAML float needs a signed exponent (1.0e+6), not 1.0e6
        assert isinstance(entry["n_timesteps"], (int, float)), (path.name, env_id, entry["n_timesteps"])
        pk = entry.get("policy_kwargs")
        if isinstance(pk, dict):  # a mapping reaches SB3 as is: no activation name strings in it
            assert "activation_fn" not in pk, (path.name, env_id)


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name)
def test_navgym_reads_the_sidecar_into_its_entries(path):
    raw = yaml.safe_load(path.read_text())
    data = read_config_file(path)
    assert SIDECAR_KEY not in data and set(data) == set(raw) - {SIDECAR_KEY, DEFAULTS_KEY}
    for env_id, opts in (raw.get(SIDECAR_KEY) or {}).items():
        assert all(data[env_id][k] == v for k, v in opts.items()), (path.name, env_id)
    for entry in data.values():
        run, hyper = split_entry(entry)
        kw = build_hyperparameters(hyper)
        assert isinstance(kw.get("policy_kwargs", {}), dict)


def test_shipped_entries_resolve_as_before():
    """Spot values of entries whose navgym keys moved to the sidecar (residual, checkpoint_freq)."""
    ppo = read_config_file(CONFIG_DIR / "ppo.yml")
    e = ppo["navgym/Robot2dMixture-v2"]
    assert e["residual"] == {"baseline": "chi_square", "observe_base": True, "params": "tuned", "scale": 0.5}
    assert e["checkpoint_freq"] == 200000
    assert e["policy_kwargs"] == {"net_arch": [64, 64], "activation_fn": "tanh", "log_std_init": -1.0}
    assert "residual" not in ppo["navgym/Robot2dFading-v1"]
    lstm = read_config_file(CONFIG_DIR / "ppo_lstm.yml")["navgym/Robot2dFading-v2"]["policy_kwargs"]
    assert lstm["lstm_hidden_size"] == 64 and lstm["shared_lstm"] is False and lstm["activation_fn"] == "tanh"


def test_zoo_policy_kwargs_parses_without_evaluating():
    got = zoo_policy_kwargs("dict(net_arch=dict(pi=[8], vf=[4]), activation_fn=nn.ReLU, ortho_init=False)")
    assert got == {"net_arch": {"pi": [8], "vf": [4]}, "activation_fn": "relu", "ortho_init": False}
    for bad in (
        "dict(activation_fn=nn.Sigmoid)",
        "__import__('os').system('true')",
        "dict(net_arch=list(range(3)))",
        "dict(**x)",
        "dict(",
    ):
        with pytest.raises(ValueError, match="policy_kwargs"):
            zoo_policy_kwargs(bad)


def test_sidecar_errors_name_the_problem():
    entry = {"n_envs": 2, "n_timesteps": 10, "gamma": 0.9}
    merged = merge_sidecar({"navgym/X-v0": entry, SIDECAR_KEY: {"navgym/X-v0": {"checkpoint_freq": 5}}})
    assert merged == {"navgym/X-v0": {**entry, "checkpoint_freq": 5}}
    with pytest.raises(ValueError, match="no entry"):
        merge_sidecar({SIDECAR_KEY: {"navgym/Y-v0": {"checkpoint_freq": 5}}})
    with pytest.raises(ValueError, match="navgym-only"):
        merge_sidecar({"navgym/X-v0": entry, SIDECAR_KEY: {"navgym/X-v0": {"gamma": 0.5}}})
    with pytest.raises(ValueError, match="both"):
        merge_sidecar(
            {
                "navgym/X-v0": {**entry, "checkpoint_freq": 4},
                SIDECAR_KEY: {"navgym/X-v0": {"checkpoint_freq": 5}},
            }
        )
