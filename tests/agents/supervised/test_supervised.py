"""agents.supervised: labels = the regime oracle's classes, the per-row model, files, the command."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from agents.evaluation.runner import make_vector_env, native_vector_env
from agents.supervised.collect import collect
from agents.supervised.command import main, split_episodes
from agents.supervised.features import RowFeatures
from agents.supervised.files import MANIFEST, SupervisedLoadError, load_policy, save_policy
from agents.supervised.labels import NOT_RECEIVED, next_step_labels, table_scales
from agents.supervised.model import RowRegimeNet
from agents.supervised.policy import SupervisedRowScalePolicy
from agents.supervised.train import TrainConfig, train_model

ENV = "navgym/Robot2dRowScale-v3"
TABLE = (0.5, 100.0, 1e4, 0.3, 30.0)
SHORT = {"max_episode_steps": 40}


def test_labels_are_the_regime_oracles_classes():
    """The oracle's applied scales equal the table mapped from the peeked labels, step by step."""
    B = 16
    env = make_vector_env(ENV, B, {**SHORT, "max_episode_steps": 120, "regime_oracle": TABLE})
    nav = native_vector_env(env)
    f = nav.observation_features
    env.reset(seed=list(range(B)))
    stepper = nav.episode_stepper()
    seen = np.zeros(4, bool)
    for _ in range(120):
        lab = next_step_labels(env)
        obs, *_ = stepper.step(np.zeros((B, 6), np.float32))
        applied = 10.0 ** np.column_stack(
            [obs[:, f.index("log_row_scale")], obs[:, f.index("log_process_scale")]]
        )
        want = table_scales(lab, np.asarray(TABLE))
        rec = lab.row != NOT_RECEIVED
        np.testing.assert_allclose(applied[:, :5][rec], want[:, :5][rec], rtol=1e-5)
        np.testing.assert_allclose(applied[:, 5], want[:, 5], rtol=1e-5)
        seen[np.unique(lab.row)] = True
    assert seen.all()  # every row class occurs
    env.close()


def test_labels_peek_leaves_the_episodes_unchanged():
    """Peeking the next step's models does not change the rollout."""
    outs = []
    for peek in (False, True):
        env = make_vector_env(ENV, 4, SHORT)
        obs, _ = env.reset(seed=[1, 2, 3, 4])
        stepper = native_vector_env(env).episode_stepper()
        for _ in range(30):
            if peek:
                next_step_labels(env)
            obs, *_ = stepper.step(np.zeros((4, 6), np.float32))
        outs.append(obs)
    np.testing.assert_array_equal(outs[0], outs[1])


def test_row_model_is_permutation_equivariant():
    torch.manual_seed(0)
    net = RowRegimeNet(7, 5, 16)
    rows, glob = torch.randn(3, 5, 7), torch.randn(3, 5)
    perm = torch.tensor([3, 0, 4, 1, 2])
    r1, m1 = net(rows, glob)
    r2, m2 = net(rows[:, perm], glob)
    torch.testing.assert_close(r2, r1[:, perm])
    torch.testing.assert_close(m2, m1)


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    ds = collect(ENV, range(4), "mixed", TABLE, SHORT)
    assert ds.rows.shape[0] == 4 * 40 and ds.rows.shape[1] == 5
    train, val = split_episodes(ds)
    res = train_model(train, val, TrainConfig(hidden=8, epochs=1), log=lambda *_: None)
    env = make_vector_env(ENV, 3, SHORT)
    pol = SupervisedRowScalePolicy(env, res.model, TABLE, "expected")
    out = tmp_path_factory.mktemp("sup")
    save_policy(out, pol, ENV, SHORT, {"command": "test"})
    return env, pol, out


def test_save_load_round_trip_gives_identical_actions(trained):
    env, pol, out = trained
    back = load_policy(out, env)
    obs, _ = env.reset(seed=[7, 8, 9])
    stepper = native_vector_env(env).episode_stepper()
    for _ in range(10):
        a, _ = pol.predict(obs)
        b, _ = back.predict(obs)
        np.testing.assert_array_equal(a, b)
        assert a.shape == (3, 6) and (np.abs(a) <= 1).all()
        obs, *_ = stepper.step(a)


