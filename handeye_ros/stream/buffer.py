"""A bounded, preallocated buffer of one pose stream, with the bookkeeping a live node needs.

Messages are validated one by one as they arrive (a bad one is rejected and counted, never
raised), stored in a ring of fixed capacity, and the oldest are dropped (and counted) when the
buffer is full or spans more than its maximum duration. :meth:`PoseBuffer.trajectory` copies
the content out in order for the calibration, so the stream can keep flowing meanwhile.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from ..core.arrays import Floats, Stamps
from ..core.trajectory import QUATERNION_NORM_TOLERANCE, Trajectory
from .convert import StampedPose

#: Reasons a message is rejected (keys of BufferStats.rejected): zero_stamp, header.stamp
#: left unset; stamp_repeated, the previous pose's stamp again; stamp_not_increasing, a stamp
#: before the previous pose's.
REJECT_REASONS = (
    'non_finite',
    'zero_quaternion',
    'non_unit_quaternion',
    'zero_stamp',
    'stamp_repeated',
    'stamp_not_increasing',
    'not_in_message',
)


@dataclass(frozen=True)
class BufferStats:
    """Counters of one stream (for diagnostics and tests).

    received: messages offered; stored: currently held; dropped: oldest discarded to respect
    the capacity or duration; rejected: per reason; span_s: buffered time span; rate_hz:
    median rate of the newest held poses (0 with fewer than 2); last_stamp_ns: newest held
    stamp.
    """

    received: int
    stored: int
    dropped: int
    rejected: dict[str, int]
    span_s: float
    rate_hz: float
    last_stamp_ns: int | None


#: :meth:`PoseBuffer.stats` takes the rate from this many of the newest intervals.
RATE_WINDOW = 10_000


class PoseBuffer:
    """Ring buffer of stamped poses (int64 ns, position, x y z w quaternion). Thread-safe."""

    def __init__(self, name: str, capacity: int = 1_000_000, max_duration_s: float = 3600.0):
        if capacity < 2:
            raise ValueError(f'{name}: buffer capacity must be at least 2, got {capacity}')
        if not max_duration_s > 0.0:
            raise ValueError(f'{name}: buffer duration must be positive, got {max_duration_s}')
        self.name = name
        self.capacity = int(capacity)
        self.max_duration_ns = int(max_duration_s * 1e9)
        # written through once, so that the memory is the process's from the start: np.empty
        # only reserves it, and the ring would page it in slot by slot, an RSS that grows by
        # 64 bytes a pose until the ring first wraps (it looked like a leak in the node)
        self._t = np.zeros(self.capacity, dtype=np.int64)
        self._pq = np.zeros((self.capacity, 7))
        self._t.fill(0)
        self._pq.fill(0.0)
        self._lock = threading.Lock()
        self.clear()

    def clear(self) -> None:
        """Forget every pose and reset the counters."""
        with self._lock:
            self._head = 0  # index of the oldest pose
            self._count = 0
            self._last: int | None = None
            self.received = 0
            #: poses that moved the stream's clock: stored, or refused as going back in time
            #: (a message without a pose, or with NaN, is no tick: a lost marker's)
            self.ticked = 0
            self.dropped = 0
            self.rejected = dict.fromkeys(REJECT_REASONS, 0)

    def __len__(self) -> int:
        return self._count

    @property
    def span_s(self) -> float:
        """The buffered time span [s], from the oldest and the newest stamp (no copy: cheap
        enough for every tick of the node's timers)."""
        with self._lock:
            return self._span_s()

    def _span_s(self) -> float:
        """:attr:`span_s`, under the lock. ``_last`` is the newest stored stamp (a rejected
        message does not change it)."""
        if self._count < 2 or self._last is None:
            return 0.0
        return (self._last - int(self._t[self._head])) * 1e-9

    def add(self, pose: StampedPose) -> str | None:
        """Store one pose (t_ns, x, y, z, qx, qy, qz, qw); returns None, or the reason it was
        rejected."""
        t_ns = pose[0]
        with self._lock:
            self.received += 1
            reason = self._check(pose)
            if reason is not None:
                self.rejected[reason] += 1
                self.ticked += reason == 'stamp_not_increasing'
                return reason
            self.ticked += 1
            if self._count == self.capacity:
                self._drop(1)
            tail = (self._head + self._count) % self.capacity
            self._t[tail] = t_ns
            self._pq[tail] = pose[1:]
            self._count += 1
            self._last = t_ns
            # keep the span within max_duration: drop from the oldest end
            oldest_allowed = t_ns - self.max_duration_ns
            n_old = 0
            while (
                n_old < self._count - 1
                and self._t[(self._head + n_old) % self.capacity] < oldest_allowed
            ):
                n_old += 1
            if n_old:
                self._drop(n_old)
            return None

    def reject(self, reason: str) -> str:
        """Count a message that held no pose for this stream (e.g. a rigid body not tracked in
        that frame); returns the reason."""
        with self._lock:
            self.received += 1
            self.rejected[reason] += 1
        return reason

    def _check(self, pose: StampedPose) -> str | None:
        t_ns, x, y, z, qx, qy, qz, qw = pose
        # one sum is finite iff every term is (NaN and inf propagate): this runs per message
        if not math.isfinite(x + y + z + qx + qy + qz + qw):
            return 'non_finite'
        norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        if norm < 1e-9:
            return 'zero_quaternion'
        if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
            return 'non_unit_quaternion'
        if t_ns == 0:
            return 'zero_stamp'
        if self._last is not None and t_ns <= self._last:
            return 'stamp_repeated' if t_ns == self._last else 'stamp_not_increasing'
        return None

    def _drop(self, n: int) -> None:
        self._head = (self._head + n) % self.capacity
        self._count -= n
        self.dropped += n

    def _ordered(self) -> tuple[Stamps, Floats]:
        idx = (self._head + np.arange(self._count)) % self.capacity
        return self._t[idx], self._pq[idx]

    def trajectory(self) -> Trajectory:
        """A validated copy of the buffered poses, oldest first (raises InputError when the
        buffer holds fewer than 2 poses)."""
        with self._lock:
            t, pq = self._ordered()
        return Trajectory.from_arrays(t, pq[:, :3], pq[:, 3:], name=self.name)

    def since(self, t_ns: int) -> Trajectory:
        """:meth:`trajectory` of the poses from the newest one at or before ``t_ns`` on (from
        the oldest when none is): the tail a status reads, without copying the whole ring."""
        with self._lock:
            n, head = self._count, self._head
            first = min(n, self.capacity - head)  # the ring's two runs, oldest first
            j = int(np.searchsorted(self._t[head : head + first], t_ns, side='right'))
            if j == first:
                j += int(np.searchsorted(self._t[: n - first], t_ns, side='right'))
            idx = (head + np.arange(max(j - 1, 0), n)) % self.capacity
            t, pq = self._t[idx], self._pq[idx]
        return Trajectory.from_arrays(t, pq[:, :3], pq[:, 3:], name=self.name)

    @property
    def newest_ns(self) -> int | None:
        """The newest buffered stamp, or None."""
        with self._lock:
            return self._last if self._count else None

    @property
    def oldest_ns(self) -> int | None:
        """The oldest buffered stamp, or None."""
        with self._lock:
            return int(self._t[self._head]) if self._count else None

    def stats(self) -> BufferStats:
        """Current counters. The rate is the median over the newest RATE_WINDOW intervals:
        the rate now, at a bounded cost (the node asks every second; copying half an hour of
        1 kHz each time held the lock, and ingest, for a tenth of a second)."""
        with self._lock:
            n = self._count
            if n >= 2:
                k = min(n, RATE_WINDOW + 1)
                newest = (self._head + n - k + np.arange(k)) % self.capacity
                rate = 1e9 / float(np.median(np.diff(self._t[newest])))
            else:
                rate = 0.0
            return BufferStats(
                self.received,
                n,
                self.dropped,
                dict(self.rejected),
                self._span_s(),
                rate,
                self._last,
            )
