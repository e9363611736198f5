"""The readiness gathered as a recording grows (core/checks/progress.py): the poses new since the
last status, added piece by piece, say what the whole recording read at once says; pieces of
poses a buffer dropped leave; a clock that jumps moves the estimate beyond its sigma."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from conftest import recording

from handeye_ros.core.checks.progress import PIECE_S, measure, start
from handeye_ros.core.checks.readiness import readiness_of
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import InputError
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.stream.buffer import PoseBuffer

CFG = CalibrationConfig()
RATES = {'hand_rate_hz': 200.0, 'eye_rate_hz': 30.0}
MOCAP = {'hand_noise_m': 1e-4, 'hand_noise_deg': 0.0057}


def _until(traj: Trajectory, t_ns: int) -> Trajectory:
    return traj.select(np.flatnonzero(traj.t_ns <= t_ns))


def _since(traj: Trajectory, t_ns: int, until_ns: int) -> Trajectory:
    """What PoseBuffer.since gives: from the newest pose at or before t_ns."""
    first = max(int(np.searchsorted(traj.t_ns, t_ns, side='right')) - 1, 0)
    return traj.select(np.arange(first, int(np.searchsorted(traj.t_ns, until_ns, 'right'))))


def _grow(hand: Trajectory, eye: Trajectory, first_s: float, step_s: float, shift_ns=None):
    """start() on the first ``first_s``, then measure() every ``step_s`` to the end, as the
    node does; ``shift_ns(t)`` may move the eye's stamps after the start (a clock jump)."""
    t0 = int(eye.t_ns[0])
    cut = t0 + int(first_s * 1e9)
    p = start(_until(hand, cut), _until(eye, cut), CFG)
    end = int(min(hand.t_ns[-1], eye.t_ns[-1]))
    while cut < end:
        cut = min(cut + int(step_s * 1e9), end)
        h, e = _until(hand, cut), _until(eye, cut)
        hand_from, eye_from = p.wants(int(h.t_ns[-1]), int(e.t_ns[-1]))
        p.take(measure(p.cursor(), _since(hand, hand_from, cut), _since(eye, eye_from, cut), CFG))
    return p


@pytest.mark.parametrize('seed', [1, 2])
def test_growing_says_what_the_whole_recording_says(seed: int) -> None:
    """Read 20 s at once, then 2 s at a time to 90 s: the predicted sigmas are those of the
    whole recording read at once at the same estimate, within 3 % (the pieces' outliers are
    judged by the noise known when they came; the noise is a histogram's median), and so is
    the excitation (the turn steps restart at each read, within 2 %)."""
    rec = recording(seed, 5, duration_s=90.0, **RATES, **MOCAP)
    grown = _grow(rec.hand, rec.eye, 20.0, 2.0)
    whole = start(rec.hand, rec.eye, CFG, known=grown.known)
    d = (rec.hand.duration_s, rec.eye.duration_s)
    a, b = readiness_of(grown, CFG, d), readiness_of(whole, CFG, d)
    assert a.ready and b.ready
    np.testing.assert_allclose(a.sigma, b.sigma, rtol=0.03)
    np.testing.assert_allclose(a.span_s, b.span_s, rtol=0.01)
    np.testing.assert_allclose(a.rotation_deg, b.rotation_deg, rtol=0.02)
    np.testing.assert_allclose(a.angular_speed_dps, b.angular_speed_dps, rtol=0.02)
    # the pieces stay few: one per PIECE_S
    assert len(grown.pairs) <= 90.0 / PIECE_S + 2


def test_pieces_of_dropped_poses_leave() -> None:
    """A buffer that dropped its first 40 s: the sigmas are those of what it still holds."""
    rec = recording(3, 5, duration_s=90.0, **RATES, **MOCAP)
    p = _grow(rec.hand, rec.eye, 20.0, 2.0)
    before = readiness_of(p, CFG, (90.0, 90.0))
    oldest = int(rec.eye.t_ns[0]) + int(40e9)
    p.drop_before(oldest, oldest)
    after = readiness_of(p, CFG, (50.0, 50.0))
    assert after.span_s < 0.62 * before.span_s
    assert all(x > y for x, y in zip(after.sigma, before.sigma, strict=True))
    assert after.rotation_deg.sum() < 0.62 * before.rotation_deg.sum()


