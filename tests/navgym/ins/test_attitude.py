import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from navgym.ins import (
    dcm_to_euler,
    euler_to_dcm,
    orthonormalize,
    rotation_matrix,
    rotation_vector,
    skew,
)
from navgym.ins.attitude import cross, cross_components, rotation_matrix_components

from .tolerances import EXACT_ATOL


@pytest.mark.parametrize("scale", [0.0, 1e-12, 1e-6, 1e-3, 0.5, 3.0])
def test_rotation_matrix_matches_scipy(scale):
    phi = np.random.default_rng(0).standard_normal((50, 3)) * scale
    ref = Rotation.from_rotvec(phi).as_matrix()
    np.testing.assert_allclose(rotation_matrix(phi), ref, atol=EXACT_ATOL)


@pytest.mark.parametrize("scale", [1e-12, 0.5, 3.0])
def test_rotation_matrix_forms_agree_with_scipy(scale):
    """The last-axis and the component-first Rodrigues agree with each other and with SciPy."""
    phi = np.random.default_rng(5).standard_normal((40, 3)) * scale
    ref = Rotation.from_rotvec(phi).as_matrix()
    last = rotation_matrix(phi)
    comp = np.moveaxis(rotation_matrix_components(np.ascontiguousarray(phi.T)), (0, 1), (-2, -1))
    np.testing.assert_allclose(last, ref, atol=EXACT_ATOL)
    np.testing.assert_allclose(comp, ref, atol=EXACT_ATOL)
    np.testing.assert_allclose(comp, last, atol=EXACT_ATOL)
    # Component-first over two trailing axes, as the quadrotor preintegration uses it.
    comp2 = rotation_matrix_components(phi.T.reshape(3, 8, 5))
    np.testing.assert_allclose(np.moveaxis(comp2, (0, 1), (-2, -1)).reshape(40, 3, 3), ref, atol=EXACT_ATOL)


def test_cross_products_match_numpy():
    rng = np.random.default_rng(6)
    a, b = rng.standard_normal((2, 30, 3))
    ref = np.cross(a, b)
    np.testing.assert_allclose(cross(a, b), ref, atol=EXACT_ATOL)
    np.testing.assert_allclose(cross_components(a.T, b.T).T, ref, atol=EXACT_ATOL)
    # Broadcast vector against matrix columns: [a x] M, as the quadrotor model uses it.
    M = rng.standard_normal((30, 3, 4))
    ref_m = np.cross(a[:, :, None], M, axis=1)
    got_m = cross_components(a.T[:, None], M.transpose(1, 2, 0)).transpose(2, 0, 1)
    np.testing.assert_allclose(got_m, ref_m, atol=EXACT_ATOL)


def test_rotation_vector_inverts_rotation_matrix():
    phi = np.random.default_rng(1).standard_normal((100, 3))
    phi *= (np.linspace(1e-9, 3.0, 100) / np.linalg.norm(phi, axis=1))[:, None]
    np.testing.assert_allclose(rotation_vector(rotation_matrix(phi)), phi, atol=1e-10)


def test_skew_is_cross_product():
    rng = np.random.default_rng(2)
    w, x = rng.standard_normal((2, 10, 3))
    np.testing.assert_allclose(skew(w) @ x[..., None], np.cross(w, x)[..., None], atol=EXACT_ATOL)


def test_euler_roundtrip_and_convention():
    rng = np.random.default_rng(3)
    roll, yaw = rng.uniform(-np.pi, np.pi, (2, 200))
    pitch = rng.uniform(-1.5, 1.5, 200)
    C = euler_to_dcm(roll, pitch, yaw)
    ref = Rotation.from_euler("ZYX", np.stack([yaw, pitch, roll], -1)).as_matrix()
    np.testing.assert_allclose(C, ref, atol=EXACT_ATOL)
    r2, p2, y2 = dcm_to_euler(C)
    np.testing.assert_allclose(np.stack([r2, p2, y2]), np.stack([roll, pitch, yaw]), atol=1e-9)


def test_orthonormalize_restores_orthogonality():
    C = rotation_matrix([0.3, -0.2, 1.0]) + 1e-6 * np.random.default_rng(4).standard_normal((3, 3))
    Co = orthonormalize(C)
    assert np.abs(Co.T @ Co - np.eye(3)).max() < 1e-10
