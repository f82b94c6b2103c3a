"""agents.evaluation.comparison: capture share, ΔRMSE %, the verdict and its sentence."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agents.evaluation.comparison import capture_share, delta_rmse, verdict, verdict_sentence


def test_capture_share_of_a_hand_example():
    # plain 5, agent 3, clairvoyant 1 (means): the agent closes (5 - 3) / (5 - 1) of the gap
    c = capture_share(np.array([4.0, 6.0]), np.array([2.0, 4.0]), np.array([1.0, 1.0]), n_boot=500)
    assert c["capture"] == 0.5 and c["gap_m"] == 4.0 and c["n"] == 2
    # the resamples of two episodes: (0, 0) -> 2/3, (1, 1) -> 2/5, mixed -> 1/2
    assert 0.4 <= c["low"] <= 0.5 <= c["high"] <= 2.0 / 3.0
    one = capture_share(np.array([3.0]), np.array([2.0]), np.array([1.0]))
    assert one["capture"] == one["low"] == one["high"] == 0.5


def test_capture_share_resamples_the_three_jointly():
    rng = np.random.default_rng(3)
    clair = rng.uniform(1.0, 5.0, 200)  # a large spread between episodes
    plain = clair + rng.uniform(1.0, 10.0, 200)
    agent = plain - 0.3 * (plain - clair)  # every episode closes exactly 30 % of its gap
    c = capture_share(plain, agent, clair)
    assert c["capture"] == pytest.approx(0.3)
    assert c["low"] == pytest.approx(0.3) and c["high"] == pytest.approx(0.3)  # pairing cancels the spread


def test_capture_share_without_a_gap_or_with_nonfinite_episodes():
    c = capture_share(np.ones(3), np.ones(3), np.ones(3))
    assert math.isnan(c["capture"]) and math.isnan(c["low"])
    c = capture_share(np.array([4.0, np.nan, 6.0]), np.array([2.0, 1.0, 4.0]), np.array([1.0, 1.0, 1.0]))
    assert c["n"] == 2 and c["capture"] == 0.5
    with pytest.raises(ValueError, match="equal lengths"):
        capture_share(np.ones(3), np.ones(2), np.ones(3))


def test_delta_rmse_is_the_paired_difference_over_the_reference_mean():
    ref = np.array([4.0, 4.0, 4.0, 4.0])
    agent = np.array([3.5, 3.5, 3.75, 3.25])  # differences -0.5, -0.5, -0.25, -0.75
    d = delta_rmse(agent, ref, n_boot=500)
    assert d["delta_m"] == -0.5 and d["delta_pct"] == -12.5 and d["reference_rmse_m"] == 4.0
    assert -18.75 <= d["low_pct"] <= -12.5 <= d["high_pct"] <= -6.25
    assert d["low_pct"] == pytest.approx(25.0 * d["low_m"]) and d["n"] == 4
    assert verdict(d["delta_pct"], d["low_pct"], d["high_pct"]) == "target met"


def test_verdict_reads_the_ci_and_the_10_percent_target():
    assert verdict(-12.0, -15.0, -9.0) == "target met"
    assert verdict(-10.0, -12.0, -8.0) == "target met"  # the target is inclusive
    assert verdict(-9.9, -12.0, -8.0) == "beats"
    assert verdict(-5.0, -8.0, -2.0) == "beats"
    assert verdict(-12.0, -20.0, 1.0) == "ties"  # a large mean gain, but the CI holds 0
    assert verdict(-1.0, -2.0, 0.0) == "ties"  # a CI ending at 0 contains it
    assert verdict(3.0, 1.0, 5.0) == "worse"
    assert verdict(-3.0, -5.0, -1.0, target_pct=2.0) == "target met"
    assert verdict(float("nan"), float("nan"), float("nan")) == "n/a"


def test_verdict_sentence_says_whether_the_agent_beats_with_the_ci():
    ref = np.full(8, 4.0)
    worse = delta_rmse(ref + np.linspace(0.1, 0.3, 8), ref, n_boot=500)
    s = verdict_sentence("navgym/X-v2", "learned", "chi_square", worse)
    assert "does not beat (it is worse than)" in s and "`chi_square`" in s and "(8 held-out episodes)" in s
    assert f"{worse['delta_pct']:+.1f} % [{worse['low_pct']:+.1f}, {worse['high_pct']:+.1f}]" in s
    better = delta_rmse(ref - np.linspace(0.1, 0.3, 8), ref, n_boot=500)
    assert " beats the best tuned" in verdict_sentence("navgym/X-v2", "learned", "chi_square", better)
    tie = delta_rmse(ref + np.array([-1.0, 1.0] * 4), ref, n_boot=500)
    assert "a tie within the CI" in verdict_sentence("navgym/X-v2", "learned", "chi_square", tie)
