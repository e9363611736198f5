"""The hand's B-spline (core/batch/spline.py, eq. 14): its basis, its rates and its fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from handeye_ros.core.batch.spline import (
    PoseSpline,
    cumulative_basis,
    cumulative_basis_derivative,
    exp_so3,
    fit_spline,
    plain_basis,
)


@pytest.mark.parametrize('order', [2, 3, 4, 5])
def test_basis_is_a_partition_of_unity_and_its_derivative_is_exact(order: int) -> None:
    s = np.linspace(0.0, 0.999, 37)
    Bc = cumulative_basis(s, order)
    np.testing.assert_allclose(plain_basis(Bc).sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(Bc[:, 0], 1.0)
    h = 1e-6
    fd = (cumulative_basis(s + h, order) - cumulative_basis(s - h, order)) / (2 * h)
    np.testing.assert_allclose(cumulative_basis_derivative(s[1:-1], order), fd[1:-1], atol=1e-7)


def test_exp_matches_scipy_at_small_and_large_angles() -> None:
    rng = np.random.default_rng(0)
    v = rng.normal(size=(200, 3)) * np.repeat([1e-9, 1e-5, 1e-2, 1.0, 3.0], 40)[:, None]
    np.testing.assert_allclose(exp_so3(v), Rotation.from_rotvec(v).as_matrix(), atol=1e-14)


def _random_spline(order: int = 4, M: int = 12) -> PoseSpline:
    rng = np.random.default_rng(1)
    R = Rotation.from_rotvec(np.cumsum(rng.normal(scale=0.3, size=(M, 3)), axis=0)).as_matrix()
    return PoseSpline(0.0, 0.1, order, R, np.cumsum(rng.normal(scale=0.05, size=(M, 3)), 0))


def test_velocity_is_the_derivative_of_the_pose() -> None:
    spline = _random_spline()
    t = np.linspace(0.01, spline.t_end - 0.01, 50)
    R, p, w, v = spline.poses_and_rates_at(spline.basis(t), spline.basis_derivative(t))
    np.testing.assert_allclose(p, spline.poses_at(t)[1], atol=1e-14)
    h = 1e-6
    Rp, pp = spline.poses_at(t + h)
    Rm, pm = spline.poses_at(t - h)
    np.testing.assert_allclose(v, (pp - pm) / (2 * h), atol=1e-7)
    # body rate: R^T dR/dt = [w]x
    dR = np.matmul(np.swapaxes(R, -1, -2), (Rp - Rm) / (2 * h))
    w_fd = np.stack((dR[:, 2, 1], dR[:, 0, 2], dR[:, 1, 0]), axis=1)
    np.testing.assert_allclose(w, w_fd, atol=1e-6)
    np.testing.assert_allclose(R, spline.poses_at(t)[0], atol=1e-14)


def test_fit_passes_through_a_spline_it_can_represent() -> None:
    """Samples of a spline give back that spline's positions (the banded least squares with no
    noise; the rotations are fitted by interpolation at the control centres, not here)."""
    spline = _random_spline()
    t = np.linspace(0.0, spline.t_end - 1e-9, 900)
    R, p = spline.poses_at(t)
    fitted = fit_spline(t, R, p, spline.dt, spline.order)
    np.testing.assert_allclose(fitted.poses_at(t)[1], p, atol=1e-9)
