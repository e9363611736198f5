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
    """Samples of a spline give back that spline (the banded least squares with no noise:
    positions to rounding, rotations to the correction's tolerance of 1e-5 rad)."""
    spline = _random_spline()
    t = np.linspace(0.0, spline.t_end - 1e-9, 900)
    R, p = spline.poses_at(t)
    fitted = fit_spline(t, R, p, spline.dt, spline.order)
    R_fit, p_fit = fitted.poses_at(t)
    np.testing.assert_allclose(p_fit, p, atol=1e-9)
    turn = Rotation.from_matrix(np.swapaxes(R_fit, -1, -2) @ R).magnitude()
    assert turn.max() < 1e-4


def test_the_fit_averages_the_mocaps_rotation_noise() -> None:
    """White rotation noise of 0.05 deg on samples at ten a knot interval: the fitted spline
    is a least-squares fit, its error between the samples well below one sample's (a spline
    held through single samples carried their whole noise into its rates)."""
    spline = _random_spline()
    t = np.linspace(0.0, spline.t_end - 1e-9, 10 * (spline.R.shape[0] - spline.order + 1))
    R, p = spline.poses_at(t)
    rng = np.random.default_rng(3)
    sigma = np.radians(0.05)
    noisy = R @ Rotation.from_rotvec(rng.normal(0.0, sigma, (t.size, 3))).as_matrix()
    fitted = fit_spline(t, noisy, p, spline.dt, spline.order)
    dense = np.linspace(t[20], t[-20], 5000)
    R_fit, _ = fitted.poses_at(dense)
    R_true, _ = spline.poses_at(dense)
    err = Rotation.from_matrix(np.swapaxes(R_true, -1, -2) @ R_fit).as_rotvec()
    # ten samples to a segment, four segments to a control pose: about a third of the noise
    assert np.sqrt(np.mean(err**2)) < 0.5 * sigma


def test_the_default_knot_spacing_is_the_one_its_rule_picks() -> None:
    """KNOT_SPACING_S's rule (core/config.py): within 10 % of 0.05 s, in steps of 0.1 ms, the
    spacing whose eye stamps leave the smallest phase gap on the knot interval, relative to an
    even spread, in 60 and in 600 frames, at the worst of 13 common frame rates."""
    from handeye_ros.core.config import KNOT_SPACING_S

    rates = (10, 15, 20, 25, 30, 40, 50, 60, 90, 100, 120, 200, 400)

    def worst(h: float) -> float:
        out = 0.0
        for rate in rates:
            for n in (60, 600):
                phase = np.sort(np.mod(np.arange(n) / (rate * h), 1.0))
                gap = np.diff(np.concatenate([phase, [phase[0] + 1.0]])).max()
                out = max(out, gap * n)
        return out

    candidates = np.round(np.arange(0.0450, 0.05501, 0.0001), 4)
    scores = [worst(h) for h in candidates]
    assert candidates[int(np.argmin(scores))] == KNOT_SPACING_S
    assert min(scores) < 2.9 < worst(0.05)