def test_wrong_feature_manifest_is_refused(trained, tmp_path):
    env, pol, out = trained
    for name in ("weights.pt", MANIFEST):
        (tmp_path / name).write_bytes((out / name).read_bytes())
    m = json.loads((tmp_path / MANIFEST).read_text())
    m["observation_layout"]["row_cn0"] = 4
    m["observation_layout"]["gnss_hdop_extra"] = 1
    (tmp_path / MANIFEST).write_text(json.dumps(m))
    with pytest.raises(SupervisedLoadError, match="row_cn0.*gnss_hdop_extra"):
        load_policy(tmp_path, env)
    (tmp_path / "weights.pt").write_bytes(b"changed")
    with pytest.raises(SupervisedLoadError, match="weights.pt changed"):
        load_policy(tmp_path, env)


def test_features_skip_the_policys_own_actions():
    env = make_vector_env(ENV, 2, SHORT)
    f = RowFeatures.of(native_vector_env(env).observation_features, 5)
    assert "row_cn0" in f.row_names and "imu_activity" in f.global_names
    assert not {"log_row_scale", "previous_action", "log_process_scale"} & set(f.global_names)


def test_command_quick(tmp_path, capsys):
    res = main(
        ["--env", ENV, "--train-episodes", "4", "--out", str(tmp_path), "--quick", "--n-boot", "50"]
        + ["--dagger", "1", "--mode", "iae_mix"]
    )
    assert (tmp_path / "report.md").is_file() and (tmp_path / MANIFEST).is_file()
    names = [r["policy"] for r in res["rows"]]
    assert "supervised" in names and "plain" in names
    assert "| supervised |" in capsys.readouterr().out
    m = json.loads((tmp_path / MANIFEST).read_text())
    assert m["training"]["train_seeds"] == [0, 8] and m["table"] == [1.0, 100.0, 1e4, 1.0, 10.0]
    assert len(m["training"]["rounds"]) == 2 and m["mode"] == "iae_mix"
    assert m["iae"] == {"b": 0.5, "beta": 0.5, "s_q": 1.0} and m["iae_q"] == "table"
    tune = main(
        ["--env", ENV, "--load", str(tmp_path), "--out", str(tmp_path / "t"), "--quick", "--n-boot", "50"]
        + ["--seed-kind", "tune", "--iae-q", "mix"]
    )
    assert tune["seed_kind"] == "tune" and tune["seeds"][0] >= 1_000_000
    assert "TUNING" in (tmp_path / "t" / "report.md").read_text()


def test_iae_mix_at_full_weight_is_row_iae(trained, monkeypatch):
    """``iae_mix`` with weight 1 gives the rows the tuned row_iae baseline's scales (same observations)."""
    from agents.baselines.registry import make_baseline
    from agents.supervised import policy as policy_module

    env, pol, _ = trained
    monkeypatch.setattr(policy_module, "IAE_WEIGHT", 1.0)
    tuned = policy_module.tuned_iae(ENV)
    assert tuned == {"b": 0.5, "beta": 0.5, "s_q": 1.0}  # the G2 zoo policy's values
    # the tuned b (one of the features' forgetting factors) and another b (its own average)
    for params, q in ((tuned, "table"), ({"b": 0.8, "beta": 2.0, "s_q": 30.0}, "iae")):
        mix = SupervisedRowScalePolicy(env, pol.model, TABLE, "iae_mix", params, q)
        iae = make_baseline(env, "row_iae", **params)
        obs, _ = env.reset(seed=[4, 5, 6])
        stepper = native_vector_env(env).episode_stepper()
        start = np.ones(3, bool)
        for _ in range(30):
            a, _ = mix.predict(obs, episode_start=start)
            b, _ = iae.predict(obs, episode_start=start)
            n = 6 if q == "iae" else 5
            np.testing.assert_allclose(a[:, :n], b[:, :n], atol=1e-6)
            obs, *_ = stepper.step(b)
            start[:] = False


