"""Dirac-Gauss particle filters (Dirac-Gauss DPF n.d., §2): neutral settings, exact branching, selection."""

import itertools

import numpy as np
import pytest

from filters import GaussianState, kalman
from filters.core.models import LinearTransition
from filters.particle import dirac_gauss as dg


class SwitchingRange:
    """2-D constant-velocity target, a range to a beacon plus a mode-dependent bias (2 modes).

    Mode 1 adds ``offset`` to the range (a hypothesis the filters must weigh); the mode switches
    with probability ``p_switch`` per step (J = 2 children, both possible). ``jumps``: optional
    velocity-jump grid for the deterministic filter.
    """

    def __init__(self, p_switch=0.2, offset=3.0, single_mode=False, jumps=None):
        dt = 1.0
        self.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        self.Q = np.diag([0.01, 0.01, 0.05, 0.05])
        self.R = np.diag([0.5, 0.02])
        self.beacon = np.array([30.0, -10.0])
        self.offset, self.p, self.single = offset, p_switch, single_mode
        grid = np.zeros((1, 4)) if jumps is None else np.asarray(jumps, float)
        self.jump_grid = grid
        self.jump_log_prob = np.log(np.full(len(grid), 1.0 / len(grid)))
        self.jump_cov = np.zeros((len(grid), 4, 4))

    def mode_children(self, mode, k):
        if self.single:
            return mode[..., None], np.zeros((*mode.shape, 1))
        children = np.stack([mode, 1 - mode], axis=-1)
        logp = np.broadcast_to(np.log([1.0 - self.p, self.p]), children.shape)
        return children, logp

    def sample_jump(self, rng, B, N):
        return np.zeros((B, N, 4))

    def h(self, x, mode, aux):
        d = x[:, :2] - self.beacon
        r = np.sqrt((d * d).sum(axis=1)) + self.offset * mode
        return np.stack([r, np.arctan2(d[:, 1], d[:, 0])], axis=1)

    def H(self, x, mode, aux):
        d = x[:, :2] - self.beacon
        r2 = (d * d).sum(axis=1)
        r = np.sqrt(r2)
        J = np.zeros((x.shape[0], 2, 4))
        J[:, 0, 0], J[:, 0, 1] = d[:, 0] / r, d[:, 1] / r
        J[:, 1, 0], J[:, 1, 1] = -d[:, 1] / r2, d[:, 0] / r2
        return J


class _Fixed:
    """EKF observation model of one mode (reference updates)."""

    def __init__(self, model, mode):
        self.model, self.mode, self.R = model, mode, model.R

    def h(self, x):
        return self.model.h(x, np.full(x.shape[0], self.mode), None)

    def H(self, x):
        return self.model.H(x, np.full(x.shape[0], self.mode), None)


def _prior(B=3, seed=0):
    rng = np.random.default_rng(seed)
    m0 = np.column_stack([rng.normal(0, 2, B), rng.normal(0, 2, B), np.ones(B), np.full(B, 0.5)])
    P0 = np.broadcast_to(np.diag([4.0, 4.0, 0.5, 0.5]), (B, 4, 4)).copy()
    return m0, P0


def _ekf_step(model, mode, m, P, z):
    pred = kalman.predict(GaussianState(m, P), LinearTransition(model.F, model.Q))
    return kalman.update(pred, z, _Fixed(model, mode))


def _zs(model, steps, B, seed=1):
    rng = np.random.default_rng(seed)
    x = np.column_stack([np.zeros(B), np.zeros(B), np.ones(B), np.full(B, 0.5)])
    out = []
    for _ in range(steps):
        x = x @ model.F.T
        out.append(model.h(x, np.zeros(B, int), None) + rng.normal(0, [0.7, 0.14], (B, 2)))
    return out


