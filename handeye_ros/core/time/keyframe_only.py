"""Stage 1 for keyframe-only eyes: the time offset from rotation angles over keyframe pairs.

Why: many SLAM systems write keyframes only (DSO, ORB-SLAM's ``KeyFrameTrajectory.txt``):
poses 0.05-5 s apart at irregular stamps, from which no angular speed can be resampled, so the
correlation of Section III-A has nothing to correlate. But the screw congruence theorem (eq. 9)
needs no rate: the rotation angle of the eye's relative motion between two keyframes a, b
equals the hand's over the same interval on the hand's clock, whatever T_HE and T_WG::

    angle(R_WE(a)^T R_WE(b)) = angle(R_GH(a - dt)^T R_GH(b - dt))

so dt is where the hand's angles over the shifted keyframe intervals agree with the eye's. Each
pair needs the hand at its two ends only, so a MoCap dropout between them costs nothing.

The search, over every lag at which the streams overlap (or the window asked for), as stage 1:

1. the hand's orientation on a uniform grid of its own (the faster of its rate and 200 Hz),
   with a mask of the grid points inside its gaps;
2. for each lag on a coarse grid (COARSE_STEP_S, at most COARSE_PAIRS pairs spread over the
   recording: an hour of 1 Hz keyframes over every lag would be 10^10 angle comparisons), a
   score ``1 - mean(min(|angle_E - angle_H|, CAP_RAD)) / CAP_RAD``: 1 when all angles agree,
   near 0 at a lag where they are unrelated; a lag counts where at least half as many pairs
   fall inside the hand as at the best-covered lag. Each pair is compared at the lags where it
   falls inside the hand only, and lags where too few pairs can are not scored: the cost is
   that of the pairs and lags that meet, not of every lag times every pair;
3. the best coarse lag, then every grid lag around it with all pairs, then a continuous
   refinement: the mean squared angle difference of the pairs that agree there, with the hand
   interpolated exactly (SLERP between its own poses), minimised by Brent's method.

The result is a :class:`.time.align.TimeAlignment` with method 'keyframes', its curve the score
(so the pipeline's checks of a weak or ambiguous peak read it as they read a correlation), and
peak_correlation the Pearson correlation of the two angle sets at the offset.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation, Slerp

from ..arrays import Floats, Indices, Mask
from ..errors import TooFewKeyframesError
from ..trajectory import Trajectory
from .align import (
    MIN_OVERLAP_FRACTION,
    Curve,
    TimeAlignment,
    candidates,
    offset_window,
)
from .correlation import second_peak_ratio
from .keyframe_errors import at_the_edge, no_agreement, too_few
from .signals import MAX_RESAMPLE_RATE_HZ, grid_step

#: Angle differences are capped at this (rad, 11 deg) in the score: a pair that does not agree
#: counts as disagreeing, however wildly (a VIO glitch, a MoCap swap).
CAP_RAD = 0.2
#: Lag step of the coarse search (s): an angle over an interval moves with the lag by at most
#: the angular speed at its two ends (a few rad/s hand-held), 0.02 rad per 10 ms.
COARSE_STEP_S = 0.02
#: Most keyframe pairs the coarse search uses (spread evenly over the recording), and most lags
#: x pairs it compares (an hour of keyframes over every lag: 360 000 lags x 2000 pairs).
COARSE_PAIRS = 2000
COARSE_WORK = 10**9
#: Fewest keyframe pairs inside the hand at a lag for it to count.
MIN_PAIRS = 20
#: Below this Pearson correlation of the eye's and the hand's angles at the best offset, they
#: do not agree anywhere searched (at the right offset it is 0.95-1; at a wrong one 0-0.3).
MIN_AGREEMENT = 0.5
#: Partners of each keyframe: the next one and the one after it.
PARTNERS = (1, 2)
#: (pair, lag) meetings compared at once (memory of a chunk: its quaternions, 4 x 8 bytes each
#: of two, and their indices: some 150 MB).
CHUNK = 1 << 20


def rotation_angles(q_a: Floats, q_b: Floats) -> Floats:
    """Rotation angle (rad, in [0, pi]) of ``R(q_a)^T R(q_b)`` for unit quaternions (..., 4):
    ``2 acos |<q_a, q_b>|``."""
    dot = np.abs(np.sum(q_a * q_b, axis=-1))
    out: Floats = 2.0 * np.arccos(np.minimum(dot, 1.0))
    return out


def keyframe_pairs(eye: Trajectory) -> tuple[Floats, Floats]:
    """Indices (a, b) of each keyframe and its PARTNERS that no break separates."""
    seg = eye.segment_ids()
    a = np.concatenate([np.arange(len(eye) - d) for d in PARTNERS])
    b = np.concatenate([np.arange(d, len(eye)) for d in PARTNERS])
    same = seg[a] == seg[b]
    return a[same], b[same]


def align_time_keyframes(
    hand: Trajectory,
    eye: Trajectory,
    *,
    max_time_offset: float | None = None,
    time_offset_guess: float | None = None,
) -> TimeAlignment:
    """dt (eye clock minus hand clock) of a keyframe-only eye (see the module docstring).

    Raises
    ------
    TimeAlignmentError
        When too few keyframe pairs fall inside the hand at any searched offset, when the eye
        does not rotate, or when the best offset is at the edge of the searched ones.
    """
    pairs = _eye_angles(eye)
    # the hand's rate (the eye's is no grid), bounded as stage 1 bounds its grids by the spans
    step = grid_step(hand, eye, min(hand.rate_hz, MAX_RESAMPLE_RATE_HZ))
    orient = _HandOrientation.of(hand)
    on_grid = _OnGrid(*_hand_grid(orient, step), *_grid_points(eye, pairs, step), pairs.angle_e)
    base_ns = int(eye.t_ns[0]) - int(hand.t_ns[0])
    window = offset_window(max_time_offset, time_offset_guess)
    k_lo, k_hi = _lag_range(on_grid.ga, on_grid.gb, on_grid.q.shape[0], base_ns, step, window)
    if k_hi - k_lo < 2:
        raise too_few(hand, eye, window, MIN_PAIRS)
    m = max(1, round(COARSE_STEP_S / step))
    coarse, c_score, c_ok, counted = _coarse_pass(on_grid, k_lo, k_hi, m)
    if not c_ok.any():
        raise too_few(hand, eye, window, MIN_PAIRS)
    kc = int(np.argmax(np.where(c_ok, c_score, -np.inf)))
    # every grid lag around the coarse best, with all pairs
    fine = np.arange(max(k_lo, coarse[kc] - 2 * m), min(k_hi, coarse[kc] + 2 * m) + 1)
    k = _best_lag(on_grid, fine, max(MIN_PAIRS, MIN_OVERLAP_FRACTION * counted))
    if k is None:
        raise too_few(hand, eye, window, MIN_PAIRS)
    if not coarse[c_ok][0] < k < coarse[c_ok][-1]:
        raise at_the_edge(base_ns * 1e-9 + k * step, window)
    lag_s, agree = _refine(orient, eye, pairs, k * step, step)
    if not agree >= MIN_AGREEMENT:
        raise no_agreement(hand, eye, base_ns * 1e-9 + lag_s, agree, window)
    first, last = np.flatnonzero(c_ok)[[0, -1]]
    sel = slice(first, last + 1)
    return TimeAlignment(
        time_offset_s=base_ns * 1e-9 + lag_s,
        method='keyframes',
        peak_correlation=agree,
        second_peak_ratio=second_peak_ratio(np.where(c_ok, c_score, -np.inf)[sel], kc - first),
        step_s=step,
        window_s=window or (base_ns * 1e-9 + k_lo * step, base_ns * 1e-9 + k_hi * step),
        lags_s=base_ns * 1e-9 + coarse[sel] * step,
        correlation=c_score[sel],
        candidates=_others(
            Curve(base_ns, m * step, coarse / m, np.where(c_ok, c_score, np.nan), c_ok), kc, lag_s
        ),
        time_offset_ns=base_ns + round(lag_s * 1e9),
    )


@dataclass(frozen=True)
class _Pairs:
    """The eye's keyframe pairs: indices (a, b) and the eye's rotation angle over each (rad)."""

    a: Floats
    b: Floats
    angle_e: Floats


@dataclass(frozen=True)
class _OnGrid:
    """The hand and the keyframe pairs on the lag grid: the hand's orientation at each grid
    point (``q``, x y z w, (G, 4)) and which points lie in a gap-free interval (``ok``); the
    pairs' stamps in grid steps (``ga``, ``gb``) and the eye's angle over each (rad)."""

    q: Floats
    ok: Mask
    ga: Indices
    gb: Indices
    angle_e: Floats

    def some(self, pick: Indices) -> _OnGrid:
        """The pairs ``pick`` only."""
        return replace(self, ga=self.ga[pick], gb=self.gb[pick], angle_e=self.angle_e[pick])


def _grid_points(eye: Trajectory, pairs: _Pairs, step: float) -> tuple[Indices, Indices]:
    """The keyframe pairs' stamps in grid steps from the eye's first: at lag k (dt = base + k
    step) the eye stamp te falls on the hand's grid point te / step - k."""
    te = eye.seconds(int(eye.t_ns[0]))
    a, b = pairs.a, pairs.b
    return np.rint(te[a] / step).astype(np.int64), np.rint(te[b] / step).astype(np.int64)


