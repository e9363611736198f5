"""A validated, timestamped pose stream.

A :class:`Trajectory` holds N poses ``T_AB(t_k)``: the pose of a moving frame B expressed in a
fixed frame A (``p_xyz`` is the origin of B in A, ``q_xyzw`` rotates B-vectors into A).
Stamps are int64 nanoseconds, exactly as they arrive from files and messages; float seconds are
only made by :meth:`Trajectory.seconds` after subtracting an origin, because 1.7e9 s in float64
keeps no sub-microsecond precision.

Two kinds of interval between consecutive poses must never be bridged by a difference, an
interpolation or a relative pose: a *gap* (longer than :data:`GAP_FACTOR` median periods: the
stream stopped) and a *break* (the stream restarted in another world frame, e.g. a VIO reset:
found by screening and stored in ``breaks``). :meth:`Trajectory.interval_ok` says which
intervals may be used; :meth:`Trajectory.segment_ids` numbers the parts between breaks.

A *keyframe* stream (``keyframes``: what many SLAM systems write, poses 0.05-5 s apart at
irregular stamps; see :func:`is_keyframe_only`) has no gaps: every interval between two of its
poses is a relative pose the estimator stands behind, however long; only its breaks split it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt

from .arrays import Floats, Indices, Mask, Stamps
from .errors import InputError
from .geometry import row_norms

#: An interval longer than this many median sample periods is a gap: nothing is interpolated or
#: differenced across it. 3.5 tolerates two consecutive dropped samples, which still give a fair
#: average.
GAP_FACTOR = 3.5
#: A stream whose median period is longer than this (s), or whose poses lie mostly in gap-free
#: parts shorter than KEYFRAME_PART_S, holds keyframes only: no angular speed can be resampled
#: from it. A part of 2 s holds a back-and-forth of hand-held motion (content from ~0.5 Hz up to
#: a few Hz); a stream of such parts with long gaps between them (recorded in two takes, paused)
#: is continuous however short a share of its span the parts cover.
KEYFRAME_PERIOD_S = 0.2
KEYFRAME_PART_S = 2.0
#: A quaternion whose norm differs from 1 by more than this is refused rather than normalised:
#: text files round to ~6 decimals (deviation ~1e-6); a larger deviation means a wrong column
#: order or corrupted data, and silently normalising it would hide that.
QUATERNION_NORM_TOLERANCE = 1e-2


@dataclass(frozen=True)
class TrajectoryInfo:
    """What a result says of an input stream without holding its poses: its name (file or
    topic), pose count, rate [Hz], span [s] and first and last stamps [ns, its own clock]."""

    source: str
    poses: int
    rate_hz: float
    duration_s: float
    first_stamp_ns: int
    last_stamp_ns: int


@dataclass(frozen=True)
class Trajectory:
    """Poses T_AB(t) of a frame B in a frame A.

    Attributes
    ----------
    t_ns : ndarray, shape (N,), int64
        Strictly increasing stamps in nanoseconds.
    p_xyz : ndarray, shape (N, 3)
        Position of B in A, metres.
    q_xyzw : ndarray, shape (N, 4)
        Unit Hamilton quaternions (x, y, z, w), signs made continuous (q_k . q_k+1 >= 0).
    name : str
        Where the poses came from (a file or topic), used in messages.
    breaks : ndarray of int, shape (B,)
        Indices k such that the interval from pose k to pose k + 1 is a break (a restart of the
        stream's world frame); sorted, unique.
    notes : tuple of str
        What was done to the poses on the way in (repeated stamps dropped, a stamp unit
        assumed, ...), for the result's warnings.
    keyframes : bool
        The stream holds keyframes only: no interval is a gap (see the module docstring).
    quaternion_order : str or None
        The order of the four quaternion numbers in its file, as they were read into
        ``q_xyzw`` ('wxyz' for a EuRoC file, 'xyzw' for a TUM file), for messages that name
        the file's order; None for poses not read from a file (ROS messages, which hold x y z
        w by definition, and arrays).
    """

    t_ns: Stamps
    p_xyz: Floats
    q_xyzw: Floats
    name: str = 'trajectory'
    breaks: Indices = field(default_factory=lambda: np.zeros(0, dtype=int))
    notes: tuple[str, ...] = ()
    keyframes: bool = False
    quaternion_order: str | None = None

    @classmethod
    def from_arrays(
        cls,
        t_ns: Stamps,
        p_xyz: Floats,
        q_xyzw: Floats,
        name: str = 'trajectory',
        min_poses: int = 2,
        notes: tuple[str, ...] = (),
    ) -> Trajectory:
        """Validate raw arrays and build a trajectory.

        Raises :class:`InputError` naming ``name`` and the first offending row for: too few
        poses, non-integer or unsorted or duplicate stamps, NaN/inf, zero or non-unit quaternions.
        Quaternion sign flips between samples are legal (q and -q are one rotation) and are
        removed here so that later interpolation and differencing see a continuous signal.
        """
        t_ns = np.asarray(t_ns)
        p_xyz = np.asarray(p_xyz, dtype=float)
        q_xyzw = np.asarray(q_xyzw, dtype=float)
        n = t_ns.shape[0] if t_ns.ndim == 1 else -1
        if n < 0 or p_xyz.shape != (n, 3) or q_xyzw.shape != (n, 4):
            msg = (
                f'{name}: expected stamps (N,), positions (N, 3) and quaternions (N, 4), '
                f'got {t_ns.shape}, {p_xyz.shape}, {q_xyzw.shape}'
            )
            raise InputError(msg)
        if n < min_poses:
            msg = f'{name}: holds {n} pose(s); at least {min_poses} are needed'
            raise InputError(msg)
        if not np.issubdtype(t_ns.dtype, np.integer):
            msg = f'{name}: stamps must be integer nanoseconds, got dtype {t_ns.dtype}'
            raise InputError(msg)
        t_ns = t_ns.astype(np.int64)
        _check_finite(name, p_xyz, 'position')
        _check_finite(name, q_xyzw, 'quaternion')
        steps = np.diff(t_ns)
        bad = np.flatnonzero(steps <= 0)
        if bad.size:
            k = int(bad[0])
            kind = 'duplicate' if steps[k] == 0 else 'unsorted (going backwards)'
            msg = (
                f'{name}: {bad.size} {kind} stamp(s); first at pose {k + 1} (from 0): '
                f'{t_ns[k]} ns then {t_ns[k + 1]} ns. Stamps must strictly increase'
            )
            raise InputError(msg)
        norms = row_norms(q_xyzw)
        bad = np.flatnonzero(np.abs(norms - 1.0) > QUATERNION_NORM_TOLERANCE)
        if bad.size:
            k = int(bad[0])
            what = 'zero' if norms[k] < 1e-9 else f'non-unit (norm {norms[k]:.6g})'
            msg = (
                f'{name}: {bad.size} quaternion(s) not of unit norm; first at pose {k} '
                '(from 0): '
                f'{what} quaternion {q_xyzw[k].tolist()} (order x y z w)'
            )
            raise InputError(msg)
        q_xyzw = q_xyzw / norms[:, None]
        return cls(t_ns, p_xyz, make_continuous(q_xyzw), name, notes=tuple(notes))

    def __len__(self) -> int:
        return int(self.t_ns.shape[0])

    def seconds(self, origin_ns: int) -> Floats:
        """Stamps in float seconds relative to ``origin_ns`` (subtraction done in int64)."""
        return (self.t_ns - np.int64(origin_ns)).astype(float) * 1e-9

    @property
    def duration_s(self) -> float:
        """Time spanned by the stamps, seconds."""
        return float(self.t_ns[-1] - self.t_ns[0]) * 1e-9

    @property
    def rate_hz(self) -> float:
        """Median sampling rate, Hz (robust to gaps and dropped samples)."""
        return 1e9 / float(np.median(np.diff(self.t_ns)))

    def info(self) -> TrajectoryInfo:
        """The stream described without its poses (:class:`TrajectoryInfo`)."""
        return TrajectoryInfo(
            self.name,
            len(self),
            self.rate_hz,
            self.duration_s,
            int(self.t_ns[0]),
            int(self.t_ns[-1]),
        )

    def select(self, mask_or_index: Mask | Indices | slice) -> Trajectory:
        """A sub-trajectory (rows kept in order; no re-validation needed).

        A break survives when both of its poses are kept; when poses around a break are
        dropped, the break moves to the interval that now spans it.
        """
        idx = np.arange(len(self))[mask_or_index]
        breaks = np.zeros(0, dtype=int)
        if self.breaks.size and idx.size:
            # kept pose m closes a break if some break lies between the previous kept pose and it
            breaks = np.flatnonzero(np.diff(self.segment_ids()[idx]) > 0)
        return replace(
            self,
            t_ns=self.t_ns[idx],
            p_xyz=self.p_xyz[idx],
            q_xyzw=self.q_xyzw[idx],
            breaks=breaks,
        )

    def with_breaks(self, breaks: Indices) -> Trajectory:
        """The same poses with these intervals (index of their first pose) marked as breaks,
        in addition to the existing ones."""
        b = np.union1d(self.breaks, np.asarray(breaks, dtype=int)).astype(int)
        return replace(self, breaks=b[(b >= 0) & (b < len(self) - 1)])

    def with_notes(self, *notes: str) -> Trajectory:
        """The same poses with more notes."""
        return replace(self, notes=self.notes + tuple(notes))

    def shifted(self, delta_ns: int) -> Trajectory:
        """The same poses with every stamp moved by ``delta_ns`` (int64 ns, exact)."""
        return replace(self, t_ns=self.t_ns + np.int64(delta_ns))

    def scaled(self, factor: float) -> Trajectory:
        """The same poses with every position multiplied by ``factor`` (an eye's scale)."""
        return replace(self, p_xyz=self.p_xyz * factor)

    def gap_limit_s(self) -> float:
        """Longest interval that is not a gap [s]: GAP_FACTOR median periods."""
        return GAP_FACTOR * float(np.median(np.diff(self.t_ns))) * 1e-9

    def interval_ok(self) -> Mask:
        """(N - 1,) bool: intervals that are neither a gap nor a break (see module docstring)."""
        step = np.diff(self.t_ns)
        ok = (
            np.ones(step.size, bool)
            if self.keyframes
            else step <= GAP_FACTOR * float(np.median(step))
        )
        ok[self.breaks] = False
        return ok

    def segment_ids(self) -> Indices:
        """(N,) int: 0 for the poses before the first break, 1 after it, ..."""
        seg = np.zeros(len(self), dtype=int)
        seg[self.breaks + 1] = 1
        return np.cumsum(seg)


def is_keyframe_only(traj: Trajectory) -> bool:
    """Whether a stream holds keyframes only (:data:`KEYFRAME_PERIOD_S`,
    :data:`KEYFRAME_PART_S`), from its stamps."""
    step = np.diff(traj.t_ns) * 1e-9
    if step.size < 2:
        return False
    median = float(np.median(step))
    dense = step <= GAP_FACTOR * median
    part = np.cumsum(~dense)[dense]
    span = np.bincount(part, weights=step[dense])
    poses = np.bincount(part)
    return median > KEYFRAME_PERIOD_S or poses[span >= KEYFRAME_PART_S].sum() < 0.5 * poses.sum()


def quaternion_columns(order: str) -> list[int]:
    """Where, in a source's quaternion ``order`` (such as 'wxyz'), x, y, z and w stand."""
    return [order.index(c) for c in 'xyzw']


def gap_free_parts(traj: Trajectory) -> list[tuple[int, int]]:
    """(start, stop) index ranges of the parts of a stream between its gaps and breaks."""
    return segment_spans(np.concatenate(([0], np.cumsum(~traj.interval_ok()))))


def lengths_text(seconds: npt.ArrayLike) -> str:
    """Part lengths for a message: each of a few, else their range and total."""
    seconds = np.asarray(seconds, float)
    if seconds.size <= 4:
        return ', '.join(f'{v:.2f} s' for v in seconds)
    return f'{seconds.min():.2f} to {seconds.max():.2f} s, {seconds.sum():.1f} s in all'


def segment_spans(labels: Indices) -> list[tuple[int, int]]:
    """(start, stop) index ranges of the runs of equal labels in a non-decreasing label array
    (the segments of :meth:`Trajectory.segment_ids`, or of pose pairs)."""
    starts = np.flatnonzero(np.diff(labels, prepend=labels[:1] - 1))
    stops = np.append(starts[1:], labels.size)
    return [(int(a), int(b)) for a, b in zip(starts, stops, strict=True)]


def make_continuous(q_xyzw: Floats) -> Floats:
    """Flip quaternion signs so that consecutive quaternions have a non-negative dot product.

    Parameters
    ----------
    q_xyzw : ndarray, shape (N, 4)

    Returns
    -------
    ndarray, shape (N, 4)
        Same rotations; the sign of row k is the product of the flips up to k (vectorised).
    """
    dots = np.einsum('ij,ij->i', q_xyzw[1:], q_xyzw[:-1])
    if not (dots < 0.0).any():  # continuous already (no copy of millions of rows)
        return q_xyzw
    flips = np.concatenate(([1.0], np.cumprod(np.where(dots < 0.0, -1.0, 1.0))))
    out: Floats = q_xyzw * flips[:, None]
    return out


def _check_finite(name: str, values: Floats, what: str) -> None:
    if np.isfinite(values).all():  # the usual case, at a tenth of the time of the row test
        return
    bad = np.flatnonzero(~np.isfinite(values).all(axis=1))
    if bad.size:
        k = int(bad[0])
        msg = (
            f'{name}: {bad.size} pose(s) with NaN or inf in the {what}; first at pose {k} '
            '(from 0): '
            f'{values[k].tolist()}'
        )
        raise InputError(msg)
