"""Stage 1: the time offset from angular-speed correlation (paper Section III-A).

Why this works: a rigid hand-eye rig turns at one angular rate, so the body angular speed
``|w_H(t)|`` of the MoCap marker and ``|w_E(t)|`` of the VIO body are the same signal, whatever
T_HE and T_WG are; only the clock differs. With the convention ``T_WE(t) = T_WG T_GH(t - dt) T_HE``
the eye signal is the hand signal delayed by dt: ``|w_E|(t) = |w_H|(t - dt)``, so the
cross-correlation ``c(tau) = sum_t |w_E|(t + tau) |w_H|(t)`` peaks at ``tau = dt`` (eq. 1).

Both speeds are computed on each stream's own stamps (rotation angle of consecutive poses over
their interval, placed at the interval midpoint so the finite difference is unbiased in time),
resampled onto one uniform grid, standardised, and correlated with a masked normalised
cross-correlation (FFT), which stays correct across gaps and partial overlap. The integer peak is
refined by a parabola through the peak and its two neighbours (the paper's quadratic fit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import fft

from .errors import TimeAlignmentError
from .geometry import matrix_from_quat, rotation_angle
from .trajectory import Trajectory

#: An interval longer than this many median sample periods is a gap: no speed is interpolated
#: across it. 3.5 tolerates two consecutive dropped samples, which still give a fair average.
GAP_FACTOR = 3.5
#: A lag is only considered where the two signals overlap on at least this fraction of the
#: shorter one: with little overlap a normalised correlation is high by chance.
MIN_OVERLAP_FRACTION = 0.5
#: ... and on at least this many seconds.
MIN_OVERLAP_S = 5.0
#: The resampling rate is the faster stream's rate, capped here: 200 Hz resolves the shape of
#: any hand-held motion (whose angular speed has little content above ~10 Hz) and bounds the
#: FFT length of long recordings.
MAX_RESAMPLE_RATE_HZ = 200.0


@dataclass(frozen=True)
class AngularSpeed:
    """Body angular speed of one stream.

    Attributes
    ----------
    t_s : ndarray, shape (M,)
        Interval midpoints, seconds from the common origin, on the stream's own clock.
    speed : ndarray, shape (M,)
        Rotation angle over the interval divided by its length, rad/s (body or world frame
        alike: the magnitude is frame-independent).
    valid : ndarray, shape (M,), bool
        False for intervals that span a gap.
    """

    t_s: np.ndarray
    speed: np.ndarray
    valid: np.ndarray


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
        Normalised correlation at the peak, in [-1, 1]; 1 means the speed profiles agree exactly.
    second_peak_ratio : float
        Highest correlation outside the main lobe divided by the peak's; near 1 means an
        ambiguous (periodic) motion.
    step_s : float
        Lag resolution of the correlation grid, seconds.
    window_s : tuple of float
        Searched offsets (min, max), seconds.
    lags_s, correlation : ndarray
        The correlation curve over the window, for plots and diagnostics.
    """

    time_offset_s: float
    method: str
    peak_correlation: float = float('nan')
    second_peak_ratio: float = float('nan')
    step_s: float = float('nan')
    window_s: tuple[float, float] = (float('nan'), float('nan'))
    lags_s: np.ndarray | None = None
    correlation: np.ndarray | None = None


def angular_speed(traj: Trajectory, origin_ns: int) -> AngularSpeed:
    """Angular speed of a trajectory from consecutive orientations (see :class:`AngularSpeed`)."""
    t = traj.seconds(origin_ns)
    R = matrix_from_quat(traj.q_xyzw)
    dR = np.matmul(np.swapaxes(R[:-1], -1, -2), R[1:])
    dt = np.diff(t)
    valid = dt <= GAP_FACTOR * np.median(dt)
    return AngularSpeed(0.5 * (t[1:] + t[:-1]), rotation_angle(dR) / dt, valid)


