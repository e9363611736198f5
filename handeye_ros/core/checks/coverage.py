"""How much of the eye's time the MoCap covers, and with how many gaps.

Real MoCap comes with occlusions (a marker hidden for a second) and with layouts where it sees
the device only part of the time (a room left and re-entered). Nothing is interpolated across a
gap (:mod:`.trajectory`); what that costs shows in the stages' uncertainty, and this says what
the MoCap left: its gaps inside the eye's time, and the part of the eye's time (on the hand's
clock) that falls inside the MoCap's gap-free parts. The eye's time is that of its own gap-free
parts: a recording paused in both streams (two takes in one file) leaves nothing uncovered.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..arrays import Floats
from ..document import CoverageDoc
from ..trajectory import Trajectory, gap_free_parts

#: The notes name the coverage when the MoCap misses more than this fraction of the eye's time,
#: or has a gap this long (s): a few dropped frames cost nothing worth a sentence (the numbers
#: are in the result's coverage section whatever they are).
NOTE_FRACTION = 0.95
NOTE_GAP_S = 0.5


@dataclass(frozen=True)
class Coverage:
    """The MoCap's coverage of the eye's time.

    gaps: gaps of the hand inside the eye's time; gap_s: their length inside it [s];
    longest_gap_s; eye_s: the eye's time, the length of its gap-free parts [s]; covered_s: the
    part of it inside the hand's gap-free parts [s]; fraction: covered_s / eye_s.
    """

    gaps: int
    gap_s: float
    longest_gap_s: float
    eye_s: float
    covered_s: float

    @property
    def fraction(self) -> float:
        return self.covered_s / self.eye_s if self.eye_s > 0 else 0.0

    def to_dict(self) -> CoverageDoc:
        return {
            'hand_gaps': self.gaps,
            'hand_gap_s': self.gap_s,
            'longest_hand_gap_s': self.longest_gap_s,
            'eye_s': self.eye_s,
            'covered_s': self.covered_s,
            'fraction': self.fraction,
        }

    def note(self) -> str:
        """One sentence for the result's notes ('' when the MoCap covers the eye all but a few
        frames: NOTE_FRACTION, NOTE_GAP_S)."""
        if self.fraction >= NOTE_FRACTION and self.longest_gap_s < NOTE_GAP_S:
            return ''
        return (
            f"the MoCap covers {self.fraction:.0%} of the eye's {self.eye_s:.0f} s "
            f'({self.covered_s:.1f} s), with {self.gaps} gap(s) inside it '
            f'({self.gap_s:.1f} s, the longest {self.longest_gap_s:.2f} s); nothing is '
            'interpolated across a gap, and the uncertainty counts only what is covered'
        )


def mocap_coverage(hand: Trajectory, eye: Trajectory, time_offset_s: float) -> Coverage:
    """Coverage of ``eye``'s gap-free parts (its stamps minus ``time_offset_s`` on the hand's
    clock) by ``hand``'s (:meth:`Trajectory.interval_ok`)."""
    origin = int(hand.t_ns[0])
    th = hand.seconds(origin)
    te = eye.seconds(origin) - time_offset_s
    eye_parts = _spans(te, gap_free_parts(eye))
    inside = _inside(eye_parts)
    hand_parts = _spans(th, gap_free_parts(hand))
    covered = inside(hand_parts)
    # between two consecutive gap-free parts lies one gap (or break) of the hand
    lengths = inside(np.column_stack((hand_parts[:-1, 1], hand_parts[1:, 0])))
    lengths = lengths[lengths > 0]
    return Coverage(
        int(lengths.size),
        float(lengths.sum()),
        float(lengths.max()) if lengths.size else 0.0,
        float(np.sum(eye_parts[:, 1] - eye_parts[:, 0])),
        float(covered.sum()),
    )


def _spans(t: Floats, parts: list[tuple[int, int]]) -> Floats:
    """(K, 2) first and last stamp [s] of each part (start, stop) of a stream."""
    return np.array([(t[a], t[b - 1]) for a, b in parts], float).reshape(-1, 2)


def _inside(parts: Floats) -> Callable[[Floats], Floats]:
    """How much of each interval (rows of an (M, 2) array, s) lies inside the disjoint, sorted
    ``parts`` (K, 2): the parts' length below x, taken at both ends of the interval."""
    length = parts[:, 1] - parts[:, 0]
    before = np.concatenate(([0.0], np.cumsum(length)))

    def below(x: Floats) -> Floats:
        k = np.searchsorted(parts[:, 0], x, side='right')
        last = np.maximum(k - 1, 0)
        part = np.clip(x - parts[last, 0], 0.0, length[last]) * (k > 0)
        out: Floats = before[last] + part
        return out

    def inside(iv: Floats) -> Floats:
        if not len(parts):
            return np.zeros(len(iv))
        out: Floats = below(iv[:, 1]) - below(iv[:, 0])
        return out

    return inside