def _best_lag(on_grid: _OnGrid, lags: Indices, need: float) -> int | None:
    """The best-scoring of ``lags`` with all pairs among those with at least ``need`` pairs;
    None when none has."""
    score, count = _scores(on_grid, lags)
    ok = count >= need
    return int(lags[int(np.argmax(np.where(ok, score, -np.inf)))]) if ok.any() else None


def _coarse_pass(
    on_grid: _OnGrid, k_lo: int, k_hi: int, m: int
) -> tuple[Indices, Floats, Mask, float]:
    """Every m-th lag of [k_lo, k_hi] scored on a subset of the keyframe pairs (fewer for very
    long searches, so that the pass stays bounded): (lags, scores, which lags have enough
    pairs, the most pairs any lag had, scaled to all pairs)."""
    coarse = np.arange(k_lo, k_hi + 1, m)
    ga = on_grid.ga
    n_pick = min(ga.size, COARSE_PAIRS, max(MIN_PAIRS * 10, COARSE_WORK // max(coarse.size, 1)))
    pick = np.unique(np.linspace(0, ga.size - 1, n_pick).astype(int))
    least = max(MIN_PAIRS * pick.size / ga.size, 1.0)
    coarse = coarse[_may_count(on_grid.some(pick), coarse, least)]
    if not coarse.size:
        return coarse, np.zeros(0), np.zeros(0, bool), 0.0
    c_score, c_count = _scores(on_grid.some(pick), coarse)
    need = max(least, MIN_OVERLAP_FRACTION * c_count.max())
    return coarse, c_score, c_count >= need, float(c_count.max() * ga.size / pick.size)


def _may_count(on_grid: _OnGrid, lags: Indices, least: float) -> Mask:
    """The lags (sorted) from one before the first to one after the last at which at least
    ``least`` of the pairs can fall inside the hand's grid: a pair (a, b) can at the lags
    [b - (G - 1), a] (gaps left aside, so the count is an upper bound of the score's), and
    outside that span no lag can count (the one on each side keeps the span's edges what they
    were among the lags around it). A short hand far from a long eye thus costs the lags where
    they can meet, not all of them."""
    n = on_grid.q.shape[0]
    first, last = np.sort(on_grid.gb - (n - 1)), np.sort(on_grid.ga)
    can = np.searchsorted(first, lags, side='right') - np.searchsorted(last, lags, side='left')
    at = np.flatnonzero(can >= least)
    out = np.zeros(lags.size, bool)
    if at.size:
        out[max(at[0] - 1, 0) : at[-1] + 2] = True
    return out


def _lag_range(
    ga: Indices,
    gb: Indices,
    n_grid: int,
    base_ns: int,
    step: float,
    window: tuple[float, float] | None,
) -> tuple[int, int]:
    """The lags (grid steps) at which a keyframe pair can fall inside the hand's grid of
    ``n_grid`` points, within the searched ``window`` of offsets (s) when there is one."""
    k_lo, k_hi = int(ga.min()) - (n_grid - 1), int(gb.max())
    if window is not None:
        k_lo = max(k_lo, int(np.ceil((window[0] - base_ns * 1e-9) / step)))
        k_hi = min(k_hi, int(np.floor((window[1] - base_ns * 1e-9) / step)))
    return k_lo, k_hi


def _others(curve: Curve, kc: int, lag_s: float) -> tuple[tuple[float, float], ...]:
    """The coarse curve's candidates (:func:`.align.candidates`) away from the answer (more than
    two coarse steps from ``lag_s``, s from the curve's base)."""
    return tuple(
        c
        for c in candidates(curve, kc)
        if abs(c[0] - curve.base_ns * 1e-9 - lag_s) > 2 * curve.step
    )


def _eye_angles(eye: Trajectory) -> _Pairs:
    """The keyframe pairs (a, b) and the eye's rotation angle over each; refused when there are
    too few, or when the keyframes hardly rotate."""
    a, b = keyframe_pairs(eye)
    if a.size < MIN_PAIRS:
        raise TooFewKeyframesError(
            f'{eye.name}: {len(eye)} keyframes give {a.size} keyframe pairs; the time offset '
            f'of a keyframe-only eye needs at least {MIN_PAIRS}'
        )
    angle_e = rotation_angles(eye.q_xyzw[a], eye.q_xyzw[b])
    if float(np.percentile(angle_e, 90)) < np.deg2rad(1.0):
        raise TooFewKeyframesError(
            f'{eye.name}: the keyframes hardly rotate (90 % of the keyframe pairs turn by less '
            'than 1 deg); the time offset cannot be observed. Record a motion with rotation'
        )
    return _Pairs(a, b, angle_e)


@dataclass(frozen=True)
class _HandOrientation:
    """The hand's orientation as both passes read it, made once (an hour of 1 kHz MoCap is
    3.6 million rotations): t_s, its stamps (s from its first); slerp, the interpolator between
    its poses; ok, which intervals are gap-free."""

    t_s: Floats
    slerp: Slerp
    ok: Mask

    @classmethod
    def of(cls, hand: Trajectory) -> _HandOrientation:
        th = hand.seconds(int(hand.t_ns[0]))
        return cls(th, Slerp(th, Rotation.from_quat(hand.q_xyzw)), hand.interval_ok())

    def inside(self, t: Floats) -> Mask:
        """Times (s) inside the hand's span and a gap-free interval of it."""
        th = self.t_s
        j = np.clip(np.searchsorted(th, t, side='right') - 1, 0, th.size - 2)
        out: Mask = (t >= th[0]) & (t <= th[-1]) & self.ok[j]
        return out


def _hand_grid(hand: _HandOrientation, step: float) -> tuple[Floats, Mask]:
    """The hand's orientation (x y z w) on a uniform grid from its first stamp, and which grid
    points lie inside a gap-free interval."""
    th = hand.t_s
    grid = step * np.arange(int(np.floor(th[-1] / step)) + 1)
    k = np.clip(np.searchsorted(th, grid, side='right') - 1, 0, th.size - 2)
    return hand.slerp(grid).as_quat(), hand.ok[k]


def _scores(on_grid: _OnGrid, lags: Indices) -> tuple[Floats, Indices]:
    """(score, pairs inside the hand) at each of the sorted ``lags`` (grid steps). Each pair
    is compared at the lags where it falls inside the hand's grid only (:func:`_meetings`), a
    chunk of (pair, lag) meetings at a time."""
    grid_q, grid_ok = on_grid.q, on_grid.ok
    ga, gb, angle_e = on_grid.ga, on_grid.gb, on_grid.angle_e
    total, count = np.zeros(lags.size), np.zeros(lags.size)
    for p, j in _meetings(on_grid, lags):
        k = lags[j]
        ia, ib = ga[p] - k, gb[p] - k
        ok = grid_ok[ia] & grid_ok[ib]
        diff = np.minimum(np.abs(rotation_angles(grid_q[ia], grid_q[ib]) - angle_e[p]), CAP_RAD)
        total += np.bincount(j, np.where(ok, diff, 0.0), lags.size)
        count += np.bincount(j, ok, lags.size)
    with np.errstate(invalid='ignore', divide='ignore'):
        score = 1.0 - total / (count * CAP_RAD)
    return score, count.astype(np.int64)


def _meetings(on_grid: _OnGrid, lags: Indices) -> Iterator[tuple[Indices, Indices]]:
    """(pair, index into ``lags``) of every meeting of a pair (a, b) with the hand's grid of G
    points, at the lags [b - (G - 1), a], in chunks of at most CHUNK meetings (one pair's may
    be more)."""
    n = on_grid.q.shape[0]
    start = np.searchsorted(lags, on_grid.gb - (n - 1), side='left')
    length = np.maximum(np.searchsorted(lags, on_grid.ga, side='right') - start, 0)
    ends = np.cumsum(length)
    first = 0
    while first < length.size:
        last = max(
            int(np.searchsorted(ends, ends[first] - length[first] + CHUNK, 'right')), first + 1
        )
        some = np.arange(first, last)
        p = np.repeat(some, length[some])
        # the meetings of the pairs ``some``, each pair's run of lags from its start
        run = np.arange(p.size) - np.repeat(np.cumsum(length[some]) - length[some], length[some])
        yield p, start[p] + run
        first = last


def _refine(
    hand: _HandOrientation, eye: Trajectory, pairs: _Pairs, lag_s: float, step: float
) -> tuple[float, float]:
    """The lag (s, after the epoch difference) within one grid step of ``lag_s`` that minimises
    the mean squared angle difference of the pairs that agree there, the hand interpolated
    exactly; and the Pearson correlation of the eye's and the hand's angles at it."""
    # at lag L a keyframe stamped te (s from the eye's first stamp) meets the hand at te - L
    # (s from the hand's first stamp): dt = base + L, base the difference of the first stamps
    a, b, angle_e = pairs.a, pairs.b, pairs.angle_e
    te = eye.seconds(int(eye.t_ns[0]))

    def at(lag: float, use: Mask) -> tuple[Floats, Mask]:
        """Hand angles over the pairs ``use`` at a lag (NaN outside the hand), and inside."""
        ta, tb = te[a[use]] - lag, te[b[use]] - lag
        inside = hand.inside(ta) & hand.inside(tb)
        ang = np.full(ta.size, np.nan)
        if inside.any():
            slerp = hand.slerp
            ang[inside] = rotation_angles(slerp(ta[inside]).as_quat(), slerp(tb[inside]).as_quat())
        return ang, inside

    every = np.ones(a.size, bool)
    ang, inside = at(lag_s, every)
    diff = np.abs(ang - angle_e)
    use = inside & (diff < CAP_RAD)
    if use.sum() >= MIN_PAIRS:  # the pairs that agree within 3 robust sigmas
        sigma = 1.4826 * float(np.median(diff[use]))
        use &= diff <= max(3.0 * sigma, np.deg2rad(0.05))

    def cost(lag: float) -> float:
        ang_u, in_u = at(lag, use)
        d = np.where(in_u, ang_u - angle_e[use], CAP_RAD)
        return float(np.mean(np.minimum(d * d, CAP_RAD**2)))

    lag = lag_s
    if use.any():  # else no pair agrees at the coarse lag: nothing to refine it on
        res = minimize_scalar(
            cost, bounds=(lag_s - step, lag_s + step), method='bounded', options={'xatol': 1e-6}
        )
        lag = float(res.x) if res.success else lag_s
    ang, inside = at(lag, every)
    r = np.corrcoef(ang[inside], angle_e[inside])[0, 1] if inside.sum() > 2 else np.nan
    return lag, float(r)
