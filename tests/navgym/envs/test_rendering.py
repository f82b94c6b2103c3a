"""Rendering: human mode, the frame's content, readable axes after divergence, ``navgym render``."""

from __future__ import annotations

import os

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import navgym  # noqa: F401
from navgym.envs import rendering
from navgym.scenarios.scenario import Outage, Scenario


def test_human_is_a_render_mode_and_runs_under_a_non_interactive_backend(monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    env = gym.make("navgym/Robot2dFading-v2", render_mode="human")
    assert "human" in env.metadata["render_modes"]
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    assert env.render() is None
    env.close()


def test_check_env_with_rgb_array():
    env = gym.make("navgym/SignalTrackingJumps-v2", render_mode="rgb_array")
    check_env(env.unwrapped)


def test_rendering_does_not_change_the_numbers():
    def run(mode):
        env = gym.make("navgym/GpsInsFading-v2", render_mode=mode)
        obs, _ = env.reset(seed=3)
        out = [obs]
        for _ in range(4):
            obs, r, *_ = env.step(np.full(env.action_space.shape, 0.3, np.float32))
            if mode:
                env.render()
            out += [obs, np.atleast_1d(r)]
        return np.concatenate([np.ravel(o) for o in out])

    np.testing.assert_array_equal(run(None), run("rgb_array"))


def test_active_events_from_the_scenario():
    sc = Scenario(outages=(Outage(10.0, 20.0),))
    assert rendering.active_events(sc, 15.0) == ["outage"]
    assert rendering.active_events(sc, 25.0) == []
    assert rendering.active_events(None, 0.0) == []


def _row(truth, est, t=1.0):
    return {
        "truth_pos": np.array(truth, float),
        "est_pos": np.array(est, float),
        "gnss_available": True,
        "pos_err_m": float(np.linalg.norm(np.subtract(est, truth))),
        "cov_ne": np.eye(2) * 1e10,
        "knob": np.array(0.5),
        "t": t,
        "reward": -1.0,
        "context": {"fading": 1.2},
    }


def test_a_diverged_estimate_keeps_the_map_at_the_truth_scale():
    r = rendering.FrameRenderer("GpsIns")
    hist = [_row([0, 0], [0, 0], 0.0), _row([10, 10], [3e5, 0], 1.0)]
    frame = r.draw(hist, Scenario(outages=(Outage(0.5, 5.0),)))
    assert frame.shape == (384, 512, 3) and frame.dtype == np.uint8
    x0, x1 = r.ax.get_xlim()
    assert x1 - x0 < 1000  # not a 300 km map
    assert "off-scale" in r.t_off.get_text()
    text = r.status.get_text()
    assert "knob=0.5" in text and "reward=-1" in text and "outage" in text and "fading=1.2" in text


def test_signal_tracking_draws_range_and_doppler_over_time():
    env = gym.make("navgym/SignalTrackingJumps-v2", render_mode="rgb_array")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.step(env.action_space.sample())
    assert env.render().ndim == 3
    r = env.unwrapped._renderer
    assert r.one_dimensional and r.ax.get_xlabel() == "t [s]"
    env.close()


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_navgym_render_writes_a_short_video(tmp_path, suffix):
    from navgym.cli import main

    out = tmp_path / f"episode{suffix}"
    rc = main(["render", "navgym/Robot2dFading-v2", "--seed", "1", "--out", str(out), "--steps", "3"])
    assert rc == 0 and out.exists() and os.path.getsize(out) > 1000
    head = out.read_bytes()[:12]
    assert head[:3] == b"GIF" if suffix == ".gif" else head[4:8] == b"ftyp"
