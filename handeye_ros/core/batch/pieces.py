"""The hand's gap-free parts, each of which gets a spline of its own (stage 3): a spline cannot
bridge a MoCap dropout, and an eye residual with an end in one would compare the VIO with an
invented motion. Also the joint solve's check that the MoCap is dense enough for its knots."""

from __future__ import annotations

import itertools

import numpy as np

from ..errors import BatchError
from ..trajectory import Trajectory, lengths_text

#: Fewest MoCap poses per knot interval the joint solve accepts: with fewer, the control poses
#: outnumber what the MoCap determines and its normal matrix is singular.
MIN_HAND_POSES_PER_KNOT_JOINT = 2.0
#: Most MoCap poses the joint solve takes. Its time and memory grow linearly with them, about
#: 0.2 ms and 10 kB each on one core (calibrate() at noise level 5: 1 min at 1 kHz + 200 Hz
#: 10.5 s and 0.7 GB, 2 min 22.9 s and 1.3 GB, 10 min at 200 Hz + 30 Hz 20.2 s and 1.2 GB):
#: 150 000 is some 30 s and 1.6 GB; 15 min at 1 kHz would be 3 min and 9 GB.
MAX_HAND_POSES_JOINT = 150_000


#: A gap-free part of the MoCap gets a spline of its own when it spans at least this many knot
#: intervals (0.3 s at the default 0.05 s): DT_MARGIN_S at each end leaves eye pairs inside.
MIN_PIECE_KNOTS = 6


def bridged_s(hand: Trajectory, knot_spacing: float, order: int) -> float:
    """Longest hand interval [s] the spline bridges: a gap of the stream's own
    (:meth:`Trajectory.gap_limit_s`) or the span of one spline segment's support."""
    return max(knot_spacing * (order - 1), hand.gap_limit_s())


def hand_pieces(
    hand: Trajectory, eye: Trajectory, time_offset_s: float, knot_spacing: float, order: int
) -> tuple[Trajectory, list[tuple[int, int]], str]:
    """The hand split at every gap the spline cannot bridge (:func:`bridged_s`), as (the hand
    without the parts too short for a spline of their own, the index ranges of the parts kept,
    a note saying what was used). A spline cannot bridge a gap, and eye residuals across one
    would compare the VIO with an invented motion; each gap-free part of at least
    MIN_PIECE_KNOTS knot intervals gets a spline of its own instead, and the shared parameters
    are solved on the eye pairs inside them. Raises BatchError, naming the parts and their
    lengths, when no part is long enough."""
    step = np.diff(hand.t_ns) * 1e-9
    cuts = np.flatnonzero(step > bridged_s(hand, knot_spacing, order))
    if not cuts.size:
        return hand, [(0, len(hand))], ''
    starts = np.concatenate(([0], cuts + 1))
    ends = np.concatenate((cuts + 1, [len(hand)]))
    length = (hand.t_ns[ends - 1] - hand.t_ns[starts]) * 1e-9
    shortest = MIN_PIECE_KNOTS * knot_spacing
    usable = (length >= shortest) & (ends - starts > order)
    k = int(cuts[np.argmax(step[cuts])])
    gaps = (
        f'{hand.name} has {cuts.size} gap(s) the spline (knots every {knot_spacing:g} s) '
        f'cannot bridge (the longest {step[k]:.3f} s, after pose {k})'
    )
    if not usable.any():
        raise BatchError(
            f'{gaps}, and none of its {starts.size} gap-free parts is long enough for a '
            f'spline of its own ({shortest:g} s): they last {lengths_text(length)}'
        )
    te = eye.t_ns - np.int64(round(time_offset_s * 1e9))
    covered = sum(
        int(np.sum((te >= hand.t_ns[a]) & (te <= hand.t_ns[b - 1])))
        for a, b in zip(starts[usable], ends[usable], strict=True)
    )
    total = int(np.sum((te >= hand.t_ns[0]) & (te <= hand.t_ns[-1])))
    note = (
        f'{gaps}: the batch stage fitted one spline to each of its {int(usable.sum())} '
        f'gap-free parts of at least {shortest:g} s ({lengths_text(length[usable])}), which cover '
        f'{covered} of the {total} eye poses in its span'
    )
    if not usable.all():
        note += (
            f'; {int((~usable).sum())} shorter part(s) left out ({lengths_text(length[~usable])})'
        )
    keep = np.concatenate(
        [np.arange(a, b) for a, b in zip(starts[usable], ends[usable], strict=True)]
    )
    sizes = (ends - starts)[usable]
    bounds = np.concatenate(([0], np.cumsum(sizes)))
    spans = [(int(a), int(b)) for a, b in itertools.pairwise(bounds)]
    return hand.select(keep), spans, note


def check_hand_rate(hand: Trajectory, knot_spacing: float, joint: bool) -> None:
    """Refuse a MoCap stream the joint solve cannot fit a spline to: fewer MoCap poses per
    knot interval than it needs (the gaps are :func:`hand_pieces`')."""
    step = np.diff(hand.t_ns) * 1e-9
    period = float(np.median(step))
    if joint and knot_spacing < MIN_HAND_POSES_PER_KNOT_JOINT * period:
        raise BatchError(
            f'the joint solve needs at least {MIN_HAND_POSES_PER_KNOT_JOINT:g} '
            f'MoCap poses per knot interval; {hand.name} at '
            f'{1.0 / period:.3g} Hz gives {knot_spacing / period:.2g} with knots '
            f'every {knot_spacing:g} s: leave batch_joint off (the default solve '
            f'holds the spline to the MoCap) or set knot_spacing >= '
            f'{MIN_HAND_POSES_PER_KNOT_JOINT * period:.3g} s'
        )


def check_joint_size(hand: Trajectory) -> None:
    """Refuse, before any stage runs, a MoCap stream too long for the joint solve."""
    if len(hand) > MAX_HAND_POSES_JOINT:
        span = (hand.t_ns[-1] - hand.t_ns[0]) * 1e-9 / 60.0
        raise BatchError(
            f'the joint solve (batch_joint) takes at most {MAX_HAND_POSES_JOINT:,} MoCap poses '
            f'(2.5 min at 1 kHz, 12.5 min at 200 Hz: some 30 s and 1.6 GB); {hand.name} has '
            f'{len(hand):,} ({span:.1f} min): leave batch_joint off (the default solve holds '
            'the spline to the MoCap and takes hours), or calibrate a part of the recording'
        )
