"""auto_calibrate's policy (auto_mode.decide): a good result published, converged once one
improves its purpose's ratio to the line too little, stalled while doubtful for a reason more
recording does not remedy, done once the buffers are full; and how the status tells that a clock
jumped.
READY from a calibration: test/core/checks/test_readiness.py."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip('diagnostic_msgs')

from handeye_ros.core.checks.readiness import Outcome
from handeye_ros.core.errors import InputError, TooFewMotionsError
from handeye_ros.ros.auto_mode import GROWTH, IMPROVEMENT, Auto, State, decide, filled, said
from handeye_ros.ros.clocks import Arrivals, ClockWatch, clocks_apart, replay_pace

#: a `good` calibration of 60 s of buffers, one near the line of its precision, and one held
#: back by its precision alone
GOOD = Outcome(True, 'good', '', (2e-4, 5e-3, 0.2), True, 60.0, 0.0, ratio=0.5)
NEAR = Outcome(True, 'good', '', (2e-4, 9e-3, 0.2), True, 60.0, 0.0, ratio=0.9)
IMPRECISE = Outcome(
    False, 'doubtful (imprecise)', 'translation 1-sigma 14 mm', (2e-4, 0.014, 0.2), True, 60.0, 0.0
)
CORRELATED = Outcome(
    False, 'doubtful (residuals_not_white)', 'the residuals are correlated', None, False, 60.0, 0.0
)


@pytest.mark.parametrize(
    ('published', 'ratio', 'state'),
    [
        # the first good result: published, improving
        (float('inf'), 0.8, State.IMPROVING),
        # smaller by more than IMPROVEMENT (of the line): published, keeps going
        (1.0, 0.8, State.IMPROVING),
        # smaller, not by IMPROVEMENT: published, converged
        (0.75, 0.7, State.CONVERGED),
        # larger: still published (more data), converged
        (0.5, 0.6, State.CONVERGED),
        # far below the line, 18 % less is under 10 % of the line: converged
        (0.5, 0.41, State.CONVERGED),
        # not by IMPROVEMENT but near the line (not settled): no place to stop
        (0.95, 0.9, State.IMPROVING),
    ],
)
def test_a_good_result_is_published(published: float, ratio: float, state: State) -> None:
    """A result is measured by its purpose's ratio to the line (:attr:`Outcome.ratio`: the
    same measure READY reads), for an evaluation its figures' largest share."""
    assert IMPROVEMENT == 0.1
    got = decide(Auto(State.IMPROVING, published), replace(GOOD, ratio=ratio), full=False)
    assert got.publish and got.state is state and got.published == ratio
    # its 1-sigmas without the blocks' term (too few eye poses): published, never converged
    partial = replace(GOOD, ratio=ratio, complete=False)
    got = decide(Auto(State.IMPROVING, published), partial, full=False)
    assert got.publish and got.state is State.IMPROVING


def test_once_converged_a_good_result_is_published_for_more_data_only() -> None:
    """The status checks a READY result again as the buffers grow: converged, a good result no
    better than the published one is published once it has GROWTH times its data."""
    converged = decide(Auto(State.IMPROVING, 0.5), replace(GOOD, ratio=0.49), full=False)
    assert converged.publish and converged.state is State.CONVERGED
    assert converged.published_span_s == GOOD.span_s
    again = decide(converged, replace(GOOD, ratio=0.48), full=False)
    assert not again.publish and again.state is State.CONVERGED and again.published == 0.49
    longer = replace(GOOD, span_s=GROWTH * GOOD.span_s, ratio=0.48)
    grown = decide(again, longer, full=False)
    assert grown.publish and grown.published_span_s == longer.span_s
    better = replace(GOOD, ratio=0.2)
    assert decide(grown, better, full=False).publish  # published at any span


def test_convergence_is_judged_over_half_as_much_data_again() -> None:
    """The status calibrates the buffers every second or so: a settled result a second after
    the published one hardly improves on it, which says nothing of convergence (white noise
    shrinks the ratio by 18 % over GROWTH). Converged once one with GROWTH times the published
    span improves too little, and so while the results that follow improve no more."""
    published = decide(Auto.start(True), replace(GOOD, ratio=0.7), full=False)
    second = decide(published, replace(GOOD, ratio=0.69, span_s=GOOD.span_s + 1), full=False)
    assert second.state is State.IMPROVING and not second.publish
    grown = replace(GOOD, ratio=0.65, span_s=GROWTH * GOOD.span_s)
    converged = decide(second, grown, full=False)
    assert converged.state is State.CONVERGED and converged.publish
    later = replace(grown, ratio=0.64, span_s=grown.span_s + 1)
    kept = decide(converged, later, full=False)
    assert kept.state is State.CONVERGED and not kept.publish


