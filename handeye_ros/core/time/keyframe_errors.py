"""What stage 1 of a keyframe-only eye (:mod:`.keyframe_only`) says when it cannot answer: too
few keyframe pairs inside the hand, the best offset at the edge of the searched ones, or angles
that agree nowhere; each error names the spans, the offset and what to do."""

from __future__ import annotations

from ..errors import TimeAlignmentError
from ..trajectory import Trajectory


def too_few(
    hand: Trajectory, eye: Trajectory, window: tuple[float, float] | None, need: int
) -> TimeAlignmentError:
    """Fewer than ``need`` keyframe pairs of ``eye`` inside ``hand`` at every searched lag."""
    where = (
        'at any offset'
        if window is None
        else f'at any offset in [{window[0]:+.3f}, {window[1]:+.3f}] s'
    )
    return TimeAlignmentError(
        f'too few keyframe pairs of {eye.name} fall inside {hand.name} {where} (need '
        f'{need}, and half as many as at the best-covered offset; hand covers '
        f'{hand.duration_s:.1f} s, eye {eye.duration_s:.1f} s, eye starts '
        f'{(eye.t_ns[0] - hand.t_ns[0]) * 1e-9:+.3f} s after hand on their own clocks)'
    )


def at_the_edge(offset_s: float, window: tuple[float, float] | None) -> TimeAlignmentError:
    """The angles agree best at the first or last lag searched (``offset_s``, s)."""
    where = 'the edge of the search window' if window else 'the edge of the lags searched'
    return TimeAlignmentError(
        f'the keyframe rotation angles agree best at {where} (at {offset_s:+.3f} s): the time '
        'offset is probably outside it. '
        + (
            'Widen max_time_offset or move time_offset_guess'
            if window
            else 'Do the two recordings show the same motion?'
        )
    )


def no_agreement(
    hand: Trajectory,
    eye: Trajectory,
    offset_s: float,
    agree: float,
    window: tuple[float, float] | None,
) -> TimeAlignmentError:
    """At the best offset the angles correlate at ``agree`` only."""
    where = 'in the search window' if window else 'at any offset'
    return TimeAlignmentError(
        f'the rotation angles of the keyframe pairs of {eye.name} and of {hand.name} do not '
        f'agree {where}: at the best offset ({offset_s:+.3f} s) they correlate at {agree:.2f} '
        '(at the right one, 0.95 or more). '
        + (
            'The time offset is probably outside the window: widen max_time_offset or '
            'move time_offset_guess'
            if window
            else 'Do the two recordings show the same motion?'
        )
    )
