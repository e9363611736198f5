"""Readiness: can the data so far calibrate to the required precision, and if not, what do they
lack, said in the frame of the device the user holds (the eye E).

The prediction is the batch stage's white covariance (eq. 15-16) without running the batch
stage: the eye's relative poses between consecutive frames (the residuals of eq. 16) at stage 1's
offset and stage 2's T_HE give the noise (robust sigmas of their residuals), and their Jacobians
in (dt, T_HE) the information; its inverse is the covariance the batch stage would report if
the residuals were white. The derivative in dt is a central difference over one knot spacing,
as smooth as the batch stage's spline, so that the MoCap's own noise does not pass for motion.

Which direction is missing follows from the motions' screw axes: a rotation about an axis a
says nothing of T_HE's rotation about a, nor of its translation along a (eq. 2). So the
covariance's widest direction, in the device's axes, names the axis the device has mostly turned
about, and the advice is to turn it about the other two.

The targets are the verdict's own (``precision_time_offset``, ``precision_translation``,
``precision_rotation``): ready means a calibration now would not be ``imprecise``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..association import interpolate, residual_motions
from ..chunked import CHUNK_ROWS, chunked
from ..config import CalibrationConfig
from ..errors import HandeyeError
from ..geometry import (
    consecutive_rotvecs,
    exp_so3,
    log_so3,
    matrix_from_quat,
    relative,
)
from ..linear.solve import solve_linear
from ..time.align import MIN_OVERLAP_S, align_time
from ..trajectory import Trajectory
from .verdict import AMBIGUOUS_PEAK_RATIO, WEAK_CORRELATION, precision_ratio, precision_ratios

#: The device's axes, as the advice names them.
AXES = ('x', 'y', 'z')
#: Slower than this RMS angular speed (deg/s), the device is held still.
STILL_DPS = 2.0
#: Below this RMS angular speed (deg/s), "turn faster" is part of the advice for dt.
SLOW_DPS = 30.0
#: The stream health looks at this much of the latest data (s).
RECENT_S = 10.0
#: A stream missing more than this fraction of its recent samples is said to drop out.
DROPOUT_FRACTION = 0.05
#: Shorter streams cannot be aligned in time: stage 1 wants MIN_OVERLAP_S of overlap at the
#: offsets it searches, some of which overlap only partly.
MIN_RECORDING_S = 2.0 * MIN_OVERLAP_S
#: Residuals beyond this many robust sigmas are left out, as Huber's loss nearly does.
OUTLIER_SIGMAS = 5.0
#: At most this many consecutive eye pairs are differentiated; a longer recording uses every
#: k-th pair and scales their information by k (a cost cap: 100 s at 200 Hz; neighbouring
#: pairs carry nearly the same information, and an hour would otherwise cost seconds).
MAX_PAIRS = 20_000


@dataclass(frozen=True)
class Readiness:
    """What the data support.

    ready: the predicted 1-sigmas are within the targets and nothing blocks a calibration.
    sigma: predicted 1-sigma of dt [s], T_HE's translation [m] (norm of the three) and rotation
    [deg] (norm), NaN when not predicted; target: the same three required.
    rotation_deg: (3,) how far the device has turned about its x, y, z axes (sum of |rotation|
    about each, deg); hand_rotation_deg: the same about the MoCap marker's axes.
    angular_speed_dps: the device's RMS angular speed; travel_m: the marker's path length;
    motions: keyframe motions (rotating by eta, eq. 6) stage 2 had; span_s: the streams' overlap
    at the offset; time_offset_s: stage 1's offset (None when it failed); peak_correlation,
    second_peak_ratio: its correlation peak and runner-up ratio; dropout: the fraction of the
    last RECENT_S each stream misses; missing: what to do, in the user's words, most important
    first.
    """

    ready: bool
    sigma: tuple[float, float, float]
    target: tuple[float, float, float]
    rotation_deg: np.ndarray
    hand_rotation_deg: np.ndarray
    angular_speed_dps: float
    travel_m: float
    motions: int = 0
    span_s: float = 0.0
    time_offset_s: float | None = None
    peak_correlation: float = float('nan')
    second_peak_ratio: float = float('nan')
    dropout: dict[str, float] = field(default_factory=dict)
    missing: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        """The ``readiness`` section of a result, and the node's status values."""

        def num(v: float, k: float = 1.0) -> float | None:
            return float(v) * k if np.isfinite(v) else None

        return {
            'ready': bool(self.ready),
            'sigma': {
                'time_offset_ms': num(self.sigma[0], 1e3),
                'translation_mm': num(self.sigma[1], 1e3),
                'rotation_deg': num(self.sigma[2]),
            },
            'target': {
                'time_offset_ms': self.target[0] * 1e3,
                'translation_mm': self.target[1] * 1e3,
                'rotation_deg': self.target[2],
            },
            'rotation_deg': dict(zip(AXES, np.round(self.rotation_deg, 1).tolist(), strict=True)),
            'hand_rotation_deg': dict(
                zip(AXES, np.round(self.hand_rotation_deg, 1).tolist(), strict=True)
            ),
            'angular_speed_dps': round(float(self.angular_speed_dps), 2),
            'travel_m': round(float(self.travel_m), 3),
            'motions': int(self.motions),
            'span_s': round(float(self.span_s), 2),
            'time_offset_s': None if self.time_offset_s is None else float(self.time_offset_s),
            'peak_correlation': num(self.peak_correlation),
            'second_peak_ratio': num(self.second_peak_ratio),
            'dropout': {k: round(float(v), 3) for k, v in self.dropout.items()},
            'missing': list(self.missing),
        }