def test_a_good_result_near_its_line_is_published_but_never_converged() -> None:
    """Good by a hair (beyond BLOCKS_MARGIN of its line), a result is published, and auto mode
    goes on: the next calibration may find it beyond the line, so it is no place to stop. As
    before convergence, it publishes again what improves or has GROWTH times the data."""
    near = decide(Auto(State.IMPROVING, 0.9), NEAR, full=False)
    assert near.publish and near.state is State.IMPROVING
    # no better, no more data: not news
    again = decide(near, replace(NEAR, ratio=0.88), full=False)
    assert not again.publish and again.state is State.IMPROVING and again.published == 0.9
    grown = replace(NEAR, span_s=GROWTH * NEAR.span_s, ratio=0.88)
    assert decide(near, grown, full=False).publish
    settled = replace(GOOD, ratio=0.8, span_s=GROWTH * NEAR.span_s)
    assert decide(near, settled, full=False).state is State.CONVERGED


def test_a_result_that_is_not_good_is_never_published() -> None:
    """Held back by its precision: more recording is the remedy, auto mode waits; by a reason
    more of the same recording does not remedy: stalled, said with it. A later good result
    (richer motion) is published whatever came before."""
    first = Auto.start(True)
    waiting = decide(first, IMPRECISE, full=False)
    assert not waiting.publish and waiting.state is State.WAITING
    stalled = decide(waiting, CORRELATED, full=False)
    assert not stalled.publish and stalled.state is State.STALLED
    assert 'the residuals are correlated' in said(stalled)
    assert decide(stalled, GOOD, full=False).publish
    converged = decide(Auto(State.IMPROVING, 0.5), replace(GOOD, ratio=0.49), full=False)
    assert decide(converged, IMPRECISE, full=False).state is State.WAITING  # not converged


def test_a_refused_input_stalls_auto_mode_where_too_few_motions_wait() -> None:
    """Turning more remedies too few motions; it does not remedy positions in millimetres."""
    first = Auto.start(True)
    few = Outcome.failure(TooFewMotionsError('only 9 relative motions'), 12.0, 0.0)
    assert decide(first, few, full=False).state is State.WAITING
    mm = Outcome.failure(InputError("The hand's translations are 1000 times the eye's"), 12.0, 0.0)
    stalled = decide(first, mm, full=False)
    assert stalled.state is State.STALLED and not stalled.publish
    assert said(stalled).startswith('stalled: more of the same recording does not remedy')
    assert "The hand's translations are 1000 times" in said(stalled)


def test_auto_mode_is_done_once_the_buffers_are_full() -> None:
    assert decide(Auto.start(True), IMPRECISE, full=True).state is State.DONE
    assert filled(Auto(State.IMPROVING, 0.8)).state is State.DONE
    assert filled(Auto(State.CONVERGED, 0.4)).state is State.CONVERGED
    assert said(Auto(State.DONE)).startswith('done: the buffers are full')
    off = Auto.start(False)
    assert decide(off, GOOD, full=False) == off and not off.publish


def test_white_noise_converges_once_the_sigmas_are_about_half_the_line() -> None:
    """White noise shrinks every sigma, and so the ratio to the line, by 1/sqrt(1.5) at each
    growth of the buffers by half, for ever: auto mode stops saying it improves once more
    recording no longer matters to the verdict."""
    ratio, span = 1.0, GOOD.span_s  # at the line
    auto = decide(Auto.start(True), replace(GOOD, ratio=ratio), False)
    for results in range(2, 20):
        ratio, span = ratio / np.sqrt(1.5), span * 1.5
        auto = decide(auto, replace(GOOD, ratio=ratio, span_s=span), False)
        if auto.state is State.CONVERGED:
            break
    assert auto.state is State.CONVERGED and results <= 6, results
    assert 0.3 < ratio < 0.6, ratio


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
