"""Bad input raises ValueError naming the argument (docs/architecture.md, "filters")."""

import numpy as np
import pytest

from filters import ParticleState
from filters.particle import bootstrap, exploration
from filters.particle import regularization as reg

from .problems import cv_model

B, N = 3, 8
RNG = np.random.default_rng(0)
MODEL = cv_model()


def _state(**kw):
    st = ParticleState(np.zeros((B, N, 2)), np.full((B, N), -np.log(N)))
    return st._replace(**kw)


Z = np.zeros((B, 1))
CASES = {
    "log_w NaN": (lambda: bootstrap.update(_state(log_w=np.full((B, N), np.nan)), Z, MODEL), "log_w"),
    "log_w +inf": (lambda: bootstrap.resample(_state(log_w=np.full((B, N), np.inf)), True, RNG), "log_w"),
    "log_w all -inf": (lambda: bootstrap.update(_state(log_w=np.full((B, N), -np.inf)), Z, MODEL), "log_w"),
    "log_w shape": (lambda: bootstrap.predict(_state(log_w=np.zeros((B, N + 1))), MODEL, rng=RNG), "log_w"),
    "x ndim": (lambda: bootstrap.predict(_state(x=np.zeros((B, N))), MODEL, rng=RNG), "state.x"),
    "N = 0": (
        lambda: bootstrap.update(_state(x=np.zeros((B, 0, 2)), log_w=np.zeros((B, 0))), Z, MODEL),
        "N >= 1",
    ),
    "from_gaussian N": (lambda: bootstrap.from_gaussian(np.zeros((B, 2)), np.eye(2), 0, RNG), "N"),
    "from_gaussian P": (lambda: bootstrap.from_gaussian(np.zeros((B, 2)), np.eye(3), 5, RNG), "P"),
    "z shape": (lambda: bootstrap.update(_state(), np.zeros((B + 1, 1)), MODEL), "z"),
    "z NaN unmasked": (lambda: bootstrap.update(_state(), np.full((B, 1), np.nan), MODEL), "z"),
    "mask shape": (lambda: bootstrap.update(_state(), Z, MODEL, mask=np.ones((B, 2), bool)), "mask"),
    "R shape": (lambda: bootstrap.update(_state(), Z, MODEL, R=np.eye(2)), "R"),
    "R not PD": (lambda: bootstrap.update(_state(), Z, MODEL, R=np.zeros((1, 1))), "R"),
    "Q shape": (lambda: bootstrap.predict(_state(), MODEL, rng=RNG, Q=np.eye(3)), "Q"),
    "forgetting 0": (lambda: bootstrap.update(_state(), Z, MODEL, forgetting=0.0), "forgetting"),
    "forgetting > 1": (
        lambda: bootstrap.update(_state(), Z, MODEL, forgetting=np.array([1, 1.2, 1])),
        "forgetting",
    ),
    "forgetting shape": (
        lambda: bootstrap.update(_state(), Z, MODEL, forgetting=np.ones(B + 1)),
        "forgetting",
    ),
    "decision shape": (lambda: bootstrap.resample(_state(), np.ones(B + 1, bool), RNG), "decision"),
    "decision without rng": (lambda: bootstrap.update(_state(), Z, MODEL, decision=True), "rng"),
    "method": (lambda: bootstrap.resample(_state(), True, RNG, "magic"), "method"),
    "rng missing": (lambda: bootstrap.predict(_state(), MODEL), "rng"),
    "rng type": (lambda: bootstrap.predict(_state(), MODEL, rng=42), "rng"),
    "rng count": (lambda: bootstrap.predict(_state(), MODEL, rng=[RNG] * (B - 1)), "rng"),
    "gamma": (lambda: reg.age_weight(np.zeros((B, N)), np.zeros((B, N)), 1.5), "gamma"),
    "log_lik shape": (lambda: reg.age_weight(np.zeros((B, N)), np.zeros((B, N + 1)), 0.9), "log_lik"),
    "window T": (lambda: reg.window_init(B, N, 0), "T"),
    "window shape": (lambda: reg.window_update(_state(), reg.window_init(B, N + 1, 3), Z, MODEL), "window"),
    "roughen K": (lambda: reg.roughen(_state(), RNG, K=-1.0), "K"),
    "bandwidth_scale": (lambda: reg.kernel_jitter(_state(), RNG, bandwidth_scale=np.nan), "bandwidth_scale"),
    "kernel cov": (lambda: reg.kernel_jitter(_state(), RNG, cov=np.eye(2)), "cov"),
    "explore M": (lambda: exploration.explore(_state(), MODEL, Z, RNG, 0), "M"),
    "explore z": (lambda: exploration.explore(_state(), MODEL, np.zeros(3), RNG, 2), "z"),
    "explore mask count": (
        lambda: exploration.explore(_state(), MODEL, np.zeros((2, B, 1)), RNG, 2, mask=[None] * 3),
        "mask",
    ),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_bad_input_raises_value_error_naming_the_argument(name):
    call, match = CASES[name]
    with pytest.raises(ValueError, match=match):
        call()


def test_model_output_shape_errors_name_the_model_function():
    class Bad:
        Q = np.eye(2)
        R = np.eye(1)

        def f(self, x, u, dt):
            return x[..., :1]

        def h(self, x):
            return x

    with pytest.raises(ValueError, match="model.f"):
        bootstrap.predict(_state(), Bad(), rng=RNG)
    with pytest.raises(ValueError, match="model.h"):
        bootstrap.update(_state(), Z, Bad())
