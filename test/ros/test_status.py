"""auto_calibrate's rules (auto_mode.judge, auto_mode.richer): a later result published only when it
improves the precision ratio, converged (stalled while doubtful for a reason more recording does
not remedy) once it improves it too little, calibrated again when the predicted ratio falls well
below; and how the status tells that a clock jumped. READY carried from a result:
test/core/checks/test_carry.py."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip('diagnostic_msgs')

from handeye_ros.core.checks.verdict import precision_ratio
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.ros.auto_mode import (
    GROWTH,
    IMPROVEMENT,
    RECALIBRATE,
    AutoMode,
    judge,
    moved_beyond,
    richer,
)
from handeye_ros.ros.clocks import Arrivals, ClockWatch, clocks_apart, replay_pace


@pytest.mark.parametrize(
    ('sigmas', 'published', 'auto', 'targets', 'expected'),
    [
        # the first result, or one asked for by ~/calibrate: published, nothing judged
        ((1.0, 1.0, 1.0), None, True, (1.0, 1.0, 1.0), (True, False)),
        ((9.0, 9.0, 9.0), (1.0, 1.0, 1.0), False, (1.0, 1.0, 1.0), (True, False)),
        # auto: the precision ratio smaller by more than IMPROVEMENT: published, keeps going
        ((0.8, 0.8, 0.8), (1.0, 1.0, 1.0), True, (1.0, 1.0, 1.0), (True, False)),
        # one sigma larger, the largest one smaller by more than IMPROVEMENT: keeps going
        ((0.5, 0.5, 0.7), (1.0, 0.6, 0.6), True, (1.0, 1.0, 1.0), (True, False)),
        # the ratio smaller, not by IMPROVEMENT: published, converged
        ((0.95, 0.8, 0.99), (1.0, 1.0, 1.0), True, (1.0, 1.0, 1.0), (True, True)),
        # the ratio larger: the published result stays, converged
        ((0.5, 0.5, 1.01), (1.0, 1.0, 1.0), True, (1.0, 1.0, 1.0), (False, True)),
        # far below the targets, 18 % less is under 10 % of the target: converged
        ((0.41, 0.41, 0.41), (0.5, 0.5, 0.5), True, (1.0, 1.0, 1.0), (True, True)),
        # above a target (the translation's), 18 % of itself counts: keeps going
        ((0.41, 0.82, 0.41), (0.5, 1.0, 0.5), True, (1.0, 0.5, 1.0), (True, False)),
    ],
)
def test_a_later_auto_result(sigmas, published, auto, targets, expected) -> None:
    assert IMPROVEMENT == 0.1
    assert judge(sigmas, published, auto, targets) == expected


@pytest.mark.parametrize(
    ('then', 'now', 'expected'),
    [
        # what a user met: converged at 6.7 mm / 0.32 deg (ratio 0.67), then minutes of
        # richer motion predicted 0.6 mm / 0.04 deg (0.08)
        (0.67, 0.08, True),
        # white noise after converging at half the targets: another 1.5x of span is no reason
        (0.5, 0.5 / np.sqrt(GROWTH), False),
        # above the targets, a fifth of itself
        (3.0, 2.3, True),
        (3.0, 2.5, False),
        # no prediction at the last calibration (a sigma unknown): nothing to compare
        (float('inf'), 0.1, False),
    ],
)
def test_converged_calibrates_again_when_the_prediction_falls_well_below(
    then, now, expected
) -> None:
    assert RECALIBRATE == 2 * IMPROVEMENT
    assert richer(then, now) is expected


def test_the_precision_ratio_is_the_largest_sigma_over_its_target() -> None:
    assert precision_ratio((0.5e-3, 6.7e-3, 0.32), (1e-3, 0.01, 0.5)) == pytest.approx(0.67)


def test_white_noise_converges_once_the_sigmas_are_about_half_the_targets() -> None:
    """White noise shrinks every sigma by 1/sqrt(GROWTH) at each later result, for ever: auto
    mode stops once more recording no longer matters to the verdict."""
    targets, sigma = (1e-3, 0.01, 0.0087), np.array([1e-3, 0.01, 0.0087])  # READY: at them
    for results in range(2, 20):
        new = sigma / np.sqrt(GROWTH)
        admitted, converged = judge(tuple(new), tuple(sigma), True, targets)
        assert admitted
        sigma = new
        if converged:
            break
    assert converged and results <= 6, results
    assert np.all(sigma / targets < 0.6) and np.all(sigma / targets > 0.3), sigma / targets


def test_the_clocks_move_apart_only_when_stamps_move_unlike_arrivals() -> None:
    """A 100 Hz MoCap and a 20 Hz device published in real time (arrival = stamp + 5 ms)."""
    hand = np.arange(0, 2000) * 10_000_000  # ns, 20 s
    eye = np.arange(0, 400) * 50_000_000

    def apart(h_end: float, e_end: float, e_seen: float, jump_s: float = 0.0) -> float:
        h, e = hand[hand <= h_end * 1e9], eye[eye <= e_end * 1e9]
        snap = Arrivals(int(h[-1]), int(e[-1]) + round(jump_s * 1e9), h[-1] * 1e-9 + 0.005, e_seen)
        return clocks_apart(snap)

    first = apart(10.0, 10.0, 10.005)
    # the device's stream ends 1 s before the MoCap's: nothing moved
    assert apart(19.0, 18.0, 18.005) == pytest.approx(first, abs=1e-9)
    # its messages keep coming but are refused for 3 s (a clock that went back 3 s)
    assert apart(19.0, 16.0, 19.005) - first == pytest.approx(-3.0, abs=1e-9)
    # its clock jumped 5 s forward
    assert apart(19.0, 19.0, 19.005, jump_s=5.0) - first == pytest.approx(5.0, abs=1e-9)


def _replayed(pace: float, lag_s: list[float], jump_s: float = 0.0) -> float | None:
    """What a ClockWatch says of snapshots every 0.5 s of a replay at ``pace`` (stamps per
    second of arrivals), the device's deliveries late by ``lag_s`` at each, its clock moved by
    ``jump_s`` from the fifth snapshot on; the last answer."""
    watch, said = ClockWatch(), None
    for k, lag in enumerate(lag_s):
        wall = 0.5 * (k + 1)
        stamp = round(wall * pace * 1e9)
        moved = round(jump_s * 1e9) if k >= 4 else 0
        # the newest device pose that came is the one sent lag_s ago
        eye_ns = round((wall - lag) * pace * 1e9) + moved
        said = watch.moved(Arrivals(stamp, eye_ns, wall, wall), 0.05)
    return said


def test_a_replay_faster_than_real_time_jumps_only_when_its_clocks_do() -> None:
    """A bag replayed 8 times faster than real time on a loaded machine: the device's
    deliveries lag the MoCap's by up to a quarter of a second at some snapshots (2 s of
    stamps) and no clock jumped; the pace the snapshots show (replay_pace) scales what counts
    as a jump. A 20-s jump is said at that pace, a 2-s one live."""
    lags = [0.0, 0.25, 0.0, 0.1, 0.25, 0.0, 0.25, 0.25, 0.0, 0.1]
    assert _replayed(8.0, lags) is None
    assert _replayed(8.0, [0.0] * 10, jump_s=20.0) == pytest.approx(20.0, abs=1e-6)
    assert _replayed(1.0, [0.0] * 10, jump_s=2.0) == pytest.approx(2.0, abs=1e-6)
    assert _replayed(1.0, [0.0] * 10) is None
    assert replay_pace(Arrivals(0, 0, 0.0, 0.0), Arrivals(8_000_000_000, 0, 1.0, 1.0)) == 8.0


def test_a_result_moved_beyond_the_published_sigma_is_said() -> None:
    q = np.array([0.0, 0.0, 0.0, 1.0])
    old = (0.010, np.array([0.1, 0.0, 0.0]), q)
    sigmas = (0.5e-3, 5e-3, 0.2)
    assert moved_beyond((0.0103, np.array([0.103, 0.0, 0.0]), q), old, sigmas) is None
    assert moved_beyond((0.010, np.array([0.1, 0.0, -0.006]), q), old, sigmas) == 'translation'
    assert moved_beyond(old, None, None) is None


def test_a_stopped_stream_is_a_warning_at_0_hz_until_it_resumes() -> None:
    from diagnostic_msgs.msg import DiagnosticStatus

    from handeye_ros.ros.diagnostics import STOPPED_S, stream_status
    from handeye_ros.stream.buffer import BufferStats

    stats = BufferStats(6000, 6000, 0, {}, 60.0, 100.0, 1)

    def said(quiet_s: float) -> tuple[int, str, str]:
        st = stream_status('/calibrator', 'hand', stats, '/mocap/pose', 'PoseStamped', quiet_s)
        return st.level, st.message, {v.key: v.value for v in st.values}['rate_hz']

    assert said(0.01) == (DiagnosticStatus.OK, '100.0 Hz', '100.00')
    assert said(STOPPED_S + 10.0) == (
        DiagnosticStatus.WARN,
        'stopped: no message for 12 s (100.0 Hz before)',
        '0.00',
    )


def _result(mm: float, reasons: list[dict[str, str]], blocks: bool = True) -> SimpleNamespace:
    """What auto mode reads of a calibration: its document's sigmas (with the blocks' term or
    without it), estimate and reasons."""
    t = mm * 1e-3 / np.sqrt(3)
    factors = {'translation': 1.5} if blocks else None
    return SimpleNamespace(
        document={
            'std': {
                'time_offset': 2e-4,
                'translation': [t] * 3,
                'rotation': [1e-3] * 3,
                'block_factors': factors,
            },
            'quality': {'reasons': reasons},
            'time_offset': 0.0,
            'extrinsic': {'translation': [0.0] * 3, 'rotation': [0.0, 0.0, 0.0, 1.0]},
        }
    )


def test_auto_mode_stalled_not_converged_while_its_result_is_doubtful() -> None:
    """Doubtful for a reason more of the same recording does not remedy: stalled. Doubtful for
    its precision alone: one result no better is no floor (EuRoC MH_01 stereo, live: stalled
    at 40 s on a 14-mm result where the whole recording is `good` at 9 mm), so it goes on."""
    node = SimpleNamespace(calib_cfg=CalibrationConfig())
    auto = AutoMode(node, on=True)  # type: ignore[arg-type]
    correlated = [
        {'code': 'residuals_not_white', 'message': 'the residuals are correlated'},
        {'code': 'imprecise', 'message': 'translation 1-sigma 36 mm'},
    ]
    assert auto.admit(_result(40.0, correlated), auto=True) == ''
    assert auto.admit(_result(38.0, correlated), auto=True) == ''  # 5 %: no longer improving
    assert auto.said.startswith('stalled') and 'correlated' in auto.said and auto.ended
    imprecise = [{'code': 'imprecise', 'message': 'translation 1-sigma 14 mm'}]
    going = AutoMode(node, on=True)  # type: ignore[arg-type]
    assert going.admit(_result(14.0, imprecise), auto=True) == ''
    assert going.admit(_result(20.0, imprecise), auto=True) != ''  # not published, no floor
    assert not going.ended
    assert going.admit(_result(9.0, []), auto=True) == ''
    assert going.admit(_result(8.9, []), auto=True) == ''
    assert going.said.startswith('converged') and going.ended
    good = AutoMode(node, on=True)  # type: ignore[arg-type]
    good.admit(_result(8.0, []), auto=True)
    good.admit(_result(7.9, []), auto=True)
    assert good.said.startswith('converged') and good.ended


def test_a_result_with_the_blocks_term_replaces_one_without_it() -> None:
    """A `good` 8.4-mm result of too few eye poses for the blocks is no bar for a later 11-mm
    one that has their term (EuRoC MH_01 stereo, live: it kept every later result from being
    published, and auto mode stalled on it); the next one is judged as before."""
    node = SimpleNamespace(calib_cfg=CalibrationConfig())
    auto = AutoMode(node, on=True)  # type: ignore[arg-type]
    assert auto.admit(_result(8.4, [], blocks=False), auto=True) == ''
    imprecise = [{'code': 'imprecise', 'message': 'translation 1-sigma 11 mm'}]
    assert auto.admit(_result(11.0, imprecise), auto=True) == ''
    assert not auto.ended
    assert auto.admit(_result(9.0, []), auto=True) == ''
    assert auto.admit(_result(9.5, []), auto=True) != ''  # no better: converged on the 9-mm one
    assert auto.said.startswith('converged') and '9' in auto.said
