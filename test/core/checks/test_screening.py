"""Screening: isolated pose outliers removed, steps kept, resets found against the hand.

Tolerances: the injected outliers are decimetres and tens of degrees off, the screening floors
are 1 mm / 0.1 deg, so every injected pose must be found; on clean data a handful of false
positives per thousand poses would still be harmless, but the tests ask for none on the
simulator (its noise is Gaussian, where the 6-sigma rule fires about once in 10^7 poses).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import recording
from scipy.spatial.transform import Rotation

from handeye_ros.core.checks.breaks import find_eye_breaks
from handeye_ros.core.checks.screening import resolution, screen
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import InputError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import calibration_error
from handeye_ros.core.trajectory import Trajectory


def _with(
    traj: Trajectory, idx: np.ndarray, p: np.ndarray | None = None, q: np.ndarray | None = None
) -> Trajectory:
    P, Q = traj.p_xyz.copy(), traj.q_xyzw.copy()
    if p is not None:
        P[idx] = p
    if q is not None:
        Q[idx] = q
    return Trajectory.from_arrays(traj.t_ns, P, Q, traj.name)


def test_clean_streams_lose_nothing() -> None:
    rec = recording(seed=1, level=3.0, hand_noise_m=1e-4, hand_noise_deg=0.005)
    for traj, stream in ((rec.hand, 'hand'), (rec.eye, 'eye')):
        kept, rep = screen(traj, stream)
        assert rep.n_removed == 0 and len(kept) == len(traj)


@pytest.mark.parametrize('count', [1, 2])
def test_placeholder_rows_at_the_start(count: int) -> None:
    """Identity poses written before the first estimate (one or two rows, as published)."""
    rec = recording(seed=2, level=3.0)
    eye = rec.eye
    t = np.concatenate((eye.t_ns[0] - 50_000_000 * np.arange(count, 0, -1), eye.t_ns))
    p = np.concatenate((np.zeros((count, 3)), eye.p_xyz))
    q = np.concatenate((np.tile([0.0, 0.0, 0.0, 1.0], (count, 1)), eye.q_xyzw))
    kept, rep = screen(Trajectory.from_arrays(t, p, q, 'eye'), 'eye')
    np.testing.assert_array_equal(rep.removed_ns, t[:count])
    assert rep.counts['placeholder'] == count and len(kept) == len(eye)


@pytest.mark.parametrize('frac', [0.01, 0.05])
def test_marker_swaps_and_zero_dropouts(frac: float) -> None:
    """Wild MoCap poses (swaps: 30-180 deg, a few cm; dropouts: zeros), runs of two and three
    included, are all found; at most ~1 % good poses go with them (a good pose with a wild
    pose on both sides cannot be told apart)."""
    rec = recording(seed=3)
    rng = np.random.default_rng(0)
    n = len(rec.hand)
    idx = np.sort(rng.choice(np.arange(5, n - 5), int(frac * n), replace=False))
    idx = np.union1d(idx, [100, 101, 200, 201, 202])  # two and three in a row
    rot = Rotation.from_rotvec(rng.normal(size=(idx.size, 3)) * 1.5)
    q = (Rotation.from_quat(rec.hand.q_xyzw[idx]) * rot).as_quat()
    swapped = _with(rec.hand, idx, rec.hand.p_xyz[idx] + rng.normal(0, 0.05, (idx.size, 3)), q)
    _, rep = screen(swapped, 'hand')
    assert set(idx) <= set(np.searchsorted(swapped.t_ns, rep.removed_ns))
    assert rep.n_removed <= idx.size + 0.012 * n
    zeros = _with(rec.hand, idx, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    _, rep = screen(zeros, 'hand')
    assert set(idx) <= set(np.searchsorted(zeros.t_ns, rep.removed_ns))


def test_a_step_is_not_an_outlier() -> None:
    """A reset (the world jumps and stays) keeps every pose: screening removes wild poses, not
    the motion after a jump."""
    rec = recording(seed=4, level=2.0)
    p = rec.eye.p_xyz.copy()
    p[600:] += [1.0, -0.5, 0.2]
    _, rep = screen(Trajectory.from_arrays(rec.eye.t_ns, p, rec.eye.q_xyzw, 'eye'), 'eye')
    assert rep.n_removed == 0


def test_rounded_values_are_not_outliers() -> None:
    """Positions written to the millimetre and quaternions to 4 decimals (some loggers): the
    floors rise above the rounding, nothing is removed."""
    rec = recording(seed=5, hand_rate_hz=200.0)
    q = np.round(rec.hand.q_xyzw, 4)
    hand = Trajectory.from_arrays(
        rec.hand.t_ns,
        np.round(rec.hand.p_xyz, 3),
        q / np.linalg.norm(q, axis=1, keepdims=True),
        'hand',
    )
    assert resolution(hand.p_xyz) == pytest.approx(1e-3)
    _, rep = screen(hand, 'hand')
    assert rep.n_removed == 0


def test_reset_splits_the_eye_and_nothing_spans_it() -> None:
    """A VIO reset: 1 s lost, then a world rotated by 40 deg about z and moved 1.5 m. The break
    is found against the hand, no motion or residual spans it, and the result is as without it
    (tolerances: level 2 errors are ~2 mm / 0.1 deg; the reset removes 1 s of 58)."""
    rec = recording(seed=6, level=2.0)
    t = rec.eye.seconds(int(rec.eye.t_ns[0]))
    keep = (t < 30.0) | (t > 31.0)
    after = t > 31.0
    J = Rotation.from_rotvec([0.0, 0.0, np.deg2rad(40.0)])
    p, q = rec.eye.p_xyz.copy(), rec.eye.q_xyzw.copy()
    p[after] = J.apply(p[after]) + [1.0, 1.0, 0.5]
    q[after] = (J * Rotation.from_quat(q[after])).as_quat()
    eye = Trajectory.from_arrays(rec.eye.t_ns[keep], p[keep], q[keep], 'eye')
    res = calibrate(rec.hand, eye)
    assert res.world.segments == 2
    assert res.screening[1].breaks_ns.size == 1
    assert res.screening[1].breaks_ns[0] == eye.t_ns[np.flatnonzero(t[keep] > 31.0)[0]]
    err = calibration_error(rec.truth, res.time_offset_s, res.q_HE, res.p_HE)
    assert err.time_offset_s < 2e-3 and err.translation_m < 0.01 and err.rotation_deg < 0.3
    assert res.quality.verdict == 'good', res.quality.reasons
    # the other way round: found directly, on the shifted eye
    found = find_eye_breaks(
        rec.hand,
        eye,
        rec.truth.time_offset_s,
        Rotation.from_quat(rec.truth.q_HE).as_matrix(),
        rec.truth.p_HE,
    )
    assert found.breaks_ns.size == 1 and found.outliers_ns.size == 0


def test_a_mocap_holding_its_last_pose_leaves_a_gap() -> None:
    """The MoCap repeats its last pose bit for bit for 3 s while moving (as a driver may while
    it has lost the body): the copies are removed from the hand as a dropout, the MoCap's
    coverage has the gap, no eye pose is blamed, and the result is as without it (level 2
    errors are ~2 mm / 0.1 deg)."""
    rec = recording(seed=6, level=2.0)
    t = rec.hand.seconds(int(rec.hand.t_ns[0]))
    held = np.flatnonzero((t > 30.0) & (t < 33.0))
    hand = _with(rec.hand, held, rec.hand.p_xyz[held[0]], rec.hand.q_xyzw[held[0]])
    res = calibrate(hand, rec.eye)
    assert res.screening[0].n_removed == held.size - 1
    assert res.screening[1].n_removed == 0 and res.screening[1].breaks_ns.size == 0
    err = calibration_error(rec.truth, res.time_offset_s, res.q_HE, res.p_HE)
    assert err.time_offset_s < 2e-3 and err.translation_m < 0.01 and err.rotation_deg < 0.3
    assert res.quality.verdict == 'good', res.quality.reasons


def test_a_rig_at_rest_written_to_the_millimetre_keeps_its_repeated_poses() -> None:
    """At rest, positions written to the millimetre repeat bit for bit; the rig then leaves its
    rest at once at 0.5 m/s, by steps of 5 mm (beyond the floor) like the ones that follow: the
    repeated poses are data, not a held dropout."""
    t = np.arange(0.0, 4.0, 0.01)
    moving = np.clip(t - 2.0, 0.0, None)
    p = np.round(np.stack((1.0 + 0.5 * moving, 0.1 * moving, np.full_like(t, 0.8)), axis=1), 3)
    q = np.round(Rotation.from_rotvec(np.outer(0.2 + 0.3 * moving, [0.0, 0.0, 1.0])).as_quat(), 4)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    traj = Trajectory.from_arrays((t * 1e9).astype(np.int64), p, q, 'hand')
    assert screen(traj, 'hand')[1].n_removed == 0


def test_too_many_outliers_are_refused_naming_the_stream() -> None:
    rec = recording(seed=7, level=1.0)
    rng = np.random.default_rng(1)
    idx = np.arange(5, len(rec.eye) - 5, 4)  # a quarter of the eye
    bad = _with(rec.eye, idx, rec.eye.p_xyz[idx] + rng.normal(0, 0.3, (idx.size, 3)))
    with pytest.raises(InputError, match=r'eye stream .*max_outlier_fraction'):
        calibrate(rec.hand, bad)
    res = calibrate(rec.hand, bad, CalibrationConfig(max_outlier_fraction=0.5))
    assert res.screening[1].fraction > 0.2
    assert 'outliers_removed' in res.quality.codes


def test_a_mocap_that_loses_the_body_for_long_is_missing_not_wrong() -> None:
    """The MoCap writes zeros for 12 s of 60 while it has lost the body (a fifth of the hand,
    beyond max_outlier_fraction's 15 %): missing poses, said as such, not outliers; the rest
    is calibrated to the truth (level 2 errors are ~2 mm / 0.1 deg)."""
    rec = recording(seed=6, level=2.0)
    t = rec.hand.seconds(int(rec.hand.t_ns[0]))
    lost = np.flatnonzero((t > 20.0) & (t < 32.0))
    hand = _with(rec.hand, lost, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))
    res = calibrate(hand, rec.eye)
    assert res.screening[0].n_placeholders == lost.size and res.screening[0].fraction == 0.0
    assert any('left out as missing' in n for n in res.quality.notes), res.quality.notes
    assert 'outliers_removed' not in res.quality.codes
    err = calibration_error(rec.truth, res.time_offset_s, res.q_HE, res.p_HE)
    assert err.time_offset_s < 2e-3 and err.translation_m < 0.01 and err.rotation_deg < 0.3


def test_damaged_blocks_are_named_and_screened_or_refused() -> None:
    """Blocks of rows whose x column holds ~1e9 m (a corrupted column, as in the published DSO
    outdoors4 files): a small fraction is screened as damaged, named in the warnings, and the
    calibration is as good as without it; a large one is refused with a message that says how
    many rows, in how many blocks and what, instead of a RANSAC or convention failure."""
    rec = recording(seed=4, level=2.0)
    rng = np.random.default_rng(1)
    n = len(rec.eye)

    def wreck(blocks: list[tuple[int, int]]) -> Trajectory:
        idx = np.concatenate([np.arange(a, b) for a, b in blocks])
        p = rec.eye.p_xyz[idx].copy()
        p[:, 0] = rng.uniform(1.0e9, 1.2e9, idx.size)
        return _with(rec.eye, idx, p)

    few = wreck([(100, 110), (500, 530)])  # 40 rows, 3 %
    _, rep = screen(few, 'eye')
    assert rep.counts['damaged'] == 40
    res = calibrate(rec.hand, few)
    assert any('40 of' in w and 'damaged, in 2 block(s)' in w for w in res.warnings)
    err = calibration_error(rec.truth, res.time_offset_s, res.q_HE, res.p_HE)
    assert err.translation_m < 0.005 and err.rotation_deg < 0.2 and err.time_offset_s < 2e-3
    many = wreck([(50, 60), (200, 200 + n // 4)])
    with pytest.raises(
        InputError, match=r'rows \(2\d%\) are damaged, in 2 block\(s\).*x positions'
    ):
        calibrate(rec.hand, many)
