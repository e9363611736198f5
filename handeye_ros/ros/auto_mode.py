"""The calibrator's auto mode (``auto_calibrate``): which of the status's calibrations are
published, as a pure function of the latest one and the previous decision (:func:`decide`).

The status calibrates the buffers as they grow (:mod:`.status`); with auto mode a result that is
``good`` for the purpose is published when it is the first, improves on the last published one (by
more than IMPROVEMENT, below), has GROWTH times its data, or is the first converged one (the status
checks a good result again as the buffers grow, and those checks are not all news). A result is
measured by its purpose's rule on precision: its *ratio* to that rule's line
(:attr:`~handeye_ros.core.checks.readiness.Outcome.ratio`; for an evaluation the largest share of a
figure that is the calibration's 1-sigma over the 5 % allowed, for the extrinsic the largest
1-sigma over its ``precision_*`` target; at most 1 for a ``good`` result). Once a ``good`` result
with GROWTH times the last published one's data improves on its ratio by no more than IMPROVEMENT,
and is settled (not near its line, as READY asks:
:attr:`~handeye_ros.core.checks.readiness.Outcome.settled`), more of the same motion no longer
matters to the purpose: auto mode has *converged* (and stays so while the results that follow
improve no more). A result that is not ``good`` is not published: while more recording is its
remedy (its precision alone) auto mode goes on; otherwise it has *stalled* (the motion, or the
recording, must change). Once the buffers are full their span grows no more, and no later result
would see more data: *done*. Converged, stalled or done, a later ``good`` result (richer motion) is
still published.
``~/calibrate`` works at any time, and its result is always published.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

from ..core.checks.readiness import Outcome

#: Converged when a good result's ratio to its line shrinks by no more than this (of the line):
#: white noise shrinks the ratio by 18 % at each growth of the buffers by half for ever
#: (1 - 1/sqrt(1.5)), and this ends it once the ratio is about half the line, where more
#: recording no longer matters to the verdict; sigmas that stop at a floor, as errors that are
#: not white make them do, end it sooner.
IMPROVEMENT = 0.1
#: Data worth a new look: a good result with this many times the published one's span is
#: published however little it improved (its figures rest on that much more of the recording),
#: and convergence is judged over such a growth (IMPROVEMENT's measure): the status calibrates
#: the buffers every second or so, over which no result improves by much.
GROWTH = 1.5


class State(Enum):
    """Where auto mode stands."""

    OFF = 'off'
    WAITING = 'waiting'
    IMPROVING = 'improving'
    CONVERGED = 'converged'
    STALLED = 'stalled'
    DONE = 'done'


@dataclass(frozen=True)
class Auto:
    """A decision: the state, the ratio to its line and the span [s] of the result auto mode
    last published (inf and 0: none), whether the result just decided on is published, and the
    reason a stalled result gave."""

    state: State
    published: float = math.inf
    publish: bool = False
    why: str = ''
    published_span_s: float = 0.0

    @classmethod
    def start(cls, on: bool) -> Auto:
        """Before any result of a recording."""
        return cls(State.WAITING if on else State.OFF)


def decide(previous: Auto, latest: Outcome, full: bool) -> Auto:
    """What auto mode does with ``latest`` (a calibration of the buffers), ``full``: the
    buffers it calibrated were full (their span grows no more)."""
    if previous.state == State.OFF:
        return previous
    kept = previous.published_span_s
    if not latest.good:
        if not latest.recording_helps:
            why = latest.held or latest.label
            return Auto(State.STALLED, previous.published, False, why, kept)
        return Auto(State.DONE if full else State.WAITING, previous.published, False, '', kept)
    old, ratio = previous.published, latest.ratio
    if not math.isfinite(ratio):  # no figure to judge: no measure of improvement
        ratio = math.inf
    improved = not math.isfinite(old) or old - ratio > IMPROVEMENT
    grown = latest.span_s >= GROWTH * kept
    # near its line (not settled) a good result is no place to stop: the next may be beyond it
    converged = latest.settled and not improved and (grown or previous.state == State.CONVERGED)
    state = State.CONVERGED if converged else State.DONE if full else State.IMPROVING
    first = converged and previous.state != State.CONVERGED
    news = improved or first or grown
    if not news:
        return Auto(state, old, False, '', kept)
    return Auto(state, ratio, True, '', latest.span_s)


def filled(previous: Auto) -> Auto:
    """The buffers became full with no result since: nothing more to wait for."""
    if previous.state in (State.WAITING, State.IMPROVING):
        return Auto(State.DONE, previous.published, False, previous.why)
    return previous


def said(auto: Auto) -> str:
    """Auto mode's state in the user's words (the status's ``auto_calibrate`` value)."""
    return {
        State.OFF: 'off',
        State.WAITING: 'waiting for a good result: calibrating as the buffers grow',
        State.IMPROVING: (
            'published a good result; one that improves on it, or has half as much data '
            'again, is published too'
        ),
        State.CONVERGED: (
            f'converged: more of the same motion no longer improves the result by '
            f'{IMPROVEMENT:.0%} of what its purpose allows; a later good result is still '
            'published'
        ),
        State.STALLED: (
            f'stalled: more of the same recording does not remedy the latest result '
            f'({auto.why}); change what it says'
        ),
        State.DONE: (
            'done: the buffers are full (buffer_duration, buffer_size), so later results '
            'would not see more data; ~/calibrate still works'
        ),
    }[auto.state]
