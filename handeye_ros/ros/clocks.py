"""Whether the two streams' clocks moved against each other while the node records (a clock that
jumped, or a stream whose every message is refused for going back in time), from each stream's
newest accepted stamp against when it came (:class:`Arrivals`).

Stamps run at the pace of their arrivals times the replay's pace: 1 live, a bag's rate in a
replay (8 for ``--rate 8``). The arrivals of the two streams jitter against each other by the
executor's and DDS's lag; in the stamps that jitter is multiplied by the pace, so the clocks are
compared at the pace the snapshots show (:func:`replay_pace`), and a move counts beyond JUMP_S
(or six of the streams' periods) times the pace: a replay 8 times faster than real time cannot
tell a 1-s jump from a quarter-second lag of one stream's delivery.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The two streams' stamps may move against their arrivals by this much (s, at least, at the
#: pace of real time) before a clock is said to have jumped: their periods and the executor's
#: lag jitter them.
JUMP_S = 1.0
#: The clocks are compared by the median of this many snapshots, first ones against last ones:
#: a delivery held up by a busy machine moves one snapshot's arrivals, a jump moves every one
#: after it.
JUMP_SNAPSHOTS = 3


@dataclass(frozen=True)
class Arrivals:
    """One snapshot: each stream's newest accepted stamp (int64 ns, its own clock) and when the
    pose that moved it came (s, one clock for both: DDS's reception times, else the node's)."""

    hand_ns: int
    eye_ns: int
    hand_s: float
    eye_s: float


def clocks_apart(snap: Arrivals, pace: float = 1.0) -> float:
    """How far (s) the device's clock is ahead of the MoCap's, as far as arrivals tell, with
    stamps running ``pace`` times as fast as arrivals. Changes when a clock jumps, or when a
    stream's every message is refused for going back (a clock that went back); not when a
    stream pauses, ends before the other one, or loses its poses (a MoCap dropout): its stamp
    and its arrival stop together."""
    return (snap.eye_ns - snap.hand_ns) * 1e-9 - pace * (snap.eye_s - snap.hand_s)


def replay_pace(a: Arrivals, b: Arrivals) -> float:
    """Seconds of stamps per second of arrivals from snapshot ``a`` to ``b``: the faster
    stream's (a stream whose messages are refused does not move its stamp); 1 when neither
    moved."""
    paces = [
        (b_ns - a_ns) * 1e-9 / (b_s - a_s)
        for a_ns, b_ns, a_s, b_s in (
            (a.hand_ns, b.hand_ns, a.hand_s, b.hand_s),
            (a.eye_ns, b.eye_ns, a.eye_s, b.eye_s),
        )
        if b_s > a_s
    ]
    fastest = max(paces, default=0.0)
    return fastest if fastest > 0.0 else 1.0


class ClockWatch:
    """The snapshots taken while both streams flow: the first JUMP_SNAPSHOTS and the last
    ones, until :meth:`reset` (the buffers hold both clocks' times)."""

    def __init__(self) -> None:
        self._first: list[Arrivals] = []
        self._last: list[Arrivals] = []

    def reset(self) -> None:
        self._first, self._last = [], []

    def moved(self, snap: Arrivals, period_s: float) -> float | None:
        """With ``snap`` taken: how far (s) the device's clock moved against the MoCap's from
        the first snapshots to the last ones (medians, at the replay's pace) when that is a
        jump (beyond JUMP_S or six periods of the slower stream, ``period_s``, times the pace),
        else None."""
        if len(self._first) < JUMP_SNAPSHOTS:
            self._first.append(snap)
            return None
        self._last = [*self._last[1 - JUMP_SNAPSHOTS :], snap]
        if len(self._last) < JUMP_SNAPSHOTS:
            return None
        pace = replay_pace(self._first[0], self._last[-1])
        before = np.median([clocks_apart(s, pace) for s in self._first])
        after = np.median([clocks_apart(s, pace) for s in self._last])
        moved = float(after - before)
        return moved if abs(moved) > max(JUMP_S, 6.0 * period_s) * max(1.0, pace) else None


def jump_advice(moved_s: float) -> str:
    """What the status says of a move of the device's clock against the MoCap's (s)."""
    return (
        f"the device's stamps moved {moved_s:+.1f} s against the MoCap's: a clock jumped, or "
        "one stream's messages are refused (see the log); call ~/reset to start over"
    )
