"""Clock drift: the time offset measured in windows along the recording, and a linear clock.

The paper's model has one constant offset (Section III-A). Device clocks drift: tens to hundreds
of ppm, so that over 10 minutes the offset at the ends differs from the middle by tens of
milliseconds. The linear clock model is::

    dt(t) = time_offset + clock_drift * (t - time_offset_stamp)

with t on the eye clock: the hand instant of an eye stamp t is ``t - dt(t)``.

It is measured here the way stage 1 measures the constant offset, in windows: the recording is
cut into windows of the eye stream, stage 1 (or its vector form, once stage 2 gives the rotation
of T_HE) runs on each against the hand around the current offset, and a line is fitted through
the windows' offsets: a robust start (Siegel's repeated medians, which ignore up to half of the
windows: a window on a repetitive stretch may lock onto a wrong peak) and least squares over the
windows that agree with it, whose scatter gives the drift's standard deviation. The reference
stamp is the mean of the window centres, where offset and drift are uncorrelated.

:func:`retime` moves the eye's stamps onto a clock without drift, so that every later stage
solves the constant-offset problem of the paper; the batch stage then refines the drift as a
parameter (:mod:`.batch.refine`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..arrays import Floats, Mask, Stamps
from ..errors import TimeAlignmentError
from ..trajectory import Trajectory
from .align import align_time, align_time_vector
from .signals import AngularSpeed, angular_speed, spans

#: Shortest window (s): stage 1 needs a few seconds of varied angular speed per window.
MIN_WINDOW_S = 10.0
#: Windows per recording when the recording is long enough (each then MIN_WINDOW_S or longer).
TARGET_WINDOWS = 16
#: Fewest windows agreeing with the line for a drift to be estimated at all.
MIN_WINDOWS = 4
#: Largest drift the first pass searches for (s/s): 2000 ppm, ten times a poor crystal's.
MAX_DRIFT = 2e-3
#: The first pass searches each window this much (s) beyond what MAX_DRIFT needs.
SEARCH_MARGIN_S = 0.05
#: The second pass searches this many robust sigmas of the first line's scatter around it,
#: and at least SECOND_PASS_MIN_S.
SECOND_PASS_SIGMAS = 6.0
SECOND_PASS_MIN_S = 0.02
#: A window agrees with the line when its offset is within this many robust sigmas of it (and
#: at least INLIER_FLOOR_S: a window's own error is ~0.5 ms on a good recording).
INLIER_SIGMAS = 4.0
INLIER_FLOOR_S = 5e-4
#: Windows whose correlation peak is below this say nothing about the offset.
MIN_WINDOW_CORRELATION = 0.3


def linear_clock(offset_s: float, drift: float, stamp_ns: int, t_ns: Stamps | int) -> Floats:
    """dt(t) = offset + drift (t - stamp) [s] at stamps t_ns [ns] (int64 differences first)."""
    return offset_s + drift * (np.asarray(t_ns) - np.int64(stamp_ns)) * 1e-9


@dataclass(frozen=True)
class DriftFit:
    """A linear clock fitted to window offsets.

    drift, drift_std: clock_drift and its standard deviation [s/s] (NaN when not estimated).
    offset_s, offset_std: dt at ``stamp_ns`` and its standard deviation [s].
    stamp_ns: the reference stamp (eye clock of the trajectories it was measured on, ns).
    span_s: time between the first and the last eye pose that the hand covers [s].
    centres_ns, offsets_s, correlation: each window's centre (ns), offset (s) and peak
    correlation; inliers: the windows the line was fitted to. why: why no drift was estimated
    (empty when it was).
    """

    drift: float
    drift_std: float
    offset_s: float
    offset_std: float
    stamp_ns: int
    span_s: float
    centres_ns: Stamps
    offsets_s: Floats
    correlation: Floats
    inliers: Mask
    why: str = ''

    @property
    def estimated(self) -> bool:
        return bool(np.isfinite(self.drift))

    @property
    def change_s(self) -> float:
        """How far the offset moves between the first and the last covered eye pose [s]."""
        return float(self.drift * self.span_s)

    def offset_at(self, t_ns: Stamps | int) -> Floats | float:
        """dt [s] at eye stamps t_ns (the clock this fit was measured on)."""
        return linear_clock(self.offset_s, self.drift, self.stamp_ns, t_ns)

    def shifted(self, delta_ns: int) -> DriftFit:
        """The same fit on an eye clock moved by ``delta_ns`` (stamps t + delta_ns), with the
        offset then eye minus hand on that clock."""
        return replace(
            self,
            stamp_ns=self.stamp_ns + int(delta_ns),
            offset_s=self.offset_s + delta_ns * 1e-9,
            centres_ns=self.centres_ns + np.int64(delta_ns),
            offsets_s=self.offsets_s + delta_ns * 1e-9,
        )


def covered_span(hand: Trajectory, eye: Trajectory) -> tuple[int, int, int]:
    """(first, last, mean) eye stamp [ns] within the hand's span, for an eye on the hand's clock
    (up to a small offset). The mean is the reference stamp: there the offset and the drift of
    a fit over the whole overlap are uncorrelated."""
    inside = (eye.t_ns >= hand.t_ns[0]) & (eye.t_ns <= hand.t_ns[-1])
    t = eye.t_ns[inside] if inside.any() else eye.t_ns
    mean = int(t[0] + np.int64(round(float(np.mean(t - t[0])))))
    return int(t[0]), int(t[-1]), mean


def window_bounds(first_ns: int, last_ns: int) -> Stamps:
    """(W, 2) window edges [ns] covering first..last: TARGET_WINDOWS windows, fewer when that
    would make them shorter than MIN_WINDOW_S."""
    span = (last_ns - first_ns) * 1e-9
    n = int(min(TARGET_WINDOWS, np.floor(span / MIN_WINDOW_S)))
    if n < 1:
        return np.zeros((0, 2), dtype=np.int64)
    edges = first_ns + np.rint(np.linspace(0.0, last_ns - first_ns, n + 1)).astype(np.int64)
    return np.stack((edges[:-1], edges[1:]), axis=1)


def window_offsets(
    hand: Trajectory,
    eye: Trajectory,
    bounds: Stamps,
    predicted_s: Floats,
    half_window_s: float | Floats,
    R_HE: Floats | None = None,
    resample_rate_hz: float | None = None,
    signals: tuple[AngularSpeed, AngularSpeed] | None = None,
) -> tuple[Stamps, Floats, Floats]:
    """Stage 1 in each window of the eye, searched ``predicted_s +- half_window_s``.

    With ``R_HE`` the vector form (``w_E = R_HE^T w_H(t - dt)``), otherwise the angular-speed
    magnitudes; ``signals``: :func:`stream_signals` of the two streams, when already made. Returns (centres ns, offsets s, peak correlation), NaN where a window gives
    no offset (too little motion, the peak at the edge of the search).
    """
    n = bounds.shape[0]
    half = np.broadcast_to(np.asarray(half_window_s, float), (n,))
    centres = (bounds[:, 0] + (bounds[:, 1] - bounds[:, 0]) // 2).astype(np.int64)
    offsets, corr = np.full(n, np.nan), np.full(n, np.nan)
    w_h, w_e = signals or stream_signals(hand, eye, R_HE)
    for k, (a, b) in enumerate(bounds):
        e0 = np.searchsorted(eye.t_ns, a, side='left')
        e1 = np.searchsorted(eye.t_ns, b, side='right')
        reach = np.int64(round((abs(predicted_s[k]) + half[k] + SEARCH_MARGIN_S) * 1e9))
        h0 = np.searchsorted(hand.t_ns, a - reach, side='left')
        h1 = np.searchsorted(hand.t_ns, b + reach, side='right')
        if e1 - e0 < 10 or h1 - h0 < 10:
            continue
        parts = (w_h.part(hand, h0, h1), w_e.part(eye, e0, e1))
        hand_k, eye_k = hand.select(slice(h0, h1)), eye.select(slice(e0, e1))
        try:
            if R_HE is None:
                ta = align_time(
                    hand_k,
                    eye_k,
                    max_time_offset=half[k],
                    time_offset_guess=float(predicted_s[k]),
                    resample_rate_hz=resample_rate_hz,
                    signals=parts,
                )
            else:
                ta = align_time_vector(
                    hand_k,
                    eye_k,
                    R_HE,
                    around_s=float(predicted_s[k]),
                    half_window_s=half[k],
                    resample_rate_hz=resample_rate_hz,
                    signals=parts,
                )
        except TimeAlignmentError:
            continue
        offsets[k], corr[k] = ta.time_offset_s, ta.peak_correlation
    return centres, offsets, corr


def stream_signals(
    hand: Trajectory, eye: Trajectory, R_HE: Floats | None
) -> tuple[AngularSpeed, AngularSpeed]:
    """The angular signals of the whole streams that :func:`window_offsets` cuts into windows:
    body angular velocities with ``R_HE``, angular speeds without."""
    vector, (n_h, n_e) = R_HE is not None, spans(hand, eye)
    return angular_speed(hand, vector=vector, span=n_h), angular_speed(
        eye, vector=vector, span=n_e
    )


def fit_drift(
    centres_ns: Stamps,
    offsets_s: Floats,
    correlation: Floats,
    stamp_ns: int,
    span_s: float,
) -> DriftFit:
    """The line through the window offsets (see the module docstring)."""
    ok = np.isfinite(offsets_s) & (np.nan_to_num(correlation) >= MIN_WINDOW_CORRELATION)
    x = (centres_ns - np.int64(stamp_ns)) * 1e-9
    nan = float('nan')

    def none(why: str) -> DriftFit:
        return DriftFit(
            nan,
            nan,
            nan,
            nan,
            int(stamp_ns),
            span_s,
            centres_ns,
            offsets_s,
            correlation,
            np.zeros(x.size, bool),
            why,
        )

    if ok.sum() < MIN_WINDOWS:
        return none(
            f'only {int(ok.sum())} window(s) of at least {MIN_WINDOW_S:g} s gave an '
            f'offset (need {MIN_WINDOWS}): the overlap of the recordings '
            f'({span_s:.0f} s) is too short, or moves too little, to observe a drift'
        )
    slope, icpt = repeated_medians_line(x[ok], offsets_s[ok])
    resid = offsets_s - (icpt + slope * x)
    sigma = 1.4826 * float(np.median(np.abs(resid[ok])))
    inl = ok & (np.abs(resid) <= max(INLIER_SIGMAS * sigma, INLIER_FLOOR_S))
    if inl.sum() < MIN_WINDOWS or np.ptp(x[inl]) <= 0.0:
        return none(
            f'only {int(inl.sum())} window offsets agree with one line (need '
            f'{MIN_WINDOWS}): the offset does not change linearly along the recording'
        )
    slope, icpt, stderr = least_squares_line(x[inl], offsets_s[inl])
    if inl.sum() == 2 or not np.isfinite(stderr):
        return none('the window offsets cannot give an uncertainty')
    # the fit's own scatter, but never below what a window can resolve: windows that agree
    # exactly (a noise-free simulation) would otherwise claim a zero uncertainty
    floor = INLIER_FLOOR_S / np.sqrt(inl.sum())
    xc = x[inl] - x[inl].mean()
    slope_std = max(stderr, floor / max(float(np.sqrt(np.mean(xc**2))), 1e-9))
    off = float(icpt + slope * x[inl].mean())
    ref = int(stamp_ns + np.int64(round(float(x[inl].mean()) * 1e9)))
    off_std = max(
        float(np.std(offsets_s[inl] - (icpt + slope * x[inl]), ddof=2)) / np.sqrt(inl.sum()), floor
    )
    return DriftFit(
        slope, slope_std, off, off_std, ref, span_s, centres_ns, offsets_s, correlation, inl
    )


def repeated_medians_line(x: Floats, y: Floats) -> tuple[float, float]:
    """(slope, intercept) of Siegel's repeated-medians line, as scipy.stats.siegelslopes
    (hierarchical): the median over i of the median over j != i of the slopes through points
    i and j, and the median of y - slope x. Robust to nearly half the points being wild.
    (Written out for the few windows here: importing scipy.stats would take 1.3 s of every
    run; test/core/time/test_clock.py checks it against scipy's.)"""
    dx = x[None, :] - x[:, None]
    dy = y[None, :] - y[:, None]
    with np.errstate(divide='ignore', invalid='ignore'):
        slopes = np.where(dx != 0.0, dy / np.where(dx != 0.0, dx, 1.0), np.nan)
    slope = float(np.median(np.nanmedian(slopes, axis=1)))
    return slope, float(np.median(y - slope * x))


def least_squares_line(x: Floats, y: Floats) -> tuple[float, float, float]:
    """(slope, intercept, the slope's standard error) of the least-squares line, as
    scipy.stats.linregress (n - 2 degrees of freedom)."""
    xm, ym = float(np.mean(x)), float(np.mean(y))
    sxx = float(np.sum((x - xm) ** 2))
    if not sxx > 0.0 or x.size < 3:
        return float('nan'), float('nan'), float('nan')
    slope = float(np.sum((x - xm) * (y - ym)) / sxx)
    icpt = ym - slope * xm
    resid = y - (icpt + slope * x)
    return slope, icpt, float(np.sqrt(np.sum(resid**2) / (x.size - 2) / sxx))


def measure_drift(
    hand: Trajectory,
    eye: Trajectory,
    R_HE: Floats | None = None,
    resample_rate_hz: float | None = None,
    start: DriftFit | None = None,
    around_s: float = 0.0,
) -> DriftFit:
    """The linear clock of an eye already on the hand's clock up to a small offset.

    Two passes: the first searches each window as far as MAX_DRIFT can move its offset (or
    around ``start``'s line when given), the second around the first line within a few of its
    robust sigmas (a window that locked onto a wrong peak the first time is searched again where
    its offset should be). ``around_s``: the offset the eye has at the reference stamp.
    """
    first, last, mean = covered_span(hand, eye)
    span = (last - first) * 1e-9
    bounds = window_bounds(first, last)
    centres = (bounds[:, 0] + (bounds[:, 1] - bounds[:, 0]) // 2).astype(np.int64)
    if start is not None and start.estimated:
        pred = np.asarray(start.offset_at(centres), float)
        half = np.full(
            centres.size,
            max(
                SECOND_PASS_MIN_S,
                SECOND_PASS_SIGMAS
                * max(start.offset_std * np.sqrt(max(start.inliers.sum(), 1)), INLIER_FLOOR_S),
            ),
        )
    else:
        pred = np.full(centres.size, around_s)
        half = MAX_DRIFT * np.abs((centres - mean) * 1e-9) + SEARCH_MARGIN_S
    signals = stream_signals(hand, eye, R_HE)
    fit = fit_drift(
        *window_offsets(hand, eye, bounds, pred, half, R_HE, resample_rate_hz, signals), mean, span
    )
    if not fit.estimated:
        return fit
    resid = fit.offsets_s[fit.inliers] - np.asarray(fit.offset_at(fit.centres_ns[fit.inliers]))
    sigma = 1.4826 * float(np.median(np.abs(resid)))
    half2 = max(SECOND_PASS_MIN_S, SECOND_PASS_SIGMAS * sigma)
    again = fit_drift(
        *window_offsets(
            hand,
            eye,
            bounds,
            np.asarray(fit.offset_at(centres)),
            half2,
            R_HE,
            resample_rate_hz,
            signals,
        ),
        mean,
        span,
    )
    return again if again.estimated else fit


def retime(traj: Trajectory, drift: float, stamp_ns: int) -> Trajectory:
    """The eye on a clock without drift: stamps ``t - drift (t - stamp)`` (int64 ns).

    An eye stamp t of the linear clock ``dt(t) = offset + drift (t - stamp)`` becomes one whose
    offset to the hand is the constant ``offset``.
    """
    if drift == 0.0:
        return traj
    if not abs(drift) < 0.5:
        msg = f'a clock drift of {drift:g} s/s is not a clock drift'
        raise ValueError(msg)
    rel = (traj.t_ns - np.int64(stamp_ns)).astype(float)
    return replace(traj, t_ns=traj.t_ns - np.rint(drift * rel).astype(np.int64))
