"""Conventions checked, not assumed: stamp units, quaternion order, inverted poses, mirrored
positions, JPL quaternions, epochs.

Every mistake is either read the way the data support (with a correction that names it and a
verdict that is not good, since the files still hold the mistake), or refused naming the
options; never a confident wrong number. Tolerances: the corrected result must equal the
result on the right files (1e-9 m and deg, up to the re-chained float arithmetic).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import recording
from scipy.spatial.transform import Rotation

from handeye_ros.core.checks.conventions import check_stamp_units, epoch_note
from handeye_ros.core.checks.orientations import PERMUTATIONS, reading_fits, reread
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import InputError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import calibration_error
from handeye_ros.core.trajectory import Trajectory


def _stamps(traj: Trajectory, t_ns: np.ndarray) -> Trajectory:
    return Trajectory.from_arrays(t_ns, traj.p_xyz, traj.q_xyzw, traj.name)


def test_plausible_stamps_are_kept() -> None:
    rec = recording(seed=1)
    hand, eye, found = check_stamp_units(rec.hand, rec.eye)
    assert hand is rec.hand and eye is rec.eye and found == []


@pytest.mark.parametrize(
    ('stream', 'factor', 'unit'),
    [
        ('eye', 1000, 'milliseconds'),  # a TUM file in ms since boot, read as s
        ('eye', 10**6, 'microseconds'),  # in us since boot, read as s
        ('hand', 10**-3, 'microseconds'),  # a EuRoC file in Unix us, read as ns
    ],
)
def test_a_stream_in_another_unit_is_read_in_it(stream: str, factor: float, unit: str) -> None:
    """What the reader makes of a file in another unit than its format's: the stamps scaled
    by a power of 1000 (boot-time clocks for the large ones: Unix ms read as s would not fit
    int64 ns, and the reader takes those as ms itself)."""
    rec = recording(seed=2)
    traj = getattr(rec, stream)
    if factor > 1:
        boot = traj.t_ns - int(traj.t_ns[0]) + 3_600 * 10**9
        scaled = boot * np.int64(factor) // 10**6 * 10**6  # written to the microsecond
    else:
        scaled = traj.t_ns // round(1 / factor)
    wrong = _stamps(traj, scaled)
    hand, eye = (wrong, rec.eye) if stream == 'hand' else (rec.hand, wrong)
    fixed_h, fixed_e, found = check_stamp_units(hand, eye)
    assert [(c.stream, c.what) for c in found] == [(stream, 'stamp_unit')]
    assert unit in found[0].assumed and f'--{stream}-stamp-unit' in found[0].message
    fixed = fixed_h if stream == 'hand' else fixed_e
    assert fixed.rate_hz == pytest.approx(traj.rate_hz, rel=1e-3)


def test_epochs_are_named() -> None:
    rec = recording(seed=4)
    boot = rec.eye.shifted(3_612 * 10**9 - int(rec.eye.t_ns[0]))
    note = epoch_note(rec.hand, boot)
    assert note is not None and 'time since boot' in note and 'absolute epoch' in note
    assert epoch_note(rec.hand, rec.eye) is None


def _misread(traj: Trajectory, reading: str) -> Trajectory:
    """What a reader makes of a stream written in another convention: the inverse of
    :func:`reread` (the quaternion permutations are each other's inverse)."""
    if reading == 'inverse':
        return reread(traj, 'inverse')
    other = {'wxyz': 'xyzw', 'xyzw': 'wxyz'}[reading]
    return Trajectory.from_arrays(
        traj.t_ns, traj.p_xyz, traj.q_xyzw[:, PERMUTATIONS[other]], traj.name
    )


@pytest.mark.parametrize(
    ('stream', 'reading'),
    [('eye', 'wxyz'), ('eye', 'xyzw'), ('eye', 'inverse'), ('hand', 'wxyz'), ('hand', 'xyzw')],
)
def test_orientation_mistakes_are_found_and_read_right(stream: str, reading: str) -> None:
    """A quaternion order swapped or poses inverted: AX = XB holds only under the right
    reading, which is applied, named, and leaves the verdict doubtful. Poses not read from a
    file (arrays, a bag's or a topic's messages, x y z w by definition) have no option that
    states another order: the message says to fix their source."""
    rec = recording(seed=5, level=2.0)
    right = calibrate(rec.hand, rec.eye)
    hand = _misread(rec.hand, reading) if stream == 'hand' else rec.hand
    eye = _misread(rec.eye, reading) if stream == 'eye' else rec.eye
    fits = reading_fits(hand, eye, rec.truth.time_offset_s, np.deg2rad(5.0))
    best = min(fits, key=lambda f: f.score)
    assert (best.stream, best.reading) == (stream, reading)
    as_given = next(f for f in fits if f.reading == 'as given')
    assert as_given.score > 10 * best.score
    res = calibrate(hand, eye)
    assert [(c.stream, c.assumed) for c in res.corrections] == [(stream, reading)]
    if reading == 'inverse':
        assert res.corrections[0].option == f'invert_{stream}'
    else:
        assert res.corrections[0].option == ''
        assert 'fix their source: they were not read from a file' in res.corrections[0].message
    assert res.quality.verdict == 'doubtful' and 'convention_corrected' in res.quality.codes
    e = calibration_error(rec.truth, res.time_offset_s, res.q_HE, res.p_HE)
    e0 = calibration_error(rec.truth, right.time_offset_s, right.q_HE, right.p_HE)
    assert abs(e.translation_m - e0.translation_m) < 1e-4
    assert abs(e.rotation_deg - e0.rotation_deg) < 1e-3


@pytest.mark.parametrize(('stream', 'axis'), [('eye', 0), ('eye', 1), ('hand', 2)])
def test_a_stream_in_a_left_handed_frame_is_refused_named(stream: str, axis: int) -> None:
    """One axis flipped in a stream's positions and its quaternions converted alike (a
    left-handed frame, as Unity's): the rotations fit, the translations do not, and negating
    either stream's positions fits exactly; refused, naming the mirror and the fix."""
    rec = recording(seed=5, level=2.0)
    S = np.ones(3)
    S[axis] = -1.0
    traj = rec.hand if stream == 'hand' else rec.eye
    q = traj.q_xyzw.copy()
    q[:, :3] *= -S  # S R S for the reflection S: its axis -S u, the same angle
    mirrored = Trajectory.from_arrays(traj.t_ns, traj.p_xyz * S, q, traj.name)
    hand, eye = (mirrored, rec.eye) if stream == 'hand' else (rec.hand, mirrored)
    with pytest.raises(InputError, match='mirrored against its orientations.*negate its'):
        calibrate(hand, eye)


@pytest.mark.parametrize(('stream', 'seed'), [('eye', 5), ('hand', 6)])
def test_jpl_quaternions_are_refused_naming_the_stream(stream: str, seed: int) -> None:
    """A stream whose quaternions are the conjugates of Hamilton's (JPL's convention), its
    positions as they are: only the conjugate explains both rotations and translations, so
    the stream is named with the fix; the other stream's readings do not fit."""
    rec = recording(seed=seed, level=2.0)
    traj = rec.hand if stream == 'hand' else rec.eye
    q = traj.q_xyzw * [-1.0, -1.0, -1.0, 1.0]
    jpl = Trajectory.from_arrays(traj.t_ns, traj.p_xyz, q, 'jpl.txt')
    hand, eye = (jpl, rec.eye) if stream == 'hand' else (rec.hand, jpl)
    with pytest.raises(InputError, match=f"^jpl.txt: the {stream} stream's quaternions are the"):
        calibrate(hand, eye)


@pytest.mark.parametrize('seed', range(3))
def test_motion_about_one_axis_leaves_the_reading_as_given(seed: int) -> None:
    """A ground robot turns about one axis: every reading of its orientations turns the
    motions alike, so the check has nothing to tell them by and reads them as given (it
    refused some 60-s planar recordings, read back from TUM files, with four fixes named)."""
    rec = recording(seed=700 + seed, level=3.0, duration_s=60.0, motion='planar')
    assert reading_fits(rec.hand, rec.eye, rec.truth.time_offset_s, np.deg2rad(5.0)) == []
    assert calibrate(rec.hand, rec.eye).corrections == ()


def test_stating_the_convention_makes_it_good() -> None:
    """An eye given as T_EW with invert_eye set: nothing to correct, verdict good."""
    rec = recording(seed=6, level=2.0)
    res = calibrate(rec.hand, reread(rec.eye, 'inverse'), CalibrationConfig(invert_eye=True))
    assert res.corrections == () and res.quality.verdict == 'good', res.quality.reasons


def test_check_can_be_switched_off() -> None:
    """check_conventions off: the mistake goes through, and the verdict fails on AX = XB."""
    rec = recording(seed=7, level=2.0)
    res = calibrate(
        rec.hand, _misread(rec.eye, 'wxyz'), CalibrationConfig(check_conventions=False)
    )
    assert res.corrections == ()
    assert res.quality.verdict == 'failed' and 'inconsistent' in res.quality.codes


def test_rotation_misreading_is_an_inversion_up_to_fixed_frames() -> None:
    """Why the magnitude correlation cannot see these mistakes: a permutation of the
    quaternion's numbers is q -> a q* b (an improper map of R^4), so |dq/dt| is unchanged."""
    rng = np.random.default_rng(0)
    q = Rotation.random(50, random_state=rng).as_quat()
    p = q[:, PERMUTATIONS['wxyz']]
    # relative angles between any two are preserved
    ang = lambda Q: Rotation.from_quat(Q[1:]).inv() * Rotation.from_quat(Q[:-1])
    np.testing.assert_allclose(ang(q).magnitude(), ang(p).magnitude(), atol=1e-9)


@pytest.mark.parametrize(('order', 'scale'), [('yzwx', 1.0), ('wxyz', 0.4)])
def test_a_file_in_another_order_is_named_in_its_own_order(
    tmp_path, order: str, scale: float
) -> None:
    """The eye written as a TUM file in another order of its quaternion's numbers: y z w x (what
    Eigen's Quaterniond(x, y, z, w), whose constructor takes w first, writes), or w x y z by a
    monocular VO (its positions 0.4 of metric): the reading that fits is found with the eye's
    scale free, applied, and named in the file's own order with the option's value; stating
    that order reads the file right (the TUM-VI monocular VO files of ../shared/data/real were
    refused with six fixes named, none of them the mistake)."""
    from handeye_ros.formats.text import read_trajectory, write_tum

    rec = recording(seed=8, level=2.0)
    path = tmp_path / 'eye.txt'
    write_tum(path, Trajectory.from_arrays(rec.eye.t_ns, rec.eye.p_xyz * scale, rec.eye.q_xyzw))
    # the file's quaternion columns rewritten in ``order`` (write_tum writes x y z w)
    rows = [line.split() for line in path.read_text().splitlines()[1:]]
    written = [r[:4] + [r[4 + 'xyzw'.index(c)] for c in order] for r in rows]
    path.write_text(''.join(' '.join(r) + '\n' for r in written))
    cfg = CalibrationConfig(estimate_scale=scale != 1.0)
    res = calibrate(rec.hand, read_trajectory(path), cfg)
    (fix,) = res.corrections
    assert f'its quaternion numbers were {" ".join(order)} where x y z w was read' in fix.message
    assert f'say so with eye_quaternion_order {order} ' in fix.message
    stated = calibrate(rec.hand, read_trajectory(path, quaternion_order=order), cfg)
    assert stated.corrections == ()
    e = calibration_error(rec.truth, res.time_offset_s, res.q_HE, res.p_HE)
    e0 = calibration_error(rec.truth, stated.time_offset_s, stated.q_HE, stated.p_HE)
    assert abs(e.translation_m - e0.translation_m) < 1e-4
    assert abs(e.rotation_deg - e0.rotation_deg) < 1e-3