def test_one_hypothesis_equals_the_ekf():
    """One particle, one mode, no jump grid: both filters are the EKF exactly."""
    model = SwitchingRange(single_mode=True)
    m0, P0 = _prior()
    zs = _zs(model, 5, 3)
    det = rnd = dg.initial_state(m0, P0, np.zeros((3, 1), int))
    m, P = m0, P0
    rngs = [np.random.default_rng(i) for i in range(3)]
    for k, z in enumerate(zs):
        det, dinfo = dg.deterministic_step(det, z, model, k)
        rnd, rinfo = dg.random_step(rnd, z, model, k, rngs)
        assert dinfo.healthy.all() and rinfo.healthy.all()
        ref, _ = _ekf_step(model, 0, m, P, z)
        m, P = ref.m, ref.P
        for s in (det, rnd):
            np.testing.assert_allclose(s.m[:, 0], m, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(s.P[:, 0], P, rtol=1e-12, atol=1e-12)
            np.testing.assert_array_equal(s.log_w, 0.0)


def test_deterministic_branching_without_pruning_is_the_exact_mode_mixture():
    """Keeping every mode history, the filter equals the enumerated bank of 2^k EKFs."""
    model = SwitchingRange()
    B, steps = 2, 3
    m0, P0 = _prior(B)
    zs = _zs(model, steps, B)
    state = dg.initial_state(m0, P0, np.zeros((B, 1), int))
    N = 2**steps
    # pad to N slots of zero weight, so no hypothesis is ever dropped
    state = dg.DiracGaussState(
        np.repeat(state.m, N, axis=1),
        np.repeat(state.P, N, axis=1),
        np.zeros((B, N), int),
        np.r_[0.0, np.full(N - 1, -np.inf)][None].repeat(B, axis=0),
    )
    for k, z in enumerate(zs):  # alpha near 1: only identical children count as overlapping
        state, _ = dg.deterministic_step(state, z, model, k, alpha=1 - 1e-12, candidates=4)
    # reference: every mode sequence, its prior probability times the EKF likelihoods
    logw, means = [], []
    for seq in itertools.product([0, 1], repeat=steps):
        m, P, lw, prev = m0, P0, np.zeros(B), 0
        for mode, z in zip(seq, zs, strict=True):
            lw = lw + np.log(model.p if mode != prev else 1 - model.p)
            post, info = _ekf_step(model, mode, m, P, z)
            m, P, lw, prev = post.m, post.P, lw + info.log_likelihood, mode
        logw.append(lw)
        means.append(m)
    logw, means = np.array(logw), np.array(means)  # (2^k, B), (2^k, B, n)
    w = np.exp(logw - logw.max(axis=0))
    w /= w.sum(axis=0)
    ref_mean = np.einsum("sb,sbi->bi", w, means)
    np.testing.assert_allclose(dg.mixture_moments(state).m, ref_mean, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(np.sort(np.exp(state.log_w), axis=1), np.sort(w.T, axis=1), atol=1e-12)


def test_local_selection_drops_duplicates_of_the_same_mode_only():
    model = SwitchingRange(single_mode=True)
    m0, P0 = _prior(B=1)
    z = _zs(model, 1, 1)[0]
    same = dg.initial_state(m0, P0, np.zeros((1, 4), int))
    _, info = dg.deterministic_step(same, z, model, 0)
    assert info.survivors.tolist() == [1]  # four identical children: one survives
    two = dg.initial_state(m0, P0, np.array([[0, 0, 1, 1]]))
    _, info = dg.deterministic_step(two, z, model, 0)
    assert info.survivors.tolist() == [2]  # one per mode


def test_jump_grid_children_carry_their_offsets_and_prior_weights():
    jumps = [[0, 0, 0, 0], [0, 0, 5.0, 0], [0, 0, -5.0, 0]]
    model = SwitchingRange(single_mode=True, jumps=jumps)
    m0, P0 = _prior(B=1)
    z = model.h((m0 @ model.F.T), np.zeros(1, int), None)  # consistent with "no jump"
    state = dg.initial_state(m0, P0, np.zeros((1, 1), int))
    out, _ = dg.deterministic_step(state, z, model, 0, alpha=0.999)
    assert out.m.shape == (1, 1, 4)  # N stays 1: the best child is kept
    # with the prior covariance small against 5 m/s, "no jump" must win
    ref, _ = _ekf_step(model, 0, m0, P0, z)
    np.testing.assert_allclose(out.m[:, 0], ref.m, rtol=1e-12)


def test_random_filter_resamples_below_its_threshold_only():
    model = SwitchingRange()
    m0, P0 = _prior(B=2)
    zs = _zs(model, 6, 2)
    rngs = [np.random.default_rng(i) for i in range(2)]
    state = dg.initial_state(m0, P0, np.zeros((2, 200), int))
    never = state
    for k, z in enumerate(zs):
        state, info = dg.random_step(state, z, model, k, rngs, ess_threshold=0.5)
        assert (info.ess >= 0).all() and info.ess.shape == (2,)
        never, ninfo = dg.random_step(never, z, model, k, rngs, ess_threshold=0.0)
        assert not ninfo.resampled.any()
    probs = dg.mode_probabilities(state, 2)
    np.testing.assert_allclose(probs.sum(axis=1), 1.0)


@pytest.mark.parametrize(
    "kwargs, match",
    [({"alpha": 0.0}, "alpha"), ({"alpha": 1.0}, "alpha"), ({"candidates": 0}, "candidates")],
)
def test_deterministic_step_rejects_bad_knobs(kwargs, match):
    model = SwitchingRange()
    m0, P0 = _prior(B=1)
    state = dg.initial_state(m0, P0, np.zeros((1, 2), int))
    with pytest.raises(ValueError, match=match):
        dg.deterministic_step(state, np.zeros((1, 2)), model, 0, **kwargs)


def test_bad_shapes_and_thresholds_are_rejected():
    model = SwitchingRange()
    m0, P0 = _prior(B=2)
    with pytest.raises(ValueError, match="modes"):
        dg.initial_state(m0, P0, np.zeros(2, int))
    state = dg.initial_state(m0, P0, np.zeros((2, 3), int))
    with pytest.raises(ValueError, match="z must have"):
        dg.random_step(state, np.zeros((3, 2)), model, 0, [np.random.default_rng(0)] * 2)
    with pytest.raises(ValueError, match="ess_threshold"):
        dg.random_step(state, np.zeros((2, 2)), model, 0, [np.random.default_rng(0)] * 2, ess_threshold=2.0)


def test_a_step_whose_every_hypothesis_fails_is_flagged_unhealthy():
    model = SwitchingRange(single_mode=True)
    m0, P0 = _prior(B=2)
    P0[0] = -100.0 * P0[0]  # finite but negative definite: filter 0's every EKF update fails
    state = dg.initial_state(m0, P0, np.zeros((2, 3), int))
    state = state._replace(m=state.m + np.array([0.0, 1.0, 2.0])[None, :, None])  # unequal likelihoods
    z = _zs(model, 1, 2)[0]
    with np.errstate(invalid="ignore", over="ignore"):
        _, dinfo = dg.deterministic_step(state, z, model, 0)
        rngs = [np.random.default_rng(i) for i in range(2)]
        _, rinfo = dg.random_step(state, z, model, 0, rngs, ess_threshold=1.0)  # resample the other
    assert dinfo.healthy.tolist() == [False, True] and rinfo.healthy.tolist() == [False, True]
    assert dinfo.ess[0] == 0.0 and dinfo.ess[1] >= 1.0
    assert rinfo.resampled.tolist() == [False, True]
