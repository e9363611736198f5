"""Stage 1's signals: the angular speed (or velocity) of a stream on its own uniform grid,
robust and standardised, ready to correlate (:mod:`.align`).

Both speeds are computed on each stream's own stamps (rotation angle of consecutive poses over
their interval, at the interval midpoint so the finite difference is unbiased in time; never
across a gap or a break), resampled onto a uniform grid *of their own* (each anchored at its
stream's first stamp, so that the grids, the FFT and the memory follow the recordings' lengths
and never the size of the offset), clipped at a robust level and standardised.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import Floats, Mask
from ..errors import TimeAlignmentError
from ..geometry import consecutive_rotvecs, row_norms
from ..trajectory import Trajectory

#: Angular speeds are averages over at least this interval [s] (:func:`spans`): a hand-held or
#: flying motion's angular speed has little content above ~10 Hz, which a 25-ms average keeps
#: (a 10 Hz sine loses 10 %), while a jittery MoCap's differenced noise falls with the interval
#: (1 kHz with 0.1 deg a pose: some 45 deg/s over the 5 ms of a 200 Hz eye, 9 deg/s over 25 ms).
MIN_SPEED_SPAN_S = 0.025
#: The resampling rate is the faster stream's rate, capped here: 200 Hz resolves the shape of
#: any hand-held motion (whose angular speed has little content above ~10 Hz) and bounds the
#: FFT length of long recordings.
MAX_RESAMPLE_RATE_HZ = 200.0


#: Most samples of one resampled signal (2^23: 11.6 h at 200 Hz). Longer streams are resampled
#: more coarsely, down to MIN_RESAMPLE_RATE_HZ; beyond that the span is refused, which also
#: bounds the memory whatever the stamps say.
MAX_GRID_SAMPLES = 2**23


MIN_RESAMPLE_RATE_HZ = 20.0


#: Signal samples beyond median + MASK_SIGMAS robust standard deviations (1.4826 MAD) are
#: left out like a gap (a spike no motion made: leaving it in, even clipped, puts a plateau
#: into one signal only); the rest are clipped at median + CLIP_SIGMAS.
MASK_SIGMAS = 8.0


CLIP_SIGMAS = 4.0


#: ... where the median and MAD are also taken in blocks of this length (s), and a sample is
#: held to the higher of the whole signal's level and its own block's (or a neighbour's): a
#: recording of mixed pace (a minute of fast hand-held motion in the MoCap room, then ten of
#: walking outdoors) keeps its fast minutes, which the whole signal's level would mask as
#: spikes, while a spike stays a spike against its own block.
LEVEL_BLOCK_S = 20.0


@dataclass(frozen=True)
class AngularSpeed:
    """Body angular speed (or velocity) of one stream.

    Attributes
    ----------
    t_s : ndarray, shape (M,)
        Interval midpoints, seconds from the stream's first stamp, on the stream's own clock.
    speed : ndarray, shape (M,) or (M, 3)
        Rotation angle over the interval divided by its length, rad/s (the magnitude is
        frame-independent), or the body angular velocity ``Log(R_k^T R_k+1) / dt`` (rad/s, in
        the body frame).
    valid : ndarray, shape (M,), bool
        False for intervals that span a gap or a break.
    span : int
        How many of the stream's intervals each sample spans (:func:`angular_speed`).
    """

    t_s: Floats
    speed: Floats
    valid: Mask
    span: int = 1

    def part(self, traj: Trajectory, first: int, stop: int) -> AngularSpeed:
        """The signal of the poses ``first..stop-1`` of the stream ``traj`` it was computed
        from, with times from the first of them: what :func:`angular_speed` gives for that part
        (a stream measured in windows is differenced once, not once per window)."""
        shift = (int(traj.t_ns[first]) - int(traj.t_ns[0])) * 1e-9
        k = slice(first, max(stop - self.span, first))
        return AngularSpeed(self.t_s[k] - shift, self.speed[k], self.valid[k], self.span)


def angular_speed(traj: Trajectory, vector: bool = False, span: int = 1) -> AngularSpeed:
    """Angular speed (or body angular velocity, ``vector``) over ``span`` consecutive intervals
    (poses k and k + span), at their midpoints in seconds from the stream's first stamp (see
    :class:`AngularSpeed`); valid where none of the intervals is a gap or a break."""
    # kept with the trajectory: stages 1 and 2 and the clock windows ask for the same stream's
    # (an hour of 1 kHz MoCap is a second to difference)
    key = f'_angular_velocity_{span}'
    cached = traj.__dict__.get(key)
    if cached is None:
        t = traj.seconds(int(traj.t_ns[0]))
        span = min(span, max(len(traj) - 1, 1))
        bad = np.concatenate(([0], np.cumsum(~traj.interval_ok())))
        cached = AngularSpeed(
            0.5 * (t[span:] + t[:-span]),
            consecutive_rotvecs(traj.q_xyzw, span) / (t[span:] - t[:-span])[:, None],
            bad[span:] == bad[:-span],
            span,
        )
        object.__setattr__(traj, key, cached)  # frozen: a cache, not state
    if vector:
        return cached
    return AngularSpeed(cached.t_s, row_norms(cached.speed), cached.valid, cached.span)


def spans(hand: Trajectory, eye: Trajectory) -> tuple[int, int]:
    """How many of its intervals each stream's angular speed spans (:func:`angular_speed`): the
    slower stream's period, at least MIN_SPEED_SPAN_S, so that both are averages over one
    interval. A stream's white noise, which differencing over a short interval amplifies (1 kHz
    MoCap with 0.1 deg of jitter: 140 deg/s over its own 1 ms), is then averaged down."""
    period = max(1.0 / hand.rate_hz, 1.0 / eye.rate_hz, MIN_SPEED_SPAN_S)
    return max(1, round(period * hand.rate_hz)), max(1, round(period * eye.rate_hz))


def resample(sig: AngularSpeed, grid_s: Floats, shift_s: float = 0.0) -> tuple[Floats, Mask]:
    """Linear interpolation of a signal at ``grid_s + shift_s``.

    Returns values (shape of the grid, with a trailing 3 for vectors) and a mask that is False
    outside the signal's support and between two samples of which either lies in a gap.
    """
    t = grid_s + shift_s
    k = np.searchsorted(sig.t_s, t)
    inside = (k > 0) & (k < sig.t_s.size)
    kc = np.clip(k, 1, sig.t_s.size - 1)
    ok = inside & sig.valid[kc - 1] & sig.valid[kc]
    if sig.speed.ndim == 1:
        values: Floats = np.where(ok, np.interp(t, sig.t_s, sig.speed), 0.0)
    else:
        values = np.stack([np.interp(t, sig.t_s, sig.speed[:, a]) for a in range(3)], axis=1)
        values[~ok] = 0.0
    return values, ok


def grid(traj: Trajectory, step: float) -> Floats:
    """Uniform grid over a stream's span, seconds from its first stamp."""
    return step * np.arange(int(np.floor(traj.duration_s / step)) + 1)