@dataclass(frozen=True)
class Known:
    """A calibration already made on the same data (offline: the result's own), so that the
    prediction needs no stage 1 or 2 of its own."""

    time_offset_s: float
    R_HE: np.ndarray
    p_HE: np.ndarray
    motions: int
    peak_correlation: float = float('nan')
    second_peak_ratio: float = float('nan')


def readiness(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig, known: Known | None = None
) -> Readiness:
    """How far ``hand`` and ``eye`` (both on their own clocks) can calibrate, and what they
    lack; never raises for data that cannot calibrate (that is what it says)."""
    target = cfg.precision
    nan3 = (float('nan'),) * 3
    if len(hand) < 3 or len(eye) < 3:
        return _empty(target, 'no data yet: both streams need poses')
    rot_e, speed = _turned(eye)
    rot_h, _ = _turned(hand)
    travel = float(np.sum(np.linalg.norm(np.diff(hand.p_xyz, axis=0), axis=1)))
    base = {
        'rotation_deg': rot_e,
        'hand_rotation_deg': rot_h,
        'angular_speed_dps': speed,
        'travel_m': travel,
        'dropout': {'hand': _dropout(hand), 'eye': _dropout(eye)},
    }
    health = _health(base['dropout'])
    if speed < STILL_DPS:
        return Readiness(
            False, nan3, target, **base, missing=('the device is held still: move it', *health)
        )
    short = min(hand.duration_s, eye.duration_s)
    if known is None and short < MIN_RECORDING_S:
        keep = (
            f'keep recording: {short:.0f} s of both streams so far, {MIN_RECORDING_S:.0f} s needed'
        )
        return Readiness(False, nan3, target, **base, missing=(keep, *health))
    try:
        known = known or _calibrate(hand, eye, cfg)
    except HandeyeError as err:
        return Readiness(False, nan3, target, **base, missing=(_plain(err), *health))
    sigma, span, advice = _predict(hand, eye, known, cfg, speed)
    blocks = []
    if known.peak_correlation < WEAK_CORRELATION:
        blocks.append(
            f'the two streams turn alike only weakly (correlation {known.peak_correlation:.2f}):'
            ' check that the MoCap tracks the device itself'
        )
    if known.second_peak_ratio > AMBIGUOUS_PEAK_RATIO:
        blocks.append(
            'the motion repeats itself, so the time offset is ambiguous: vary the motion'
        )
    ok = precision_ratio(sigma, target) <= 1.0
    return Readiness(
        ok and not blocks,
        sigma,
        target,
        **base,
        motions=known.motions,
        span_s=span,
        time_offset_s=known.time_offset_s,
        peak_correlation=known.peak_correlation,
        second_peak_ratio=known.second_peak_ratio,
        missing=(*blocks, *advice, *health),
    )