def resample(sig: AngularSpeed, grid_s: np.ndarray, shift_s: float = 0.0) -> tuple[np.ndarray,
                                                                                   np.ndarray]:
    """Linear interpolation of a speed signal at ``grid_s + shift_s``.

    Returns values and a mask that is False outside the signal's support and between two
    samples of which either lies in a gap.
    """
    t = grid_s + shift_s
    k = np.searchsorted(sig.t_s, t)
    inside = (k > 0) & (k < sig.t_s.size)
    kc = np.clip(k, 1, sig.t_s.size - 1)
    ok = inside & sig.valid[kc - 1] & sig.valid[kc]
    values = np.interp(t, sig.t_s, sig.speed)
    return np.where(ok, values, 0.0), ok


def masked_normalised_correlation(y: np.ndarray, my: np.ndarray, x: np.ndarray,
                                  mx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pearson correlation of ``y[k + lag]`` with ``x[k]`` over the samples valid in both.

    For each lag the mean and variance are those of the overlapping valid samples only
    (Padfield's masked normalised cross-correlation), all sums computed by FFT.

    Returns
    -------
    lags : ndarray of int, shape (len(y) + len(x) - 1,)
    ncc : ndarray, same shape, NaN where the overlap has no variance
    overlap : ndarray, same shape, number of samples valid in both
    """
    fy, fx = my.astype(float), mx.astype(float)
    y, x = y * fy, x * fx
    # One zero-padded FFT per signal, then every sum is a product of spectra: 6 forward and
    # 5 inverse transforms for the whole masked correlation. (scipy.fft rather than
    # scipy.signal, whose import alone takes a second.)
    nfft = fft.next_fast_len(y.size + x.size - 1, real=True)
    Y, FY, YY = (fft.rfft(v, nfft) for v in (y, fy, y * y))
    X, FX, XX = (np.conj(fft.rfft(v, nfft)) for v in (x, fx, x * x))

    def corr(A: np.ndarray, B: np.ndarray) -> np.ndarray:
        c = fft.irfft(A * B, nfft)  # c[L] = sum_m a[m + L] b[m], negative L wrapped to the end
        return np.concatenate((c[nfft - (x.size - 1):], c[:y.size]))

    n = np.rint(corr(FY, FX))
    sy, sx = corr(Y, FX), corr(FY, X)
    syy, sxx = corr(YY, FX), corr(FY, XX)
    sxy = corr(Y, X)
    with np.errstate(divide='ignore', invalid='ignore'):
        cov = sxy - sy * sx / n
        var = (syy - sy * sy / n) * (sxx - sx * sx / n)
        ncc = np.where((n > 1) & (var > 0.0), cov / np.sqrt(np.abs(var)), np.nan)
    lags = np.arange(-(x.size - 1), y.size)
    return lags, ncc, n


def align_time(hand: Trajectory, eye: Trajectory, *, max_time_offset: float = 0.5,
               time_offset_guess: float = 0.0, resample_rate_hz: float | None = None,
               peak_fit: str = 'quadratic') -> TimeAlignment:
    """Estimate dt (eye clock minus hand clock) within ``guess +- max_time_offset`` seconds.

    Raises
    ------
    TimeAlignmentError
        When the streams do not overlap enough at any searched offset, when the motion has no
        variation in angular speed, or when the correlation peaks at the window's edge (the
        offset is then most likely outside the window).
    """
    if peak_fit not in ('quadratic', 'none'):
        msg = f"peak_fit must be 'quadratic' or 'none', got {peak_fit!r}"
        raise ValueError(msg)
    origin = int(hand.t_ns[0])
    w_h = angular_speed(hand, origin)
    w_e = angular_speed(eye, origin)
    rate = resample_rate_hz or min(max(hand.rate_hz, eye.rate_hz), MAX_RESAMPLE_RATE_HZ)
    step = 1.0 / rate
    # Eye stamps are moved by the guess first, so the residual lag is searched around zero.
    start = min(w_h.t_s[0], w_e.t_s[0] - time_offset_guess)
    stop = max(w_h.t_s[-1], w_e.t_s[-1] - time_offset_guess)
    grid = start + step * np.arange(int(np.floor((stop - start) / step)) + 1)
    x, mx = resample(w_h, grid)
    y, my = resample(w_e, grid, shift_s=time_offset_guess)
    x = _standardise(x, mx, hand.name)
    y = _standardise(y, my, eye.name)

    lags, ncc, overlap = masked_normalised_correlation(y, my, x, mx)
    half = int(np.ceil(max_time_offset / step))
    need = max(MIN_OVERLAP_S / step, MIN_OVERLAP_FRACTION * min(mx.sum(), my.sum()))
    window = (np.abs(lags) <= half)
    eligible = window & (overlap >= need) & np.isfinite(ncc)
    lo, hi = time_offset_guess - half * step, time_offset_guess + half * step
    if not eligible.any():
        msg = (f'{hand.name} and {eye.name} do not overlap in time by at least '
               f'{need * step:.1f} s at any offset in [{lo:+.3f}, {hi:+.3f}] s '
               f'(hand covers {hand.duration_s:.1f} s, eye {eye.duration_s:.1f} s, eye starts '
               f'{(eye.t_ns[0] - hand.t_ns[0]) * 1e-9:+.3f} s after hand). If the clocks differ '
               'by more, pass a time_offset_guess near the difference')
        raise TimeAlignmentError(msg)
    scores = np.where(eligible, ncc, -np.inf)
    k = int(np.argmax(scores))
    win_idx = np.flatnonzero(eligible)
    if k in (win_idx[0], win_idx[-1]) or not (eligible[k - 1] and eligible[k + 1]):
        msg = (f'the angular-speed correlation peaks at the edge of the search window '
               f'[{lo:+.3f}, {hi:+.3f}] s (at {time_offset_guess + lags[k] * step:+.3f} s): the '
               'time offset is probably outside it. Widen max_time_offset or move '
               'time_offset_guess')
        raise TimeAlignmentError(msg)
    frac = _parabola_vertex(*ncc[k - 1:k + 2]) if peak_fit == 'quadratic' else 0.0
    sel = slice(win_idx[0], win_idx[-1] + 1)
    return TimeAlignment(
        time_offset_s=float(time_offset_guess + (lags[k] + frac) * step),
        method=peak_fit,
        peak_correlation=float(ncc[k]),
        second_peak_ratio=_second_peak_ratio(scores[sel], k - win_idx[0]),
        step_s=step,
        window_s=(lo, hi),
        lags_s=time_offset_guess + lags[sel] * step,
        correlation=ncc[sel],
    )


def _standardise(v: np.ndarray, mask: np.ndarray, name: str) -> np.ndarray:
    """Zero mean, unit variance over the valid samples (keeps the FFT sums well scaled)."""
    if mask.sum() < 3:
        msg = f'{name}: too few samples to compute an angular speed signal'
        raise TimeAlignmentError(msg)
    mean = v[mask].mean()
    std = v[mask].std()
    if not std > 1e-9:
        msg = (f'{name}: the angular speed is constant ({mean:.3g} rad/s); the time offset '
               'cannot be observed. Record a motion with varying rotation')
        raise TimeAlignmentError(msg)
    return np.where(mask, (v - mean) / std, 0.0)


def _parabola_vertex(c_minus: float, c0: float, c_plus: float) -> float:
    """Sub-sample position, in (-0.5, 0.5), of the vertex of the parabola through 3 samples."""
    den = c_minus - 2.0 * c0 + c_plus
    if not den < 0.0:  # flat or not a maximum: keep the integer peak
        return 0.0
    return float(np.clip(0.5 * (c_minus - c_plus) / den, -0.5, 0.5))


def _second_peak_ratio(scores: np.ndarray, k: int) -> float:
    """Best correlation outside the main lobe (bounded by the nearest local minima) over peak."""
    d = np.diff(scores)
    left = np.flatnonzero(d[:k] < 0.0)  # a rise towards the left of the peak ends the lobe
    right = np.flatnonzero(d[k:] > 0.0)
    lo = left[-1] + 1 if left.size else 0
    hi = k + right[0] if right.size else scores.size - 1
    outside = np.concatenate((scores[:lo], scores[hi + 1:]))
    outside = outside[np.isfinite(outside)]
    if not outside.size or scores[k] <= 0.0:
        return 0.0
    return float(max(outside.max(), 0.0) / scores[k])
