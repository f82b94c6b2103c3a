"""experiments.knob_reach: the regime codes, the regime oracle's actions, a tiny study."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from experiments.knob_reach.__main__ import (
    GRIDS,
    REGIMES,
    RegimeOracle,
    action_grid,
    regime_codes,
    study,
    task_of,
)

TINY = {"episode_steps": 30, "max_episode_steps": 30}


def _ev(start: float, end: float) -> SimpleNamespace:
    return SimpleNamespace(start=start, end=end)


def test_regime_codes_take_the_latest_regime_of_overlapping_events():
    sc = SimpleNamespace(
        outages=(_ev(1.0, 2.0),), canyons=(_ev(1.5, 4.0),), jamming=(), multipath=(), bursts=(_ev(3.5, 3.5),)
    )
    codes = regime_codes([sc], np.array([0.5, 1.0, 1.5, 2.0, 3.0, 3.5, 4.5]))
    names = [REGIMES[c] for c in codes[0]]
    assert names == ["none", "outage", "canyon", "canyon", "canyon", "burst", "none"]


def test_regime_oracle_plays_the_table_row_of_each_step_and_restarts_per_episode():
    codes = np.array([[0, 2, 5], [1, 1, 0]])
    table = np.arange(len(REGIMES) * 2, dtype=np.float32).reshape(len(REGIMES), 2) / 10
    oracle = RegimeOracle(codes, table)
    first, _ = oracle.predict(np.zeros((2, 3)), episode_start=np.ones(2, bool))
    second, _ = oracle.predict(np.zeros((2, 3)), episode_start=np.zeros(2, bool))
    np.testing.assert_array_equal(first, table[[0, 1]])
    np.testing.assert_array_equal(second, table[[2, 1]])
    again, _ = oracle.predict(np.zeros((2, 3)), episode_start=np.ones(2, bool))
    np.testing.assert_array_equal(again, table[[0, 1]])


def test_only_fading_noisescale_and_rowscale_ids_are_covered():
    assert task_of("navgym/Robot2dNoiseScale-v2") == "NoiseScale"
    assert task_of("navgym/GpsInsRowScale-v3") == "RowScale"
    with pytest.raises(ValueError, match="env_id"):
        task_of("navgym/Robot2dMixture-v2")
    assert task_of("navgym/GpsInsRowScale-v3", {"task": "noisescale"}) == "NoiseScale"
    with pytest.raises(ValueError, match="task='mixture'"):
        task_of("navgym/GpsInsRowScale-v3", {"task": "mixture"})


def _nav(lo, hi):
    return SimpleNamespace(task=SimpleNamespace(log_low=np.log10(lo), log_high=np.log10(hi)))


def test_the_noise_scale_grid_follows_the_task_ranges_and_holds_the_plain_filter():
    v2 = action_grid("NoiseScale", _nav([0.1, 0.1], [100.0, 100.0]))
    np.testing.assert_allclose(v2, GRIDS["NoiseScale"], atol=1e-12)  # half decades, as before
    wide = np.asarray(action_grid("NoiseScale", _nav([0.1, 0.1], [1e4, 1e4])))
    scales = 10.0 ** (-1.0 + (wide + 1.0) / 2.0 * 5.0)
    np.testing.assert_allclose(scales, [0.1, 1.0, 10.0, 100.0, 1e3, 1e4], rtol=1e-12)
    assert action_grid("Fading", None) == GRIDS["Fading"]


def test_tiny_study_searches_on_tuning_seeds_and_never_worsens_the_constant():
    r = study("navgym/Robot2dNoiseScale-v2", 2, 3, n_boot=200, progress=False, env_kwargs=TINY)
    assert r["table_tune_rmse_m"] <= r["constant_tune_rmse_m"]
    assert set(r["eval_rmse_m"]) == {"plain", r["best_tuned"], "regime oracle"}
    assert r["reach_low"] <= r["reach"] <= r["reach_high"]
    assert set(r["table"]) == set(REGIMES)


def test_the_row_regime_search_excludes_a_biased_row_on_the_toy():
    import gymnasium as gym

    from experiments.knob_reach.row_regimes import ENTRIES, search_row_table
    from tests.navgym.envs.toy_v2 import ToyEnv, ToyVectorEnv

    env_id = "navgym-test/ToyV2RowScale-v0"
    if env_id not in gym.registry:
        gym.register(env_id, entry_point=ToyEnv, vector_entry_point=ToyVectorEnv, max_episode_steps=40,
                     kwargs={"task": "rowscale"})  # fmt: skip
    # row 1 carries a 5-sigma bias all episode: its regime is "biased", row 0's "nominal"
    const, const_rmse, table, rmse = search_row_table(env_id, [0, 1, 2, 3], False, {"bias": (0.0, 15.0)})
    assert rmse <= const_rmse
    found = dict(zip(ENTRIES, table, strict=True))
    assert found["s_biased"] >= 100.0 * found["s_nominal"], found
    assert rmse < 0.8 * const_rmse


def test_the_row_regime_search_starts_from_a_given_table_and_only_improves_it():
    import gymnasium as gym

    from experiments.knob_reach.row_regimes import search_row_table
    from tests.navgym.envs.toy_v2 import ToyEnv, ToyVectorEnv

    env_id = "navgym-test/ToyV2RowScale-v0"
    if env_id not in gym.registry:
        gym.register(env_id, entry_point=ToyEnv, vector_entry_point=ToyVectorEnv, max_episode_steps=40,
                     kwargs={"task": "rowscale"})  # fmt: skip
    start = (1.0, 1.0, 1.0, 1.0, 1.0)
    const, const_rmse, table, rmse = search_row_table(
        env_id, [0, 1, 2, 3], False, {"bias": (0.0, 15.0)}, start=start, passes=1
    )
    np.testing.assert_array_equal(const, start)  # no grid of constants: the start is the constant
    assert rmse < 0.8 * const_rmse  # one pass finds the biased row's exclusion


def test_the_bounds_probe_replays_the_table_and_pushes_only_the_entries_at_an_end():
    from experiments.knob_reach.bounds import actions_of, probe, scales_of

    lo, hi = np.log10([0.1, 0.1]), np.log10([1e4, 1e4])
    table = {r: [-1.0, 0.2] for r in REGIMES}  # s_q at the low end, s_r = 100 inside
    s = scales_of(table, lo, hi)
    np.testing.assert_allclose(s[0], [0.1, 100.0])
    np.testing.assert_allclose(actions_of(s, lo, hi), [[-1.0, 0.2]] * len(REGIMES))
    kw = {"task": "noisescale", "motion_q": True, "q_scale_range": (0.1, 1e4), "r_scale_range": (0.1, 1e4)}
    result = {"env_id": "navgym/Robot2dRowScale-v3", "env_kwargs": {**kw, **TINY}, "table": table}
    r = probe(result, widen=100.0, episodes=2)
    assert r["entries_at_an_end"] == len(REGIMES)  # every s_q, no s_r
    assert r["table_rmse_m"] > 0 and r["pushed_rmse_m"] > 0
    assert r["table_rmse_m"] != r["pushed_rmse_m"]  # s_q 1e-3 instead of 0.1 changes the filter
