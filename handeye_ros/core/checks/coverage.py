"""How much of the eye's time the MoCap covers, and with how many gaps.

Real MoCap comes with occlusions (a marker hidden for a second) and with layouts where it sees
the device only part of the time (a room left and re-entered). Nothing is interpolated across a
gap (:mod:`.trajectory`); what that costs shows in the stages' uncertainty, and this says what
the MoCap left: its gaps inside the eye's span, and the part of the eye's span (on the hand's
clock) that falls inside the MoCap's gap-free parts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..document import CoverageDoc
from ..trajectory import Trajectory, gap_free_parts

#: The notes name the coverage when the MoCap misses more than this fraction of the eye's span,
#: or has a gap this long (s): a few dropped frames cost nothing worth a sentence (the numbers
#: are in the result's coverage section whatever they are).
NOTE_FRACTION = 0.95
NOTE_GAP_S = 0.5


@dataclass(frozen=True)
class Coverage:
    """The MoCap's coverage of the eye's span.

    gaps: gaps of the hand inside the eye's span; gap_s: their total length [s]; longest_gap_s;
    eye_span_s: the eye's first to last pose [s]; covered_s: the part of it inside the hand's
    gap-free parts [s]; fraction: covered_s / eye_span_s.
    """

    gaps: int
    gap_s: float
    longest_gap_s: float
    eye_span_s: float
    covered_s: float

    @property
    def fraction(self) -> float:
        return self.covered_s / self.eye_span_s if self.eye_span_s > 0 else 0.0

    def to_dict(self) -> CoverageDoc:
        return {
            'hand_gaps': self.gaps,
            'hand_gap_s': self.gap_s,
            'longest_hand_gap_s': self.longest_gap_s,
            'eye_span_s': self.eye_span_s,
            'covered_s': self.covered_s,
            'fraction': self.fraction,
        }

    def note(self) -> str:
        """One sentence for the result's notes ('' when the MoCap covers the eye all but a few
        frames: NOTE_FRACTION, NOTE_GAP_S)."""
        if self.fraction >= NOTE_FRACTION and self.longest_gap_s < NOTE_GAP_S:
            return ''
        return (
            f"the MoCap covers {self.fraction:.0%} of the eye's {self.eye_span_s:.0f} s "
            f'({self.covered_s:.1f} s), with {self.gaps} gap(s) inside it '
            f'({self.gap_s:.1f} s, the longest {self.longest_gap_s:.2f} s); nothing is '
            'interpolated across a gap, and the uncertainty counts only what is covered'
        )


def mocap_coverage(hand: Trajectory, eye: Trajectory, time_offset_s: float) -> Coverage:
    """Coverage of ``eye`` (its stamps minus ``time_offset_s`` on the hand's clock) by
    ``hand``'s gap-free parts (:meth:`Trajectory.interval_ok`)."""
    origin = int(hand.t_ns[0])
    th = hand.seconds(origin)
    te = eye.seconds(origin) - time_offset_s
    lo, hi = float(te[0]), float(te[-1])
    ok = hand.interval_ok()
    covered = sum(max(0.0, min(hi, th[b - 1]) - max(lo, th[a])) for a, b in gap_free_parts(hand))
    gap = np.flatnonzero(~ok)
    start, stop = th[gap], th[gap + 1]
    inside = (stop > lo) & (start < hi)
    lengths = np.minimum(stop[inside], hi) - np.maximum(start[inside], lo)
    return Coverage(
        int(inside.sum()),
        float(lengths.sum()),
        float(lengths.max()) if lengths.size else 0.0,
        hi - lo,
        float(covered),
    )