def _empty(target: tuple[float, float, float], why: str) -> Readiness:
    zero = np.zeros(3)
    return Readiness(False, (float('nan'),) * 3, target, zero, zero, 0.0, 0.0, missing=(why,))


#: The turn about each axis is summed over steps this long (s): summed over every pose's step,
#: it summed each pose's noise too (a noisy planar recording 'turned' 859 deg about an axis
#: it never turned about, and the advice then thought that axis done).
TURN_STEP_S = 0.2


def _turned(traj: Trajectory) -> tuple[np.ndarray, float]:
    """(3,) how far the body turned about each of its axes (deg) and its RMS angular speed
    (deg/s), from its rotations over steps of about TURN_STEP_S that span no gap."""
    if len(traj) < 2:
        return np.zeros(3), 0.0
    period = float(np.median(np.diff(traj.t_ns))) * 1e-9
    idx = np.arange(0, len(traj), max(1, round(TURN_STEP_S / max(period, 1e-9))))
    gaps = np.concatenate(([0], np.cumsum(~traj.interval_ok())))
    whole = gaps[idx[1:]] == gaps[idx[:-1]]  # no gap or break inside the step
    if not np.any(whole):
        return np.zeros(3), 0.0
    turn = consecutive_rotvecs(traj.q_xyzw[idx])[whole]  # rad, body frame
    seconds = np.diff(traj.t_ns[idx])[whole] * 1e-9
    rate = turn / seconds[:, None]  # rad/s
    rms = float(np.degrees(np.sqrt(np.mean(np.sum(rate**2, axis=1)))))
    return np.degrees(np.sum(np.abs(turn), axis=0)), rms


def _dropout(traj: Trajectory) -> float:
    """The fraction of the stream's samples missing over its last RECENT_S (0 for a keyframe
    stream, whose rate is its own)."""
    if traj.keyframes or len(traj) < 3:
        return 0.0
    period = float(np.median(np.diff(traj.t_ns))) * 1e-9
    t = traj.seconds(int(traj.t_ns[-1]))
    span = min(RECENT_S, -float(t[0]))
    if span <= 10 * period:
        return 0.0
    got = int(np.sum(t > -span))
    return float(np.clip(1.0 - got * period / span, 0.0, 1.0))


def _health(dropout: dict[str, float]) -> list[str]:
    who = {'hand': 'the MoCap lost the marker', 'eye': 'the device stream misses poses'}
    return [
        f'{who[s]} {f:.0%} of the last {RECENT_S:.0f} s'
        for s, f in dropout.items()
        if f > DROPOUT_FRACTION
    ]


def _plain(err: HandeyeError) -> str:
    """A refusal of stage 1 or 2 as advice: its first sentence, and what to do."""
    text = str(err)
    if 'relative motions' in text or 'keyframe' in text:
        return 'turn the device more, about all its axes: too few rotations so far (' + text + ')'
    if 'RANSAC found no model' in text:
        return 'turn the device more, faster and about all its axes: the motions so far do not agree on one T_HE'
    if 'overlap' in text:
        return 'the streams do not overlap in time: check the clocks (' + text + ')'
    return text


def _calibrate(hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig) -> Known:
    """Stages 1 and 2 on the data as they are (no screening, drift or scale)."""
    if cfg.time_offset is not None:
        dt, peak, second = cfg.time_offset, float('nan'), float('nan')
    else:
        ta = align_time(
            hand,
            eye,
            max_time_offset=cfg.max_time_offset,
            time_offset_guess=cfg.time_offset_guess,
            resample_rate_hz=cfg.resample_rate_hz,
        )
        dt, peak, second = ta.time_offset_s, ta.peak_correlation, ta.second_peak_ratio
    lin, _ = solve_linear(hand, eye, dt, cfg)
    return Known(dt, matrix_from_quat(lin.q_HE), lin.p_HE, lin.n_motions, peak, second)


