"""Stage 1: the time offset from angular-velocity correlation (paper Section III-A).

Why this works: a rigid hand-eye rig turns at one angular rate, so the body angular speed
``|w_H(t)|`` of the MoCap marker and ``|w_E(t)|`` of the VIO body are the same signal, whatever
T_HE and T_WG are; only the clock differs. With the convention ``T_WE(t) = T_WG T_GH(t - dt) T_HE``
the eye signal is the hand signal delayed by dt: ``|w_E|(t) = |w_H|(t - dt)``, so the
cross-correlation ``c(tau) = sum_t |w_E|(t + tau) |w_H|(t)`` peaks at ``tau = dt`` (eq. 1), and
a parabola through the peak and its two neighbours gives the sub-sample offset (the paper's
quadratic fit).

Both speeds are made on grids of their own, robust and standardised (:mod:`.signals`: two
clocks 1.4e9 s apart cost nothing more), and correlated with a masked normalised
cross-correlation (FFT, :mod:`.correlation`), which stays correct across gaps and partial
overlap.

Beyond the paper, three things make the offset hard to fool:

- **Robust signals.** Samples of a signal beyond ``median + 8 * 1.4826 * MAD`` of its own
  values are left out (like a gap) and the rest clipped at ``median + 4 * 1.4826 * MAD``: one
  spike that screening missed (a glitch the size of a whole turn) is then not correlated at
  all, and a fast turn weighs like a fast turn, not like the whole recording.
- **Every lag.** By default every lag at which the recordings overlap by at least half of the
  shorter one (and 5 s) is searched, so offsets of seconds or minutes and clocks on different
  epochs are found; ``max_time_offset`` / ``time_offset_guess`` narrow the search. The other
  local maxima of the curve are kept as *candidates* for the self-check of the pipeline.
- **A vector form** (:func:`align_time_vector`), once stage 2 knows the rotation of T_HE:
  the eye's body angular velocity is matched with the hand's rotated into the eye frame,
  ``w_E(t) = R_EH w_H(t - dt)``: three signed components instead of one magnitude, so the
  short windows along the recording that measure a drift (:mod:`.clock`) are not tied by a
  repetitive speed profile or a noisy magnitude.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..arrays import Floats, Indices, Mask
from ..errors import NoOverlapError, TimeAlignmentError
from ..trajectory import Trajectory, gap_free_parts, lengths_text
from .correlation import (
    lobe,
    masked_normalised_correlation,
    parabola_vertex,
    second_peak_ratio,
)
from .signals import (
    AngularSpeed,
    angular_speed,
    clip_signal,
    grid,
    grid_step,
    resample,
    spans,
    standardise,
)

#: A lag is only considered where the two signals overlap on at least this fraction of the
#: shorter one: with little overlap a normalised correlation is high by chance.
MIN_OVERLAP_FRACTION = 0.5
#: ... and on at least this many seconds.
MIN_OVERLAP_S = 5.0
#: Other local maxima of the correlation at least this fraction of the peak are candidates.
CANDIDATE_RATIO = 0.7
#: At most this many candidates besides the peak.
MAX_CANDIDATES = 4


@dataclass(frozen=True)
class TimeAlignment:
    """Result of stage 1.

    Attributes
    ----------
    time_offset_s : float
        dt = eye clock minus hand clock, seconds (``T_WE(t) = T_WG T_GH(t - dt) T_HE``).
    method : str
        'quadratic' (sub-sample peak), 'none' (integer peak, the paper's baseline) or 'fixed'.
    peak_correlation : float
        Normalised correlation at the peak, in [-1, 1]; 1 means the profiles agree exactly.
    second_peak_ratio : float
        Highest correlation outside the main lobe divided by the peak's; near 1 means an
        ambiguous (periodic) motion.
    step_s : float
        Lag resolution of the correlation grid, seconds.
    window_s : tuple of float
        Searched offsets (min, max), seconds.
    lags_s, correlation : ndarray
        The correlation curve over the searched offsets, for plots and diagnostics.
    candidates : tuple of (float, float)
        Other local maxima (offset s, correlation) reaching CANDIDATE_RATIO of the peak, best
        first.
    time_offset_ns : int
        ``time_offset_s`` in integer nanoseconds, exact where the float is not (clocks on
        different epochs, 1e9 s apart).
    """

    time_offset_s: float
    method: str
    peak_correlation: float = float('nan')
    second_peak_ratio: float = float('nan')
    step_s: float = float('nan')
    window_s: tuple[float, float] = (float('nan'), float('nan'))
    lags_s: Floats | None = None
    correlation: Floats | None = None
    candidates: tuple[tuple[float, float], ...] = field(default=())
    time_offset_ns: int = 0


@dataclass(frozen=True)
class Curve:
    """A correlation over lags: offsets dt (s, from the epoch difference D plus the lag),
    values, and which lags may be chosen."""

    base_ns: int  # eye origin - hand origin (ns): dt = base + lag * step
    step: float
    lags: Floats | Indices
    ncc: Floats
    eligible: Mask

    def offset_s(self, lag: float) -> float:
        return self.base_ns * 1e-9 + lag * self.step


@dataclass(frozen=True)
class _Search:
    """Where stage 1 looks: the lag grid's step [s], and the offsets time_offset_guess +-
    max_time_offset [s] (every lag when max_time_offset is None)."""

    step: float
    max_time_offset: float | None
    time_offset_guess: float | None


def _correlate(
    hand: Trajectory,
    eye: Trajectory,
    hand_signal: tuple[Floats, Mask],
    eye_signal: tuple[Floats, Mask],
    search: _Search,
) -> Curve:
    """The correlation of the two signals on their grids (each (values, valid mask)) over the
    lags ``search`` allows, with the lags that overlap enough eligible."""
    (x, mx), (y, my) = hand_signal, eye_signal
    step = search.step
    lags, ncc, overlap = masked_normalised_correlation(y, my, x, mx)
    base_ns = int(eye.t_ns[0]) - int(hand.t_ns[0])
    need = max(MIN_OVERLAP_S / step, MIN_OVERLAP_FRACTION * min(mx.sum(), my.sum()))
    eligible = (overlap >= need) & np.isfinite(ncc)
    if search.max_time_offset is not None:
        guess = search.time_offset_guess or 0.0
        # offsets relative to the guess, computed without forming base + lag in float
        rel = (base_ns - round(guess * 1e9)) * 1e-9 + lags * step
        eligible &= np.abs(rel) <= search.max_time_offset + 0.5 * step
    return Curve(base_ns, step, lags, ncc, eligible)


def _no_overlap(
    hand: Trajectory, eye: Trajectory, need_s: float, window: tuple[float, float] | None
) -> NoOverlapError:
    where = (
        'at any offset'
        if window is None
        else f'at any offset in [{window[0]:+.3f}, {window[1]:+.3f}] s'
    )
    msg = (
        f'{hand.name} and {eye.name} do not overlap in time by at least {need_s:.1f} s '
        f'{where} (hand covers {hand.duration_s:.1f} s{_parts(hand)}, eye '
        f'{eye.duration_s:.1f} s{_parts(eye)}, eye starts '
        f'{(eye.t_ns[0] - hand.t_ns[0]) * 1e-9:+.3f} s after hand on their own clocks)'
        + (
            ''
            if window is None
            else '. Widen max_time_offset or move '
            'time_offset_guess, or leave both unset to search every lag'
        )
    )
    return NoOverlapError(msg)


def _parts(traj: Trajectory) -> str:
    """', in N gap-free parts of ... s' for a stream with gaps ('' without)."""
    parts = gap_free_parts(traj)
    if len(parts) < 2:
        return ''
    return f' in {len(parts)} gap-free parts of ' + lengths_text(
        [(traj.t_ns[b - 1] - traj.t_ns[a]) * 1e-9 for a, b in parts]
    )


def _peak(
    curve: Curve,
    peak_fit: str,
    hand: Trajectory,
    eye: Trajectory,
    window: tuple[float, float] | None,
    need_s: float,
) -> tuple[int, float]:
    """Index of the best eligible lag and its sub-sample fraction."""
    if not curve.eligible.any():
        raise _no_overlap(hand, eye, need_s, window)
    scores = np.where(curve.eligible, curve.ncc, -np.inf)
    k = int(np.argmax(scores))
    idx = np.flatnonzero(curve.eligible)
    if k in (idx[0], idx[-1]) or not (curve.eligible[k - 1] and curve.eligible[k + 1]):
        where = (
            'the edge of the search window'
            if window is not None
            else 'the edge of the lags at which the recordings overlap enough'
        )
        msg = (
            f'the angular-speed correlation peaks at {where} (at '
            f'{curve.offset_s(curve.lags[k]):+.3f} s): the time offset is probably outside '
            'it. '
            + (
                'Widen max_time_offset or move time_offset_guess'
                if window is not None
                else 'Do the two recordings show the same motion?'
            )
        )
        raise TimeAlignmentError(msg)
    frac = parabola_vertex(*curve.ncc[k - 1 : k + 2]) if peak_fit == 'quadratic' else 0.0
    return k, frac


def offset_window(
    max_time_offset: float | None, time_offset_guess: float | None
) -> tuple[float, float] | None:
    if max_time_offset is None:
        return None
    g = 0.0 if time_offset_guess is None else time_offset_guess
    return g - max_time_offset, g + max_time_offset


def align_time(
    hand: Trajectory,
    eye: Trajectory,
    *,
    max_time_offset: float | None = None,
    time_offset_guess: float | None = None,
    resample_rate_hz: float | None = None,
    peak_fit: str = 'quadratic',
    signals: tuple[AngularSpeed, AngularSpeed] | None = None,
) -> TimeAlignment:
    """Estimate dt (eye clock minus hand clock) from the angular-speed magnitudes (eq. 1).

    Every lag with enough overlap is searched unless ``max_time_offset`` is given (then
    ``time_offset_guess +- max_time_offset``; the guess alone only matters with it).
    ``signals``: the streams' angular speeds when already at hand (:meth:`AngularSpeed.part`).

    Raises
    ------
    TimeAlignmentError
        When the streams do not overlap enough at any searched offset, when the motion has no
        variation in angular speed, or when the correlation peaks at the edge of the searched
        offsets (the offset is then most likely outside them).
    """
    if peak_fit not in ('quadratic', 'none'):
        msg = f"peak_fit must be 'quadratic' or 'none', got {peak_fit!r}"
        raise ValueError(msg)
    step = grid_step(hand, eye, resample_rate_hz)
    n_h, n_e = spans(hand, eye)
    signals = signals or (angular_speed(hand, span=n_h), angular_speed(eye, span=n_e))
    return _align(
        hand, eye, signals, _Search(step, max_time_offset, time_offset_guess), peak_fit, peak_fit
    )


def align_time_vector(
    hand: Trajectory,
    eye: Trajectory,
    R_HE: Floats,
    *,
    around_s: float,
    half_window_s: float,
    resample_rate_hz: float | None = None,
    signals: tuple[AngularSpeed, AngularSpeed] | None = None,
) -> TimeAlignment:
    """dt from the body angular velocities: ``w_E(t) = R_HE^T w_H(t - dt)``.

    Searches ``around_s +- half_window_s`` (seconds); the sub-sample peak by the same parabola.
    ``method`` is 'vector'. ``signals``: the streams' body angular velocities when already at
    hand (:meth:`AngularSpeed.part` of longer streams).

    Raises
    ------
    TimeAlignmentError
        As :func:`align_time`.
    """
    step = grid_step(hand, eye, resample_rate_hz)
    n_h, n_e = spans(hand, eye)
    w_h, w_e = signals or (
        angular_speed(hand, vector=True, span=n_h),
        angular_speed(eye, vector=True, span=n_e),
    )
    w_h = AngularSpeed(w_h.t_s, w_h.speed @ R_HE, w_h.valid, w_h.span)  # rows: R_HE^T w_H
    search = _Search(step, half_window_s, around_s)
    return _align(hand, eye, (w_h, w_e), search, 'quadratic', 'vector')


def _align(
    hand: Trajectory,
    eye: Trajectory,
    signals: tuple[AngularSpeed, AngularSpeed],
    search: _Search,
    peak_fit: str,
    method: str,
) -> TimeAlignment:
    """Stage 1 on two signals (hand's, eye's: magnitudes or vectors): each on its own grid,
    robust, standardised, correlated over the lags ``search`` allows, the peak (``peak_fit``)
    and its candidates; ``method`` names it in the result."""
    (w_h, w_e), step = signals, search.step
    x, mx = resample(w_h, grid(hand, step))
    y, my = resample(w_e, grid(eye, step))
    x, mx = clip_signal(x, mx, step)
    y, my = clip_signal(y, my, step)
    x = standardise(x, mx, hand.name)
    y = standardise(y, my, eye.name)
    curve = _correlate(hand, eye, (x, mx), (y, my), search)
    window = offset_window(search.max_time_offset, search.time_offset_guess)
    need_s = max(MIN_OVERLAP_S, MIN_OVERLAP_FRACTION * min(mx.sum(), my.sum()) * step)
    k, frac = _peak(curve, peak_fit, hand, eye, window, need_s)
    eligible = np.flatnonzero(curve.eligible)
    sel = slice(int(eligible[0]), int(eligible[-1]) + 1)
    scores = np.where(curve.eligible, curve.ncc, -np.inf)
    lag_ns = round((curve.lags[k] + frac) * step * 1e9)
    return TimeAlignment(
        time_offset_s=curve.offset_s(curve.lags[k] + frac),
        method=method,
        peak_correlation=float(curve.ncc[k]),
        second_peak_ratio=second_peak_ratio(scores[sel], k - sel.start),
        step_s=step,
        window_s=window
        or (curve.offset_s(curve.lags[sel.start]), curve.offset_s(curve.lags[sel.stop - 1])),
        lags_s=curve.base_ns * 1e-9 + curve.lags[sel] * step,
        correlation=curve.ncc[sel],
        candidates=candidates(curve, k),
        time_offset_ns=curve.base_ns + lag_ns,
    )


def candidates(curve: Curve, k: int) -> tuple[tuple[float, float], ...]:
    """Other local maxima outside the peak's lobe reaching CANDIDATE_RATIO of it (with their
    sub-sample parabola): the MAX_CANDIDATES best, and the one nearest to a zero offset (on a
    repetitive motion many peaks tie, and clocks started together are the likelier case)."""
    s = np.where(curve.eligible, curve.ncc, -np.inf)
    peak = s[k]
    if not peak > 0.0:
        return ()
    inner = s[1:-1]
    local = (
        np.flatnonzero((inner >= s[:-2]) & (inner > s[2:]) & (inner >= CANDIDATE_RATIO * peak)) + 1
    )
    lo, hi = lobe(s, k)
    local = local[(local < lo) | (local > hi)]
    if not local.size:
        return ()
    nearest = local[np.argmin(np.abs(curve.base_ns * 1e-9 + curve.lags[local] * curve.step))]
    local = local[np.argsort(-s[local])][:MAX_CANDIDATES]
    if nearest not in local:
        local = np.append(local, nearest)
    out = []
    for m in local:
        frac = (
            parabola_vertex(*curve.ncc[m - 1 : m + 2])
            if np.all(np.isfinite(curve.ncc[m - 1 : m + 2]))
            else 0.0
        )
        out.append((curve.offset_s(curve.lags[m] + frac), float(curve.ncc[m])))
    return tuple(out)
