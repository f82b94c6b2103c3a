"""Resampling triggers: ESS threshold and Carvalho et al. 1997's redistribution rule."""

import numpy as np
import pytest

from filters.particle import triggers


def test_ess_trigger():
    N = 100
    uniform = np.zeros((1, N))
    degenerate = np.full((1, N), -np.inf)
    degenerate[0, 3] = 0.0
    half = np.where(np.arange(N) < 50, 0.0, -np.inf)[None]  # ESS = 50 exactly
    lw = np.concatenate([uniform, degenerate, half])
    assert triggers.ess_trigger(lw, 0.5).tolist() == [False, True, False]
    assert triggers.ess_trigger(lw, 0.51).tolist() == [False, True, True]
    assert triggers.ess_trigger(lw, 1.0).tolist() == [False, True, True]
    assert not triggers.ess_trigger(lw, 0.0).any()
    assert triggers.ess_trigger(lw, np.array([0.0, 0.0, 0.9])).tolist() == [False, False, True]


def test_redistribution_rule_of_carvalho_1997():
    """More than 10% of the particles below 1/(10N) triggers (Carvalho et al. 1997, §V)."""
    N = 100

    def cloud(n_light):
        w = np.full(N, 1e-4)  # light: 1e-4 < 1/(10N) = 1e-3
        w[n_light:] = (1.0 - 1e-4 * n_light) / (N - n_light)
        return np.log(w)

    lw = np.stack([cloud(0), cloud(10), cloud(11), cloud(60)])
    assert triggers.redistribution_trigger(lw).tolist() == [False, False, True, True]
    # unnormalized weights give the same answer
    assert triggers.redistribution_trigger(lw + 7.0).tolist() == [False, False, True, True]
    # the knobs are per filter
    got = triggers.redistribution_trigger(
        lw, weight_factor=np.array([0.1, 0.1, 0.005, 0.1]), count_fraction=np.array([0.1, 0.05, 0.1, 0.7])
    )
    assert got.tolist() == [False, True, False, False]


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda lw: triggers.ess_trigger(lw, 1.5), "threshold_fraction"),
        (lambda lw: triggers.ess_trigger(lw, -0.1), "threshold_fraction"),
        (lambda lw: triggers.ess_trigger(lw, np.nan), "threshold_fraction"),
        (lambda lw: triggers.ess_trigger(lw, np.ones(3)), "threshold_fraction"),
        (lambda lw: triggers.redistribution_trigger(lw, weight_factor=0.0), "weight_factor"),
        (lambda lw: triggers.redistribution_trigger(lw, weight_factor=2.0), "weight_factor"),
        (lambda lw: triggers.redistribution_trigger(lw, count_fraction=-1.0), "count_fraction"),
        (lambda lw: triggers.ess_trigger(lw[:, :0]), "N >= 1"),
        (lambda lw: triggers.ess_trigger(np.where(lw == lw, np.nan, 0)), "log_w"),
    ],
)
def test_trigger_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call(np.zeros((2, 5)))
