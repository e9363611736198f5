"""A bounded excerpt of a recording on which the self-check judges a candidate offset, so that
examining a candidate costs the same on a minute and on an hour.

A wrong offset minutes away is ruled out by a few hundred motions as surely as by all of them.
At a candidate offset, stage 2 therefore runs on :data:`WINDOWS`
windows of the eye, spread evenly over the poses the hand covers at that offset and together
long enough for some :data:`EXCERPT_MOTIONS` of its keyframe motions (:func:`excerpt_share`; a
slow motion needs longer windows than a fast one), with the hand around each window. The windows are laid end to end, each moved by a shift of its own (the
same for the hand and the eye: the offset between them is kept), with :data:`GAP_S` of no poses
between them (the hand's interpolation and the angular speeds stop there) and a break of the
eye at each join (no motion spans one). The candidates' motions for eq. 9's test and the score
are a sample of at most :data:`SAMPLE_MOTIONS` of the eye's keyframe motions, evenly spread
(:func:`spread_sample`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..arrays import Indices, Mask, Stamps
from ..trajectory import Trajectory

#: Windows of the eye in an excerpt, and the eye's keyframe motions (eq. 6) they hold in all:
#: at 30 deg/s some 160 s of a recording (bench/results/runtime.md: the truth kept and a lap away
#: rejected there on every motion and noise level of the simulations).
WINDOWS = 8
EXCERPT_MOTIONS = 800
#: An excerpt of more than this share of a recording is the whole recording.
WHOLE_SHARE = 2 / 3
#: The hand reaches this far (s) beyond each eye window: the interpolation's neighbours fit
#: within it.
MARGIN_S = 1.0
#: Time between two windows of an excerpt (s), and at least this many times either stream's
#: gap limit: the interpolation and the angular speeds do not reach across it.
GAP_S = 5.0
GAP_LIMITS = 2.0
#: Most keyframe motions the self-check scores each candidate on.
SAMPLE_MOTIONS = 2000


def excerpt_share(eye: Trajectory, n_motions: int, covered: float = 1.0) -> float:
    """The share of the eye's poses the hand covers (``covered``) an excerpt keeps, for an eye
    of ``n_motions`` keyframe motions: enough for EXCERPT_MOTIONS of them; 1 (the whole) beyond
    WHOLE_SHARE, and for a keyframe-only eye (sparse already)."""
    share = EXCERPT_MOTIONS / max(n_motions * covered, 1.0)
    return 1.0 if eye.keyframes or share > WHOLE_SHARE else share


def excerpt(
    hand: Trajectory, eye: Trajectory, time_offset_s: float, n_motions: int
) -> tuple[Trajectory, Trajectory]:
    """(hand, eye) cut to an excerpt (see the module docstring) at offset ``time_offset_s`` (s,
    eye clock minus hand clock), for an eye of ``n_motions`` keyframe motions: the windows are
    spread over the eye poses the hand covers at that offset (a MoCap of a few rooms, or of the
    start and the end only, covers parts); both unchanged when the excerpt would be most of
    them."""
    offset_ns = round(time_offset_s * 1e9)
    covered = np.flatnonzero(_covers(hand, eye.t_ns - offset_ns))
    share = excerpt_share(eye, n_motions, covered.size / len(eye))
    if share >= 1.0 or covered.size < 2 * WINDOWS:
        return hand, eye
    margin_ns = round(MARGIN_S * 1e9)
    gap_s = max(GAP_S, GAP_LIMITS * hand.gap_limit_s(), GAP_LIMITS * eye.gap_limit_s())
    gap_ns = 2 * margin_ns + round(gap_s * 1e9)
    h_rows, e_rows, h_stamps, e_stamps, joins = [], [], [], [], []
    t_next = int(eye.t_ns[0])  # where the next window starts once moved
    for part in np.array_split(covered, WINDOWS):
        # the middle of this part of the covered poses
        n = max(2, round(part.size * share))
        a = int(part[(part.size - n) // 2])
        b = int(part[(part.size - n) // 2 + n - 1])
        t0, t1 = int(eye.t_ns[a]), int(eye.t_ns[b])
        shift = t_next - t0  # this window's move, hand and eye alike
        h = np.flatnonzero(
            (hand.t_ns >= t0 - offset_ns - margin_ns) & (hand.t_ns <= t1 - offset_ns + margin_ns)
        )
        e_rows.append(np.arange(a, b + 1))
        h_rows.append(h)
        e_stamps.append(eye.t_ns[a : b + 1] + shift)
        h_stamps.append(hand.t_ns[h] + shift)
        joins.append(sum(r.size for r in e_rows) - 1)
        t_next += t1 - t0 + gap_ns
    return (
        _rows(hand, np.concatenate(h_rows), np.concatenate(h_stamps)),
        _rows(eye, np.concatenate(e_rows), np.concatenate(e_stamps)).with_breaks(
            np.array(joins[:-1], dtype=int)
        ),
    )


def _covers(hand: Trajectory, t_ns: Stamps) -> Mask:
    """Which stamps ``t_ns`` (int64 ns, sorted) the hand covers: inside its span, in no gap."""
    k = np.clip(np.searchsorted(hand.t_ns, t_ns, side='right'), 1, len(hand) - 1)
    inside = (t_ns >= hand.t_ns[0]) & (t_ns <= hand.t_ns[-1])
    covered: Mask = inside & hand.interval_ok()[k - 1]
    return covered


def _rows(traj: Trajectory, rows: Mask | Indices, t_ns: Stamps) -> Trajectory:
    """The poses ``rows`` of a stream (its breaks among them kept) at new stamps."""
    return replace(traj.select(rows), t_ns=t_ns)


def spread_sample(i: Indices, j: Indices) -> tuple[Indices, Indices]:
    """At most SAMPLE_MOTIONS of the motions (i -> j), evenly spread over them."""
    if i.size <= SAMPLE_MOTIONS:
        return i, j
    k = np.linspace(0, i.size - 1, SAMPLE_MOTIONS).round().astype(int)
    return i[k], j[k]
