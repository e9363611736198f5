"""The hand's gap-free parts, each of which gets a spline of its own (stage 3): a spline cannot
bridge a MoCap dropout, and an eye residual with an end in one would compare the VIO with an
invented motion."""

from __future__ import annotations

import itertools

import numpy as np

from ..errors import BatchError
from ..trajectory import Trajectory, lengths_text

#: A gap-free part of the MoCap gets a spline of its own when it spans at least this many knot
#: intervals (0.32 s at the default 0.0527 s): DT_MARGIN_S at each end leaves eye pairs inside.
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
