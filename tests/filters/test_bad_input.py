"""Bad input raises ValueError naming the argument; nothing returns NaN silently."""

import numpy as np
import pytest

from filters import FILTERS, GaussHermite, GaussianState, Unscented, information, kalman, sigma_point

from .problems import RandomNonlinear, random_linear


@pytest.fixture
def setup():
    p = RandomNonlinear.draw(3, 2, 0)
    m0, P0, zs = p.simulate(4, 1, 0)
    return p, GaussianState(m0, P0), zs[0]


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_wrong_state_shapes(name, setup):
    p, s, z = setup
    flt = FILTERS[name]
    with pytest.raises(ValueError, match=r"state\.P"):
        flt.predict(GaussianState(s.m, s.P[:, :2, :2]), p)
    with pytest.raises(ValueError, match=r"state\.m"):
        flt.predict(GaussianState(s.m[0], s.P), p)
    with pytest.raises(ValueError, match=r"state\.P"):
        flt.update(GaussianState(s.m, s.P[:3]), z, p)  # batch mismatch


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_non_finite_covariance_and_measurement(name, setup):
    p, s, z = setup
    flt = FILTERS[name]
    P = s.P.copy()
    P[1, 0, 0] = np.nan
    with pytest.raises(ValueError, match=r"state\.P.*non-finite"):
        flt.predict(GaussianState(s.m, P), p)
    bad = z.copy()
    bad[2, 1] = np.inf
    with pytest.raises(ValueError, match=r"^z has non-finite"):
        flt.update(s, bad, p)
    with pytest.raises(ValueError, match=r"^z must have shape"):
        flt.update(s, z[:2], p)
    with pytest.raises(ValueError, match=r"^mask must have shape"):
        flt.update(s, z, p, mask=np.ones((4, 3), bool))


def test_bad_noise_and_knobs(setup):
    p, s, z = setup
    with pytest.raises(ValueError, match=r"^Q must have shape"):
        kalman.predict(s, p, Q=np.eye(2))
    with pytest.raises(ValueError, match=r"^R has non-finite"):
        kalman.update(s, z, p, R=np.full((2, 2), np.nan))
    with pytest.raises(ValueError, match=r"^fading"):
        kalman.predict(s, p, fading=np.array([1.0, 2.0]))
    with pytest.raises(ValueError, match=r"^fading"):
        sigma_point.predict(s, p, fading=-1.0)
    with pytest.raises(ValueError, match=r"^max_iter"):
        kalman.iterated_update(s, z, p, max_iter=0)
    with pytest.raises(ValueError, match=r"^alpha"):
        Unscented(alpha=0.0)
    with pytest.raises(ValueError, match=r"^p must"):
        GaussHermite(0)
    with pytest.raises(ValueError, match="filter must be one of"):
        __import__("filters").get("nope")


def test_information_state_checks(setup):
    p, s, z = setup
    i = information.to_information(s)
    with pytest.raises(ValueError, match=r"state\.Y"):
        information.eif_update(type(i)(i.y, i.Y[:, :2]), z, p)


def test_non_positive_definite_innovation_covariance_is_flagged_not_nan():
    """A negative R makes S indefinite: the filter flags it instead of returning NaN."""
    model = random_linear(3, 2, 1)
    model = model._replace(R=-10.0 * np.eye(2))
    s = GaussianState(np.zeros((2, 3)), np.eye(3)[None].repeat(2, 0) * 1e-3)
    post, info = kalman.update(s, np.ones((2, 2)), model)
    assert not info.healthy.any()
    assert np.isfinite(post.m).all() and np.isfinite(info.log_likelihood).all()