def _predict(
    hand: Trajectory, eye: Trajectory, known: Known, cfg: CalibrationConfig, speed_dps: float
) -> tuple[tuple[float, float, float], float, list[str]]:
    """The predicted sigmas (dt s, translation m, rotation deg), the overlap (s) and the advice
    for each sigma over its target."""
    i = np.flatnonzero(eye.interval_ok())  # the pairs (i, i + 1)
    scale = 1.0
    if i.size > MAX_PAIRS:  # see MAX_PAIRS
        every = i[:: -(-i.size // MAX_PAIRS)]
        scale, i = i.size / every.size, every
    h = cfg.knot_spacing / 2.0
    dt0 = known.time_offset_s
    ends = np.concatenate([i, i + 1])  # the eye poses the pairs use: starts, then ends
    hands = [_hand_at(hand, eye.t_ns[ends], dt0 + s) for s in (0.0, -h, h)]
    covered = hands[0][2] & hands[1][2] & hands[2][2]
    k_ok = np.flatnonzero(covered[: i.size] & covered[i.size :])
    if k_ok.size < 20:
        return (float('nan'),) * 3, 0.0, ['the streams overlap too little at the time offset']
    span = float(np.sum(np.diff(eye.t_ns)[i[k_ok]])) * 1e-9 * scale
    eye_pose = (matrix_from_quat(eye.q_xyzw[ends]), eye.p_xyz[ends])
    X = (np.asarray(known.R_HE, float), np.asarray(known.p_HE, float))

    def motions(k: slice) -> tuple[list[tuple], tuple]:
        """The hand's motions at dt, dt - h, dt + h and the eye's, of the pairs k."""
        a = k_ok[k]
        b = a + i.size
        return [relative(hp[:2], a, b) for hp in hands], relative(eye_pose, a, b)

    r0 = chunked(lambda k: _residuals(*_first(motions(k)), X), k_ok.size)
    s_rot, s_t = _robust_sigma(r0[:, :3]), _robust_sigma(r0[:, 3:])
    w = np.array([1 / s_rot] * 3 + [1 / s_t] * 3)
    keep = np.all(np.abs(r0 * w) < OUTLIER_SIGMAS, axis=1)
    info = np.zeros((7, 7))
    for start in range(0, k_ok.size, CHUNK_ROWS):
        k = slice(start, min(start + CHUNK_ROWS, k_ok.size))
        A, B = motions(k)
        Jw = (_jacobian(A, B, X, h)[keep[k]] * w[None, :, None]).reshape(-1, 7)
        info += Jw.T @ Jw
    info *= scale
    with np.errstate(all='ignore'):  # a direction no motion observes: infinite sigmas
        try:
            cov = np.linalg.inv(info)
        except np.linalg.LinAlgError:
            cov = np.full((7, 7), np.inf)
        cov_p_eye = X[0].T @ cov[1:4, 1:4] @ X[0]  # the lever arm's covariance in E
        cov_r = cov[4:7, 4:7]
        sigma = tuple(
            float(v) if np.isfinite(v) else float('inf')
            for v in (
                np.sqrt(max(cov[0, 0], 0.0)),
                np.sqrt(max(np.trace(cov[1:4, 1:4]), 0.0)),
                np.degrees(np.sqrt(max(np.trace(cov_r), 0.0))),
            )
        )
    return sigma, span, _advice(sigma, cfg, cov_r, cov_p_eye, speed_dps)


def _hand_at(hand: Trajectory, t_eye_ns: np.ndarray, dt: float):
    """The hand's poses at eye stamps (ns) less dt, and where it covers them."""
    return interpolate(hand, t_eye_ns - np.int64(round(dt * 1e9)))


def _first(m: tuple[list[tuple], tuple]) -> tuple[tuple, tuple]:
    return m[0][0], m[1]


def _jacobian(A: list[tuple], B: tuple, X: tuple, h: float) -> np.ndarray:
    """(n, 6, 7) central differences of the residuals in (dt, p_HE in H, the rotation
    R_HE Exp(d) with d in E): dt over +-h (A: the hand's motions at dt, dt - h, dt + h), the
    extrinsic over +-1e-6."""
    J = np.zeros((B[1].shape[0], 6, 7))
    J[:, :, 0] = (_residuals(A[2], B, X) - _residuals(A[1], B, X)) / (2 * h)
    eps = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = eps
        up, down = (X[0], X[1] + d), (X[0], X[1] - d)
        J[:, :, 1 + k] = (_residuals(A[0], B, up) - _residuals(A[0], B, down)) / (2 * eps)
        up, down = (X[0] @ exp_so3(d[None])[0], X[1]), (X[0] @ exp_so3(-d[None])[0], X[1])
        J[:, :, 4 + k] = (_residuals(A[0], B, up) - _residuals(A[0], B, down)) / (2 * eps)
    return J


def _residuals(A: tuple, B: tuple, X: tuple) -> np.ndarray:
    """(n, 6) residual motions as (Log of the rotation, translation): the relative-pose
    residuals of eq. 16 in the eye frame."""
    err_R, err_p = residual_motions(A, B, X)
    return np.concatenate((log_so3(err_R), err_p), axis=1)


def _robust_sigma(r: np.ndarray) -> float:
    """A robust standard deviation of every component (1.4826 MAD about 0), floored."""
    return max(1.4826 * float(np.median(np.abs(r))), 1e-9)


def _advice(
    sigma: tuple[float, float, float],
    cfg: CalibrationConfig,
    cov_r: np.ndarray,
    cov_p: np.ndarray,
    speed_dps: float,
) -> list[str]:
    """What narrows each sigma that is over its target, in the device's axes."""
    out = []
    ratio = precision_ratios(sigma, cfg.precision)
    for cov, over in ((cov_p, ratio[1] > 1.0), (cov_r, ratio[2] > 1.0)):
        said = _turn_advice(cov, sigma[1]) if over else None
        if said and said not in out:
            out.append(said)
    if ratio[0] > 1.0:
        fast = f' (now {speed_dps:.0f} deg/s)' if speed_dps < SLOW_DPS else ''
        out.append(
            f'turn the device faster and more abruptly{fast}: the time offset is uncertain by '
            f'{sigma[0] * 1e3:.2g} ms'
        )
    return out


#: A T_HE covariance (in the device frame) whose widest 1-sigma is this many times its
#: narrowest says the turns so far were about nearly one axis, the one it leaves unobserved.
ONE_AXIS_RATIO = 3.0


def _turn_advice(cov: np.ndarray, translation_sigma: float) -> str:
    """Turns about one axis leave T_HE about and along it unobserved (the covariance's widest
    direction u, in the device frame): say where that axis lies among the device's axes (the
    bars are the turns' projections on them, so a diagonal axis fills two) and name the device
    axis most across it to turn about. Without one widest direction: more turns about all."""
    if np.all(np.isfinite(cov)):
        vals, vecs = np.linalg.eigh(cov)
        if vals[-1] < ONE_AXIS_RATIO**2 * max(vals[0], 0.0):
            return (
                'keep turning the device about all its axes: its offset from the marker is '
                f'still uncertain by {translation_sigma * 1e3:.2g} mm'
            )
        u = np.abs(vecs[:, -1])
    else:  # a direction no motion observes at all
        u = np.abs(np.nan_to_num(np.diag(cov), posinf=1e300))
    first, second, across = np.argsort(u)[::-1]
    where = (
        f'between its {AXES[min(first, second)]} and {AXES[max(first, second)]} axes'
        if u[second] > 0.5 * u[first]
        else f'near its {AXES[first]} axis'
    )
    return (
        f'turn the device about its {AXES[across]} axis too (so far it turned mostly about one '
        f"axis, {where}, which leaves the device's offset from the marker along it unobserved)"
    )