def grid_step(hand: Trajectory, eye: Trajectory, resample_rate_hz: float | None) -> float:
    """Grid step: the faster stream's rate (at most 200 Hz), coarser for very long streams."""
    rate = resample_rate_hz or min(max(hand.rate_hz, eye.rate_hz), MAX_RESAMPLE_RATE_HZ)
    longest = max(hand.duration_s, eye.duration_s)
    if longest * rate > MAX_GRID_SAMPLES:
        rate = MAX_GRID_SAMPLES / longest
        if rate < MIN_RESAMPLE_RATE_HZ:
            msg = (
                f'{hand.name} spans {hand.duration_s:.4g} s and {eye.name} '
                f'{eye.duration_s:.4g} s: too long to correlate at {MIN_RESAMPLE_RATE_HZ:g} '
                'Hz or more. Are the stamps in the unit the format expects (seconds for TUM, '
                'nanoseconds for EuRoC)? Otherwise cut the recording into parts'
            )
            raise TimeAlignmentError(msg)
    return 1.0 / rate


def clip_signal(v: Floats, mask: Mask, step: float) -> tuple[Floats, Mask]:
    """A robust signal: samples beyond median + MASK_SIGMAS robust deviations (1.4826 MAD) are
    masked out like a gap, the others clipped at median + CLIP_SIGMAS (vectors by their
    norm), each at the higher of the whole signal's level and its block's
    (:data:`LEVEL_BLOCK_S`). Returns (values, mask)."""
    if mask.sum() < 3:  # standardise refuses it with its own message
        return v, mask
    mag = np.abs(v) if v.ndim == 1 else row_norms(v)
    med, dev = _median_mad(mag[mask])
    if not dev > 0.0:
        return v, mask
    mask_level, clip_level = _levels(mag, mask, step, med, dev)
    mask = mask & (mag <= mask_level)
    scale = np.minimum(1.0, clip_level / np.maximum(mag, 1e-300))
    clipped: Floats = v * (scale if v.ndim == 1 else scale[:, None])
    return clipped, mask


def _median_mad(values: Floats) -> tuple[float, float]:
    """Median and robust standard deviation (1.4826 MAD)."""
    med = float(np.median(values))
    return med, 1.4826 * float(np.median(np.abs(values - med)))


def _levels(mag: Floats, mask: Mask, step: float, med: float, dev: float) -> tuple[Floats, Floats]:
    """Per-sample mask and clip levels: the whole signal's, raised to its block's where that
    is higher (the highest of the block and its two neighbours, so that a block boundary
    inside a fast stretch changes nothing)."""
    n = max(1, round(LEVEL_BLOCK_S / step))
    n_blocks = mag.size // n
    levels = np.array([med + MASK_SIGMAS * dev, med + CLIP_SIGMAS * dev])
    if n_blocks < 2:
        return levels[0], levels[1]
    block = np.tile(levels[:, None], n_blocks)
    for b in range(n_blocks):
        part = mag[b * n : (b + 1) * n][mask[b * n : (b + 1) * n]]
        if part.size >= n // 4:  # a block mostly in a gap says nothing of its own
            m, d = _median_mad(part)
            block[:, b] = np.maximum(block[:, b], (m + MASK_SIGMAS * d, m + CLIP_SIGMAS * d))
    padded = np.pad(block, ((0, 0), (1, 1)), mode='edge')
    block = np.maximum(np.maximum(padded[:, :-2], padded[:, 1:-1]), padded[:, 2:])
    index = np.minimum(np.arange(mag.size) // n, n_blocks - 1)
    return block[0, index], block[1, index]


def standardise(v: Floats, mask: Mask, name: str) -> Floats:
    """Zero mean, unit variance over the valid samples (keeps the FFT sums well scaled)."""
    if mask.sum() < 3:
        msg = f'{name}: too few samples to compute an angular speed signal'
        raise TimeAlignmentError(msg)
    mean = v[mask].mean(axis=0)
    std = np.sqrt(np.sum(v[mask].var(axis=0)))
    if not std > 1e-9:
        msg = (
            f'{name}: the angular speed is constant ({np.linalg.norm(mean):.3g} rad/s); the '
            'time offset cannot be observed. Record a motion with varying rotation'
        )
        raise TimeAlignmentError(msg)
    out: Floats = (v - mean) / std
    out[~mask] = 0.0
    return out