def test_iae_mix_needs_the_tuned_file(trained, tmp_path):
    """No tuned row_iae: a clear error naming the file; the parameters are kept in the manifest."""
    from agents.supervised.policy import tuned_iae

    env, pol, _ = trained
    with pytest.raises(FileNotFoundError, match="nothere.json"):
        tuned_iae(ENV, tmp_path / "nothere.json")
    (tmp_path / "t.json").write_text(json.dumps({"env_id": ENV, "baselines": {"plain": {"params": {}}}}))
    with pytest.raises(FileNotFoundError, match="t.json has no tuned row_iae"):
        tuned_iae(ENV, tmp_path / "t.json")
    with pytest.raises(ValueError, match="needs row_iae"):
        SupervisedRowScalePolicy(env, pol.model, TABLE, "iae_mix")
    mix = SupervisedRowScalePolicy(env, pol.model, TABLE, "iae_mix", {"b": 0.8, "beta": 2.0, "s_q": 30.0})
    save_policy(tmp_path / "p", mix, ENV, SHORT)
    assert json.loads((tmp_path / "p" / MANIFEST).read_text())["iae"] == {"b": 0.8, "beta": 2.0, "s_q": 30.0}
    assert load_policy(tmp_path / "p", env).iae == mix.iae


def test_train_model_warm_start_keeps_normalization(trained):
    _, pol, _ = trained
    ds = collect(ENV, range(2), "plain", None, SHORT)
    res = train_model(ds, ds, TrainConfig(hidden=8, epochs=1), log=lambda *_: None, init=pol.model)
    torch.testing.assert_close(res.model.row_mean, pol.model.row_mean)
    assert res.model is not pol.model


def test_zoo_policy_loads_and_acts():
    """The shipped G2 policy: hashes and layout check, actions in bounds."""
    from pathlib import Path

    folder = Path(__file__).resolve().parents[3] / "agents" / "zoo" / "Robot2dRowScale-v3-supervised"
    env = make_vector_env(ENV, 2, SHORT)
    pol = load_policy(folder, env)
    assert pol.mode == "iae_mix" and pol.table.tolist() == [1.0, 100.0, 1e4, 1.0, 10.0]
    obs, _ = env.reset(seed=[1, 2])
    a, _ = pol.predict(obs)
    assert a.shape == (2, 6) and (np.abs(a) <= 1).all()
    env.close()


def test_the_v3_zoo_policies_load_and_act():
    """The shipped Quadrotor, Pedestrian and GpsIns G2 policies: mode, table, row_iae's tuned parameters."""
    from pathlib import Path

    folder = Path(__file__).resolve().parents[3] / "agents" / "zoo" / "QuadrotorRowScale-v3-supervised"
    for name, mode, q, table, iae in (
        ("QuadrotorRowScale-v3", "expected", "table", [0.3, 3.0, 1000.0, 0.1, 1e4], (0.8, 0.5, 1000.0)),
        ("PedestrianRowScale-v3", "iae_mix", "mix", [1.0, 100.0, 1000.0, 1000.0, 1e4], (0.8, 2.0, 1e4)),
        ("GpsInsRowScale-v3", "iae_mix", "table", [0.3, 3.0, 1000.0, 0.1, 1000.0], (0.8, 0.5, 100.0)),
    ):
        env = make_vector_env(f"navgym/{name}", 2, SHORT)
        pol = load_policy(folder.parent / f"{name}-supervised", env)
        assert (pol.mode, pol.iae_q, pol.table.tolist()) == (mode, q, table)
        assert pol.iae == dict(zip(("b", "beta", "s_q"), iae, strict=True))
        obs, _ = env.reset(seed=[1, 2])
        a, _ = pol.predict(obs)
        assert a.shape == (2, pol.task.m_max + 1) and (np.abs(a) <= 1).all()
        env.close()


def test_navgym_eval_takes_a_supervised_folder(tmp_path):
    """``supervised:DIR`` is a policy spec of ``navgym eval``, scored beside the baselines."""
    from pathlib import Path

    from agents.evaluation.cli import run_eval

    folder = Path(__file__).resolve().parents[3] / "agents" / "zoo" / "Robot2dRowScale-v3-supervised"
    res = run_eval(
        ENV,
        ["plain", f"g2=supervised:{folder}"],
        episodes=2,
        out=tmp_path,
        env_kwargs={"max_episode_steps": 20},
        tuned=False,
        plots=False,
        progress=False,
        n_boot=50,
    )
    assert set(res.episodes) == {"plain", "g2"}
    assert np.isfinite(res.episodes["g2"]["rmse_m"]).all() and len(res.episodes["g2"]["rmse_m"]) == 2
