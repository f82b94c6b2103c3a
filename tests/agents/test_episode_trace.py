"""agents.evaluation.episode_trace: one episode's knob, error and regimes, per policy."""

from pathlib import Path

import numpy as np
import pytest

from agents.baselines.registry import load_tuned, make_baselines
from agents.evaluation.episode_trace import _regime_rows, episode_trace, plot_episode_trace
from agents.evaluation.runner import make_vector_env, rollout

ENV = "navgym/Robot2dMixture-v2"
KW = {"episode_steps": 50, "max_episode_steps": 50}


def _baselines():
    env = make_vector_env(ENV, 1, KW)
    return make_baselines(env, load_tuned(ENV), names=["zero", "constant"])


def test_the_trace_replays_the_evaluated_episode():
    pols = _baselines()
    trace = episode_trace(ENV, pols, seed=2_000_000_007, env_kwargs=KW)
    assert trace.t.shape == (50,) and trace.t[0] == pytest.approx(0.1)
    assert trace.knob["zero"].shape == (50, 5) and np.all(trace.knob["zero"] == 0.0)
    assert np.all(trace.knob["constant"][:, :4] > 0.0)  # a tuned constant weight on the GNSS rows
    # the same episode as the batched evaluation of that seed (sub-env 1 of 2)
    env = make_vector_env(ENV, 2, KW)
    r = rollout(env, pols["constant"], [2_000_000_001, 2_000_000_007])
    np.testing.assert_allclose(trace.pos_err_m["constant"], r.steps["pos_err_m"][1], rtol=1e-12)
    assert not np.allclose(trace.pos_err_m["zero"], trace.pos_err_m["constant"])
    assert trace.scenario.duration > 0


def test_regime_lanes_and_the_plot(tmp_path: Path):
    trace = episode_trace(ENV, _baselines(), seed=2_000_000_000, env_kwargs=KW)
    lanes = _regime_rows(trace.scenario)
    sc = trace.scenario
    expected = {f"multipath row {m.row}" for m in sc.multipath}
    expected |= {"GNSS outage"} if sc.outages else set()
    expected |= {"process-noise burst"} if sc.bursts else set()
    assert expected <= {lane[0] for lane in lanes}
    for label, _, spans in lanes:
        assert all(a <= b for a, b in spans), label
    p = plot_episode_trace(trace, tmp_path / "k.png")
    assert p.is_file() and p.stat().st_size > 10_000


def test_no_policy_is_an_error():
    with pytest.raises(ValueError, match="policies is empty"):
        episode_trace(ENV, {}, seed=1)


def test_a_v3_trace_keeps_the_observed_c_n0_per_row_and_names_the_process_scale(tmp_path: Path):
    from navgym.envs.base import navigation_env

    env_id = "navgym/Robot2dRowScale-v3"
    env = make_vector_env(env_id, 1, KW)
    nav = navigation_env(env)
    m = nav.task.m_max
    pols = make_baselines(env, load_tuned(env_id), names=["plain", "row_iae"])
    trace = episode_trace(env_id, pols, seed=2_000_000_003, env_kwargs=KW)
    cn0 = trace.context["row_cn0"]
    assert cn0.shape == (50, m)
    # what the observation carried after each step of the first policy (plain) on that episode
    cols = nav.observation_features.index("row_cn0")
    env.reset(seed=[2_000_000_003])
    for k in range(3):
        obs, *_ = env.step(nav.task.neutral_action()[None, :])
        np.testing.assert_array_equal(cn0[k], obs[0, cols])
    assert (cn0 > 0).any() and (cn0 <= 60.0).all()
    assert trace.knob_labels == (*(f"row {j}" for j in range(m)), "s_q")
    assert np.all(trace.knob["plain"] == 1.0) and trace.knob["row_iae"].shape == (50, m + 1)
    assert plot_episode_trace(trace, tmp_path / "v3.png").stat().st_size > 10_000
    env.close()