@pytest.mark.parametrize('seed', [1, 2])
def test_a_clock_that_jumps_moves_the_estimate(seed: int) -> None:
    """The eye's stamps jump by 30 ms after 40 s of 60 (the offset's 1-sigma is about 0.4 ms):
    the pieces since call for a step of many sigmas in dt, and the node reads the whole buffers
    again. Without the jump, the step from 40 s to 60 s stays within 3 sigmas (white noise:
    about sqrt(20 / 40) of one)."""
    rec = recording(seed, 5, duration_s=60.0, **RATES, **MOCAP)
    t = rec.eye.t_ns.copy()
    t[t > t[0] + int(40e9)] += int(30e6)
    jumped = replace(rec.eye, t_ns=t)
    (size, _, _), (sigma, _, _) = _grow(rec.hand, rec.eye, 40.0, 2.0).step()
    assert size < 3 * sigma
    moved = _grow(rec.hand, jumped, 40.0, 2.0)
    (size, _, _), (sigma, _, _) = moved.step()
    assert size > 10 * sigma and size > 5e-3, (size, sigma)
    assert 'time offset' in moved.moved()


def test_nothing_new_or_an_empty_start_never_raises() -> None:
    """A status with no new poses, or a start on a still or short recording, says so."""
    rec = recording(1, 5, duration_s=30.0, **RATES, **MOCAP)
    p = start(rec.hand, rec.eye, CFG)
    tail_h = _since(rec.hand, int(rec.hand.t_ns[-1]), int(rec.hand.t_ns[-1]))
    tail_e = _since(rec.eye, int(rec.eye.t_ns[-3]), int(rec.eye.t_ns[-1]))
    m = measure(p.cursor(), tail_h, tail_e, CFG)
    assert m.pairs is None
    short = start(
        _until(rec.hand, rec.hand.t_ns[0] + int(5e9)), rec.eye.select(np.arange(150)), CFG
    )
    said = readiness_of(short, CFG, (5.0, 5.0))
    assert not said.ready and said.missing[0].startswith('keep recording'), said.missing


def test_buffer_since_reads_the_tail_across_the_ring() -> None:
    """PoseBuffer.since: from the newest pose at or before the stamp, across the ring's wrap."""
    buf = PoseBuffer('hand', capacity=10)
    for k in range(1, 26):  # wraps twice; holds 16..25
        assert buf.add((k * 100, 0.0, 0.0, float(k), 0.0, 0.0, 0.0, 1.0)) is None
    assert buf.oldest_ns == 1600 and buf.newest_ns == 2500
    np.testing.assert_array_equal(buf.since(2150).t_ns, [2100, 2200, 2300, 2400, 2500])
    np.testing.assert_array_equal(buf.since(2100).t_ns, [2100, 2200, 2300, 2400, 2500])
    np.testing.assert_array_equal(buf.since(0).t_ns, np.arange(16, 26) * 100)
    with pytest.raises(InputError, match='holds 1 pose'):  # the status waits for more
        buf.since(10**6)
    np.testing.assert_array_equal(buf.since(1950).p_xyz[:, 2], [19, 20, 21, 22, 23, 24, 25])


def test_what_makes_the_status_read_everything_again() -> None:
    """No estimate yet, a recording grown by half, or a clock that jumped: the whole buffers
    are read again (Progress.due); otherwise the pieces go on."""
    rec = recording(1, 5, duration_s=60.0, **RATES, **MOCAP)
    short = start(
        _until(rec.hand, rec.hand.t_ns[0] + int(5e9)), rec.eye.select(np.arange(150)), CFG
    )
    assert short.due(5.0).startswith('keep recording')
    p = _grow(rec.hand, rec.eye, 40.0, 2.0)
    assert p.span_s == pytest.approx(39.0, abs=1.0)
    assert p.due(p.span_s * 1.4) is None
    assert 'grown' in p.due(p.span_s * 1.5)


def test_inverted_mocap_poses_are_said_with_the_fix_not_more_motion() -> None:
    """MoCap poses published inverted (T_HG for T_GH): the status names the mistake and the
    option, and is not ready, instead of asking for motion it already has."""
    from handeye_ros.core.checks.orientations import reread

    rec = recording(seed=2, level=2.0, duration_s=60.0, **RATES)
    p = start(reread(rec.hand, 'inverse'), rec.eye, CFG)
    ready = readiness_of(p, CFG, (60.0, 60.0))
    assert not ready.ready
    assert ready.missing[0].startswith('the MoCap: its poses were the inverse'), ready.missing
    assert 'invert_hand' in ready.missing[0]
    assert start(rec.hand, rec.eye, CFG).refused is None


def test_a_device_stream_too_sparse_for_the_status_is_said_with_its_rate() -> None:
    """A VIO at 1 Hz: the status names the rate and the fix, not the clocks or the motion."""
    rec = recording(seed=2, level=2.0, duration_s=60.0, **RATES)
    sparse = rec.eye.select(np.arange(0, len(rec.eye), 30))  # 30 Hz -> 1 Hz
    ready = readiness_of(start(rec.hand, sparse, CFG), CFG, (60.0, 60.0))
    assert not ready.ready
    assert ready.missing[0].startswith("the device's poses come 1.00 s apart (1.0 Hz)")
