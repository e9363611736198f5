"""Readiness: can the data so far calibrate to the required precision, and if not, what do they
lack, said in the frame of the device the user holds (the eye E).

The prediction is the batch stage's white covariance (eq. 15-16) without running the batch
stage: the eye's relative poses between consecutive frames (the residuals of eq. 16) at stage 1's
offset and stage 2's T_HE give the noise (robust sigmas of their residuals), and their Jacobians in (dt, T_HE) the information
(:mod:`.pair_information`); its inverse is the covariance the batch stage would report if the
residuals were white. The derivative in dt is a central difference over one knot spacing, as
smooth as the batch stage's spline, so that the MoCap's own noise does not pass for motion.
:func:`readiness` reads a whole recording; the node's status adds up what the poses new since
its last status say (:mod:`.progress`) and judges the sum with :func:`readiness_of`.

Which direction is missing follows from the motions' screw axes: a rotation about an axis a
says nothing of T_HE's rotation about a, nor of its translation along a (eq. 2). So the
covariance's widest direction, in the device's axes, names the axis the device has mostly turned
about, and the advice is to turn it about the other two.

The targets are the verdict's own (``precision_time_offset``, ``precision_translation``,
``precision_rotation``): ready means a calibration now would not be ``imprecise``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np

from ..arrays import Floats
from ..config import CalibrationConfig
from ..document import ReadinessDoc
from ..trajectory import Trajectory
from . import pair_information as info
from .excitation import RECENT_S
from .progress import MIN_RECORDING_S, STILL_DPS, Known, Progress, start
from .verdict import AMBIGUOUS_PEAK_RATIO, WEAK_CORRELATION, precision_ratio, precision_ratios

__all__ = ['AXES', 'Known', 'Readiness', 'readiness', 'readiness_of']

#: The device's axes, as the advice names them.
AXES = ('x', 'y', 'z')
#: Below this RMS angular speed (deg/s), "turn faster" is part of the advice for dt.
SLOW_DPS = 30.0
#: A stream missing more than this fraction of its recent samples is said to drop out.
DROPOUT_FRACTION = 0.05
#: Fewer covered pairs than this predict nothing.
MIN_PAIRS = 20


@dataclass(frozen=True)
class Readiness:
    """What the data support.

    ready: the predicted 1-sigmas are within the targets and nothing blocks a calibration.
    sigma: predicted 1-sigma of dt [s], T_HE's translation [m] (norm of the three) and rotation
    [deg] (norm), NaN when not predicted; target: the same three required.
    rotation_deg: (3,) how far the device has turned about its x, y, z axes (sum of |rotation|
    about each, deg); hand_rotation_deg: the same about the MoCap marker's axes;
    axis_spread_deg: how far apart the device's turns' axes are (0: one axis, 90: two or more
    alike; :attr:`.excitation.Turned.axis_spread_deg`).
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
    rotation_deg: Floats
    hand_rotation_deg: Floats
    angular_speed_dps: float
    travel_m: float
    motions: int = 0
    span_s: float = 0.0
    time_offset_s: float | None = None
    peak_correlation: float = float('nan')
    second_peak_ratio: float = float('nan')
    dropout: dict[str, float] = field(default_factory=dict)
    missing: tuple[str, ...] = ()
    axis_spread_deg: float = 0.0

    def to_dict(self) -> ReadinessDoc:
        """The ``readiness`` section of a result, and the node's status values, before a
        result's factors and reasons are carried over (:mod:`.carry`): ``sigma`` is still
        ``predicted``."""

        def num(v: float, k: float = 1.0) -> float | None:
            return float(v) * k if np.isfinite(v) else None

        sigma = {
            'time_offset_ms': num(self.sigma[0], 1e3),
            'translation_mm': num(self.sigma[1], 1e3),
            'rotation_deg': num(self.sigma[2]),
        }
        return {
            'ready': bool(self.ready),
            'sigma': sigma,
            'predicted': dict(sigma),
            'target': {
                'time_offset_ms': self.target[0] * 1e3,
                'translation_mm': self.target[1] * 1e3,
                'rotation_deg': self.target[2],
            },
            'rotation_deg': dict(zip(AXES, np.round(self.rotation_deg, 1).tolist(), strict=True)),
            'hand_rotation_deg': dict(
                zip(AXES, np.round(self.hand_rotation_deg, 1).tolist(), strict=True)
            ),
            'axis_spread_deg': round(float(self.axis_spread_deg), 1),
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


def readiness(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig, known: Known | None = None
) -> Readiness:
    """How far ``hand`` and ``eye`` (both on their own clocks) can calibrate, and what they
    lack; never raises for data that cannot calibrate (that is what it says)."""
    if len(hand) < 3 or len(eye) < 3:
        return _empty(cfg.precision, 'no data yet: both streams need poses')
    durations = (hand.duration_s, eye.duration_s)
    return readiness_of(start(hand, eye, cfg, known), cfg, durations)


class _Moved(TypedDict):
    """What a :class:`Readiness` says of the motion so far (its fields of the same names)."""

    rotation_deg: Floats
    hand_rotation_deg: Floats
    angular_speed_dps: float
    travel_m: float
    dropout: dict[str, float]
    axis_spread_deg: float


def readiness_of(
    progress: Progress, cfg: CalibrationConfig, durations: tuple[float, float]
) -> Readiness:
    """What the pieces gathered so far support; ``durations`` (hand, eye) [s], the spans of
    the streams they come from."""
    target = cfg.precision
    nan3 = (float('nan'),) * 3
    eye_turn, hand_turn = progress.turned('eye'), progress.turned('hand')
    if eye_turn is None or hand_turn is None:
        return _empty(target, 'no data yet: both streams need poses')
    speed = eye_turn.rms_dps
    base = _Moved(
        rotation_deg=eye_turn.deg,
        hand_rotation_deg=hand_turn.deg,
        angular_speed_dps=speed,
        travel_m=hand_turn.travel_m,
        dropout=dict(progress.dropout),
        axis_spread_deg=eye_turn.axis_spread_deg,
    )
    health = _health(base['dropout'])
    if speed < STILL_DPS:
        return Readiness(
            False, nan3, target, **base, missing=('the device is held still: move it', *health)
        )
    known = progress.known
    if known is None:
        short = min(durations)
        why = progress.refused or (
            f'keep recording: {short:.0f} s of both streams so far, {MIN_RECORDING_S:.0f} s needed'
        )
        return Readiness(False, nan3, target, **base, missing=(_plain(why), *health))
    sigma, span, advice = _predict(progress, cfg, speed)
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
    # for an evaluation no prediction of T_HE's sigmas says whether the figures are settled:
    # a calibration of the data so far does (the node's check), once stages 1 and 2 stand
    extrinsic = cfg.purpose == 'extrinsic'
    ok = precision_ratio(sigma, target) <= 1.0 or not extrinsic
    advice = advice if extrinsic else []
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


def _health(dropout: dict[str, float]) -> list[str]:
    who = {'hand': 'the MoCap lost the marker', 'eye': 'the device stream misses poses'}
    return [
        f'{who[s]} {f:.0%} of the last {RECENT_S:.0f} s'
        for s, f in dropout.items()
        if f > DROPOUT_FRACTION
    ]


def _plain(text: str) -> str:
    """A refusal of stage 1 or 2 as advice: its first sentence, and what to do."""
    if 'relative motions' in text or 'keyframe' in text:
        return 'turn the device more, about all its axes: too few rotations so far (' + text + ')'
    if 'RANSAC found no model' in text:
        return 'turn the device more, faster and about all its axes: the motions so far do not agree on one T_HE'
    if 'overlap' in text:
        return 'the streams do not overlap in time: check the clocks (' + text + ')'
    return text


def _predict(
    progress: Progress, cfg: CalibrationConfig, speed_dps: float
) -> tuple[tuple[float, float, float], float, list[str]]:
    """The predicted sigmas (dt s, translation m, rotation deg), the time the pairs span (s)
    and the advice for each sigma over its target: the inverse of the pairs' information, the
    covariance the batch stage would report if the residuals were white."""
    total = progress.total()
    if total is None or total.pairs < MIN_PAIRS:
        return (float('nan'),) * 3, 0.0, ['the streams overlap too little at the time offset']
    H, _ = info.normal_equations(total)
    cov = info.covariance(H)
    dt, t, r = (v if np.isfinite(v) else float('inf') for v in info.sigmas(cov))
    sigma = (dt, t, r)
    assert progress.known is not None, 'pairs are gathered once stages 1 and 2 are known'
    R_HE = np.asarray(progress.known.R_HE, float)
    with np.errstate(all='ignore'):  # a direction no motion observes: infinite sigmas
        cov_p_eye = R_HE.T @ cov[1:4, 1:4] @ R_HE  # the lever arm's covariance in E
    return sigma, total.span_s, _advice(sigma, cfg, cov[4:7, 4:7], cov_p_eye, speed_dps)


def _advice(
    sigma: tuple[float, float, float],
    cfg: CalibrationConfig,
    cov_r: Floats,
    cov_p: Floats,
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


def _turn_advice(cov: Floats, translation_sigma: float) -> str:
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
