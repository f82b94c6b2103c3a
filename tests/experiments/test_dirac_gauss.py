"""Dirac-Gauss DPF n.d. study: the correlator model, the truth simulation and a quick end-to-end run."""

import json

import numpy as np
import pytest

from experiments.dirac_gauss.__main__ import main
from navgym.signal_tracking.models import (
    CHIP_M,
    CODES_PER_BIT,
    LAMBDA_L1,
    T_CODE,
    SignalConfig,
    SignalModel,
    simulate_truth,
    transition_matrix,
)


def test_jacobian_matches_finite_differences():
    model = SignalModel(SignalConfig(snr_db=0.0))
    rng = np.random.default_rng(0)
    K = 6
    x = np.column_stack(
        [np.full(K, 1.4), rng.uniform(-3, 3, K), rng.uniform(-100, 100, K), rng.normal(0, 50, K), np.zeros(K)]
    )
    prompt = x[:, 2] + rng.uniform(-0.4, 0.4, K) * CHIP_M  # every tap on a slope of the pulse
    mode = rng.integers(0, 2 * CODES_PER_BIT, K)
    J = model.H(x, mode, prompt)
    for i, step in enumerate([1e-6, 1e-7, 1e-4, 1e-4, 1e-4]):
        dx = np.zeros(5)
        dx[i] = step
        num = (model.h(x + dx, mode, prompt) - model.h(x - dx, mode, prompt)) / (2 * step)
        np.testing.assert_allclose(J[:, :, i], num, rtol=1e-5, atol=1e-7)


def test_mode_transitions_follow_the_bits():
    model = SignalModel(SignalConfig())
    mode = np.array([0, 5, CODES_PER_BIT - 1, CODES_PER_BIT + 3, 2 * CODES_PER_BIT - 1])
    children, logp = model.mode_children(mode, 0)
    # within a bit: the next code of the same bit, surely; at its last code: a new bit, +-
    assert children[:, 0].tolist() == [1, 6, 0, CODES_PER_BIT + 4, CODES_PER_BIT]
    assert children[2, 1] == CODES_PER_BIT and children[4, 1] == 0
    np.testing.assert_allclose(np.exp(logp).sum(axis=1), 1.0)
    assert np.isneginf(logp[[0, 1, 3], 1]).all()


def test_carrier_phase_follows_the_range():
    F = transition_matrix(SignalConfig())
    x = np.array([1.0, 0.3, 0.0, 100.0, 0.0])
    y = F @ x
    assert y[2] == pytest.approx(100.0 * T_CODE)
    assert y[1] - x[1] == pytest.approx(-2 * np.pi * (y[2] - x[2]) / LAMBDA_L1)


def test_truth_of_a_batch_equals_single_runs_and_keeps_the_first_bit():
    cfg = SignalConfig(jump_rate=5.0)
    batch = simulate_truth(cfg, [np.random.default_rng(s) for s in (3, 4)], 300)
    one = simulate_truth(cfg, [np.random.default_rng(4)], 300)
    np.testing.assert_allclose(batch.x[1], one.x[0], rtol=1e-12, atol=1e-9)  # the same draws; BLAS rounding
    np.testing.assert_array_equal(batch.mode[1], one.mode[0])
    assert (batch.mode[:, 0] < CODES_PER_BIT).all()  # the first bit is +1
    # codes advance one per step and bits change only at code 0
    c = batch.mode % CODES_PER_BIT
    assert ((c[:, 1:] - c[:, :-1]) % CODES_PER_BIT == 1).all()
    changed = (batch.mode[:, 1:] // CODES_PER_BIT) != (batch.mode[:, :-1] // CODES_PER_BIT)
    assert (c[:, 1:][changed] == 0).all()


def test_quick_study_runs_and_reports(tmp_path):
    assert main(["--quick", "--out", str(tmp_path)]) == 0
    report = (tmp_path / "report.md").read_text()
    assert "deterministic" in report and "random" in report
    assert (tmp_path / "doppler.png").stat().st_size > 0
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["filters"] == [["deterministic", 24], ["random", 24], ["random", 200]]
    rows = (tmp_path / "table.csv").read_text().splitlines()
    assert len(rows) == 4  # header + three filters


def test_bit_metrics_count_a_half_cycle_slip_once_differentially():
    from experiments.dirac_gauss.run import RunResult, metrics

    cfg = SignalConfig(jump_rate=0.0)
    truth = simulate_truth(cfg, [np.random.default_rng(9)], 1500)
    p_minus = (truth.mode >= CODES_PER_BIT).astype(float)
    perfect = metrics(truth, RunResult(truth.x.copy(), p_minus, np.ones((1, 1500)), 0.0))
    assert perfect["bit_errors"][0] == 0 and perfect["transition_errors"][0] == 0
    assert perfect["transitions"][0] == perfect["bits"][0] - 1 > 50 and perfect["jumps"][0] == 0
    slipped = p_minus.copy()
    slipped[:, 800:] = 1.0 - slipped[:, 800:]  # every bit inverted from 0.8 s on
    m = metrics(truth, RunResult(truth.x.copy(), slipped, np.ones((1, 1500)), 0.0))
    assert m["transition_errors"][0] == 1 and m["bit_errors"][0] > 20
    assert not m["lost"][0] and m["range_rmse_m"][0] == 0.0
