"""The long-run covariance of :mod:`handeye_ros.core.batch.long_run`, piece by piece.

Tolerances are Monte Carlo ones: with T = 20 000 samples the sample variance of a mean has a
relative standard error of ~1 % for white noise and ~5-10 % for AR(1) with rho = 0.8 at the
chosen bandwidths, so the tests allow 10-25 %.
"""

from __future__ import annotations

import numpy as np
import pytest

from handeye_ros.core.batch.long_run import (
    andrews_bandwidth,
    huber_psi,
    influence,
    influence_two_step,
    long_run_covariance,
)


def _ar1(rng: np.random.Generator, T: int, rho: float, p: int = 1) -> np.ndarray:
    e = rng.normal(size=(T, p))
    x = np.empty_like(e)
    x[0] = e[0] / np.sqrt(1 - rho**2)
    for t in range(1, T):
        x[t] = rho * x[t - 1] + e[t]
    return x


def test_white_noise_has_a_small_bandwidth_and_the_plain_variance() -> None:
    x = np.random.default_rng(0).normal(size=(20_000, 2))
    lr = long_run_covariance(x)
    assert lr.bandwidth <= 3
    np.testing.assert_allclose(np.diag(lr.covariance), [20_000, 20_000], rtol=0.1)
    np.testing.assert_allclose(lr.inflation, 1.0, atol=0.1)


@pytest.mark.parametrize('rho', [0.5, 0.8])
def test_ar1_long_run_variance_matches_theory(rho: float) -> None:
    """Var(sum x) / T -> sigma_e^2 / (1 - rho)^2 for an AR(1) with unit innovations."""
    x = _ar1(np.random.default_rng(1), 20_000, rho)
    lr = long_run_covariance(x)
    assert lr.bandwidth > 5
    theory = 20_000 / (1.0 - rho) ** 2
    assert lr.covariance[0, 0] == pytest.approx(theory, rel=0.25)
    assert lr.inflation[0] == pytest.approx(np.sqrt((1 + rho) / (1 - rho)), rel=0.2)


def test_bandwidth_grows_with_persistence() -> None:
    rng = np.random.default_rng(2)
    assert andrews_bandwidth(_ar1(rng, 5000, 0.3)) < andrews_bandwidth(_ar1(rng, 5000, 0.9))
    assert andrews_bandwidth(np.zeros((5, 2))) == 0


def test_influence_of_least_squares_is_the_textbook_covariance() -> None:
    """Ordinary least squares on white Gaussian noise (Huber never active): the sandwich of
    the influences equals s^2 (J^T J)^-1 to sampling error."""
    rng = np.random.default_rng(3)
    T = 5000
    J = rng.normal(size=(T * 3, 2))
    r = rng.normal(scale=0.5, size=T * 3)
    psi, H_inv = influence(r, J, delta=1e9, rows_per_sample=3)
    lr = long_run_covariance(psi, bandwidth=0)
    np.testing.assert_allclose(
        lr.covariance, 0.25 * H_inv, rtol=0.1, atol=0.1 * 0.25 * float(np.max(np.diag(H_inv)))
    )


def test_huber_psi_clips() -> None:
    psi, dpsi = huber_psi(np.array([-3.0, -0.5, 0.0, 2.0]), 1.0)
    np.testing.assert_array_equal(psi, [-1.0, -0.5, 0.0, 1.0])
    np.testing.assert_array_equal(dpsi, [0.0, 1.0, 1.0, 0.0])


def test_two_step_influence_carries_the_first_step() -> None:
    """y = a + b x: a from step A (rows z = a), b from step B with a fixed. The influence of b
    moves by -(x.x)^-1 x.1 times a's own, as the sensitivity S says."""
    rng = np.random.default_rng(4)
    T = 4000
    x = rng.normal(1.0, 1.0, T)
    J_a = np.ones((T, 1))
    r_a = rng.normal(size=T)
    J_b = x[:, None]
    J_theta = np.ones((T, 1))
    r_b = rng.normal(size=T)
    psi_a, psi_b = influence_two_step(r_a, J_a, r_b, J_b, J_theta, 1e9, 1, 1, np.array([0]))
    direct = -(x * r_b)[:, None] / (x @ x)
    S = -(x @ np.ones(T)) / (x @ x)
    np.testing.assert_allclose(psi_b, direct + psi_a * S, rtol=1e-9)
