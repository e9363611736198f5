"""The world alignment T_WG (core/world.py): Umeyama's fit of the positions where they span a
room, the orientations' where they span a few centimetres, and continuous between."""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial.transform import Rotation

from handeye_ros.core.association import PosePairs
from handeye_ros.core.geometry import compose, matrix_from_quat, rotation_angle
from handeye_ros.core.world import MIN_PLANAR_SPREAD_M, align_worlds, metrics_of, rigid_fit

#: A turntable: the marker on the axis (z of G), turned through two laps.
N = 2000
ANGLES = np.linspace(0.0, 4.0 * np.pi, N)
R_GH = Rotation.from_rotvec(ANGLES[:, None] * [0.0, 0.0, 1.0]).as_matrix()
W = (Rotation.from_rotvec([0.3, -0.2, 1.1]).as_matrix(), np.array([0.5, -1.0, 0.2]))
Q_HE = Rotation.from_rotvec([0.1, 0.2, -0.3]).as_quat()


def _pairs(lever_m: float, drift_m: float, noise_deg: float, seed: int = 0) -> PosePairs:
    """The turntable's eye ``lever_m`` from the axis, its VIO positions drifting by up to
    ``drift_m`` (a random walk) and its orientations with white noise of ``noise_deg``."""
    rng = np.random.default_rng(seed)
    X = (matrix_from_quat(Q_HE), np.array([lever_m, 0.0, 0.0]))
    R_WE, p_WE = compose(compose(W, (R_GH, np.zeros((N, 3)))), X)
    walk = np.cumsum(rng.normal(size=(N, 3)), axis=0)
    p_WE = p_WE + drift_m * walk / np.abs(walk).max()
    noise = Rotation.from_rotvec(rng.normal(0.0, np.radians(noise_deg), (N, 3))).as_matrix()
    R_WE = R_WE @ noise
    return PosePairs(np.arange(N) * 0.01, R_GH, np.zeros((N, 3)), R_WE, p_WE, np.zeros(N, int))


def _angle_deg(R_a: np.ndarray, R_b: np.ndarray) -> float:
    return float(np.degrees(rotation_angle((R_a.T @ R_b)[None])[0]))


def test_a_room_is_aligned_by_its_positions_alone_as_umeyama_does() -> None:
    rng = np.random.default_rng(1)
    p_GH = rng.uniform(-1.0, 1.0, (N, 3))
    R_WE, p_WE = compose(W, (R_GH, p_GH))
    R_WE = R_WE @ Rotation.from_rotvec(rng.normal(0.0, 0.05, (N, 3))).as_matrix()
    pairs = PosePairs(np.arange(N) * 0.01, R_GH, p_GH, R_WE, p_WE + 0.01, np.zeros(N, int))
    world = align_worlds(pairs, np.r_[0.0, 0.0, 0.0, 1.0], np.zeros(3))
    R, p = rigid_fit(p_GH, p_WE + 0.01)
    assert world.method == 'positions'
    np.testing.assert_array_equal(world.R_WG, R)
    np.testing.assert_array_equal(world.p_WG, p)


def test_a_turntables_small_circle_beside_the_vio_drift_is_aligned_by_its_orientations() -> None:
    """A 4-cm circle beside 3 cm of position drift: the positions alone tilt T_WG by 3.5 deg
    here; the orientations (0.1 deg of noise per axis, 2000 poses) fix it within a tenth of a
    degree, and the ARE is their noise's (0.17 deg RMS)."""
    pairs = _pairs(0.04, 0.03, 0.1)
    world = align_worlds(pairs, Q_HE, np.array([0.04, 0.0, 0.0]))
    assert world.method == 'orientations'
    assert _angle_deg(world.R_WG, W[0]) < 0.1
    m = metrics_of(pairs, Q_HE, np.array([0.04, 0.0, 0.0]), world)
    assert m.are_rmse_deg < 0.2


def test_t_wg_moves_continuously_as_the_lever_arm_crosses_the_orientations_arm() -> None:
    """The lever arm's circle spans from below MIN_PLANAR_SPREAD_M to beyond twice it: between
    lever arms 0.7 mm apart T_WG's rotation moves by 0.02 deg at most (a switch between the two
    fits would jump by the positions' tilt, 1-3.5 deg here)."""
    # the circle's second principal spread is its radius / sqrt(2)
    levers = np.sqrt(2.0) * MIN_PLANAR_SPREAD_M * np.linspace(0.9, 2.1, 121)
    fits = []
    for lever in levers:
        pairs = _pairs(float(lever), 0.03, 0.1)
        fits.append(align_worlds(pairs, Q_HE, np.array([lever, 0.0, 0.0])).R_WG)
    steps = [_angle_deg(a, b) for a, b in itertools.pairwise(fits)]
    assert max(steps) < 0.05
    assert _angle_deg(fits[0], W[0]) < 0.1
