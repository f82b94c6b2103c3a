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
