"""Pose stacks and dual quaternions against scipy's Rotation (an independent implementation)."""

import numpy as np
from scipy.spatial.transform import Rotation

from handeye_ros.core import geometry as g


def _poses(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return Rotation.random(n, random_state=rng).as_matrix(), rng.normal(size=(n, 3))


def test_compose_and_inverse_give_identity() -> None:
    a = _poses(50, 0)
    R, p = g.compose(a, g.inverse(a))
    np.testing.assert_allclose(R, np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(p, 0.0, atol=1e-12)


def test_compose_matches_homogeneous_matrices() -> None:
    a, b = _poses(20, 1), _poses(20, 2)
    R, p = g.compose(a, b)
    for k in range(3):
        Ta, Tb = np.eye(4), np.eye(4)
        Ta[:3, :3], Ta[:3, 3] = a[0][k], a[1][k]
        Tb[:3, :3], Tb[:3, 3] = b[0][k], b[1][k]
        T = Ta @ Tb
        np.testing.assert_allclose(R[k], T[:3, :3], atol=1e-12)
        np.testing.assert_allclose(p[k], T[:3, 3], atol=1e-12)


def test_quaternions_are_hamilton_xyzw() -> None:
    qa = Rotation.random(10, random_state=3)
    qb = Rotation.random(10, random_state=4)
    np.testing.assert_allclose(
        Rotation.from_quat(g.quat_multiply(qa.as_quat(), qb.as_quat())).as_matrix(),
        (qa * qb).as_matrix(),
        atol=1e-12,
    )
    np.testing.assert_allclose(g.matrix_from_quat(qa.as_quat()), qa.as_matrix(), atol=1e-12)


def test_dual_quaternion_round_trip() -> None:
    rng = np.random.default_rng(5)
    q = Rotation.random(30, random_state=rng).as_quat()
    p = rng.normal(size=(30, 3))
    q2, p2 = g.pose_from_dual_quat(*g.dual_quat_from_pose(q, p))
    np.testing.assert_allclose(p2, p, atol=1e-12)
    # same rotation, whatever the sign
    np.testing.assert_allclose(np.abs(np.einsum('ij,ij->i', q, q2)), 1.0, atol=1e-12)


def test_rotation_angle() -> None:
    rv = np.random.default_rng(6).normal(size=(40, 3))
    rv *= (np.linspace(0.0, np.pi - 1e-6, 40) / np.linalg.norm(rv, axis=1))[:, None]
    np.testing.assert_allclose(
        g.rotation_angle(Rotation.from_rotvec(rv).as_matrix()),
        np.linalg.norm(rv, axis=1),
        atol=1e-6,
    )


def test_log_and_exp_so3_match_scipy_at_every_angle() -> None:
    from handeye_ros.core.geometry import exp_so3

    rng = np.random.default_rng(7)
    v = rng.normal(size=(3000, 3)) * np.repeat([1e-9, 0.3, 1.0], 1000)[:, None]
    R = Rotation.from_rotvec(v).as_matrix()
    np.testing.assert_allclose(g.log_so3(R), Rotation.from_matrix(R).as_rotvec(), atol=1e-12)
    np.testing.assert_allclose(exp_so3(v), R, atol=1e-12)


def test_row_norms_are_numpys_norms_to_the_bit() -> None:
    """row_norms replaces np.linalg.norm(axis=-1) on long streams: the same bits, so results
    do not move (C and Fortran order, strided views, magnitudes from 1e-6 to 1e3)."""
    rng = np.random.default_rng(5)
    for k in (2, 3, 4):
        v = rng.standard_normal((20_000, k)) * rng.uniform(1e-6, 1e3, (20_000, 1))
        for view in (v, np.asfortranarray(v), v[::3], v.reshape(100, 200, k)):
            assert np.array_equal(g.row_norms(view), np.linalg.norm(view, axis=-1))
