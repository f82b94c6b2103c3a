"""Masked rows contribute exactly nothing; B filters together equal B separate runs."""

import numpy as np
import pytest

from filters import FILTERS, GaussianState, information

from .problems import RandomNonlinear
from .tolerances import MASK_ATOL, MASK_RTOL


class Rows:
    """The observation model restricted to some rows (the 'deleted rows' reference)."""

    def __init__(self, p, rows):
        self.p, self.rows = p, np.asarray(rows)
        self.R = p.R[np.ix_(self.rows, self.rows)]

    def h(self, x):
        return self.p.h(x)[..., self.rows]

    def H(self, x):
        return self.p.H(x)[..., self.rows, :]


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_masked_row_equals_deleted_row(name):
    p = RandomNonlinear.draw(4, 4, 11)
    m0, P0, zs = p.simulate(1, 3, 11)
    flt = FILTERS[name]
    prior = flt.predict(GaussianState(m0, P0), p)
    keep = [0, 2, 3]
    z = zs[0].copy()
    z[:, 1] = np.nan  # anything may sit in a masked row
    mask = np.array([[True, False, True, True]])
    got, info = flt.update(prior, z, p, mask=mask)
    ref, ref_info = flt.update(prior, zs[0][:, keep], Rows(p, keep))
    np.testing.assert_allclose(got.m, ref.m, rtol=MASK_RTOL, atol=MASK_ATOL)
    np.testing.assert_allclose(got.P, ref.P, rtol=MASK_RTOL, atol=MASK_ATOL)
    np.testing.assert_allclose(info.nis, ref_info.nis, rtol=MASK_RTOL, atol=MASK_ATOL)
    np.testing.assert_allclose(info.log_likelihood, ref_info.log_likelihood, rtol=MASK_RTOL, atol=MASK_ATOL)
    assert info.innovation[0, 1] == 0.0 and info.n_meas[0] == 3
    assert np.isfinite(info.innovation).all() and info.healthy.all()


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_fully_masked_update_is_identity(name):
    p = RandomNonlinear.draw(3, 2, 5)
    m0, P0, zs = p.simulate(2, 1, 5)
    prior = GaussianState(m0, P0)
    post, info = FILTERS[name].update(prior, np.full((2, 2), np.nan), p, mask=np.zeros((2, 2), bool))
    np.testing.assert_allclose(post.m, prior.m, rtol=0, atol=1e-15)
    np.testing.assert_allclose(post.P, prior.P, rtol=0, atol=1e-15)
    assert (info.log_likelihood == 0).all() and (info.nis == 0).all()


@pytest.mark.parametrize("kind", ["eif", "cif"])
def test_information_filters_mask_rows(kind):
    p = RandomNonlinear.draw(4, 4, 12)
    m0, P0, zs = p.simulate(1, 1, 12)
    state = information.to_information(GaussianState(m0, P0))
    upd = information.eif_update if kind == "eif" else information.cif_update
    keep = [0, 1, 3]
    got, _ = upd(state, zs[0], p, mask=np.array([[True, True, False, True]]))
    ref, _ = upd(state, zs[0][:, keep], Rows(p, keep))
    np.testing.assert_allclose(got.Y, ref.Y, rtol=MASK_RTOL, atol=MASK_ATOL)
    np.testing.assert_allclose(got.y, ref.y, rtol=MASK_RTOL, atol=MASK_ATOL)


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_batch_equals_separate_runs(name):
    p = RandomNonlinear.draw(4, 3, 21)
    B = 5
    m0, P0, zs = p.simulate(B, 10, 21)
    rng = np.random.default_rng(0)
    masks = rng.random(zs.shape) > 0.3
    flt = FILTERS[name]
    batch = GaussianState(m0, P0)
    singles = [GaussianState(m0[b : b + 1], P0[b : b + 1]) for b in range(B)]
    for z, mask in zip(zs, masks, strict=True):
        batch, info = flt.update(flt.predict(batch, p), z, p, mask=mask)
        for b in range(B):
            singles[b], info_b = flt.update(flt.predict(singles[b], p), z[b : b + 1], p, mask=mask[b : b + 1])
            np.testing.assert_allclose(batch.m[b], singles[b].m[0], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(batch.P[b], singles[b].P[0], rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(info.nis[b], info_b.nis[0], rtol=1e-12, atol=1e-12)
