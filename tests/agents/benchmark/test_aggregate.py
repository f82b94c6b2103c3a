"""IQM and the stratified bootstrap across training seeds (agents.benchmark.aggregate)."""

import numpy as np
import pytest
from scipy import stats

from agents.benchmark.aggregate import across_seeds, iqm, mean, stratified_bootstrap_ci


def test_iqm_of_known_numbers():
    assert iqm([1, 2, 3, 4, 5, 6, 7, 8]) == pytest.approx(4.5)  # 2 cut at each end: mean(3, 4, 5, 6)
    assert iqm([1, 2, 3, 4, 100]) == pytest.approx(3.0)  # int(1.25) = 1 cut at each end
    assert iqm([1.0, 2.0, 30.0]) == pytest.approx(11.0)  # n < 4: nothing cut, the mean
    x = np.random.default_rng(0).normal(size=(7, 3))
    assert iqm(x, axis=None) == pytest.approx(stats.trim_mean(x, 0.25, axis=None))  # rliable's aggregate_iqm


def test_iqm_is_vectorized_over_resamples():
    x = np.arange(24.0).reshape(3, 8)
    np.testing.assert_allclose(iqm(x), [iqm(r) for r in x])


def test_one_run_per_task_has_a_zero_width_interval():
    assert stratified_bootstrap_ci([[1.0], [5.0]], mean) == (3.0, 3.0, 3.0)


def test_the_bootstrap_resamples_within_each_task_only():
    # two tasks, each constant over its runs: any within-task resample keeps the mean at 5, an
    # unstratified one (runs drawn from the pooled values) would not
    scores = np.column_stack([np.zeros(4), np.full(4, 10.0)])  # (runs, tasks)
    assert stratified_bootstrap_ci(scores, mean, reps=500) == (5.0, 5.0, 5.0)
    # ragged strata keep their own sizes: 1 run of 10 and 3 of 0 always average 2.5
    assert stratified_bootstrap_ci([[10.0], [0.0, 0.0, 0.0]], mean, reps=500) == (2.5, 2.5, 2.5)


def test_interval_of_one_task_brackets_the_mean_and_is_seeded():
    x = np.random.default_rng(1).normal(5.5, 3.0, size=10)
    v, lo, hi = stratified_bootstrap_ci(x, mean, reps=4000, seed=3)
    assert v == pytest.approx(x.mean()) and x.min() < lo < v < hi < x.max()
    assert (v, lo, hi) == stratified_bootstrap_ci(x, mean, reps=4000, seed=3)
    assert (lo, hi) != stratified_bootstrap_ci(x, mean, reps=4000, seed=4)[1:]
    # the 95 % interval of a mean of 10 values is about 2 x 1.96 sd / sqrt(10) wide
    width = 2 * 1.96 * x.std() / np.sqrt(10)
    assert 0.7 * width < hi - lo < 1.3 * width


def test_a_list_of_numbers_is_one_task():
    a = across_seeds([1.0, 2.0, 3.0, 10.0], reps=2000)
    assert a["n_runs"] == 4
    assert a["mean"] == pytest.approx(4.0) and a["iqm"] == pytest.approx(2.5)
    assert a["mean_low"] < a["mean"] < a["mean_high"]
    assert a["iqm_low"] <= a["iqm"] <= a["iqm_high"] and a["iqm_low"] < a["iqm_high"]


@pytest.mark.parametrize(
    ("scores", "kwargs", "match"),
    [
        ([], {}, "at least one task"),
        ([[1.0], []], {}, "at least one task and one run"),
        ([1.0, float("nan")], {}, "finite"),
        ([1.0, 2.0], {"level": 1.0}, "level"),
        ([1.0, 2.0], {"reps": 0}, "reps"),
        (np.zeros((2, 2, 2)), {}, "runs, tasks"),
    ],
)
def test_bad_inputs_are_refused(scores, kwargs, match):
    with pytest.raises(ValueError, match=match):
        stratified_bootstrap_ci(scores, mean, **kwargs)
