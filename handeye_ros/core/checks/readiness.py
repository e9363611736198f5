"""Readiness: whether a calibration of the data so far is ``good`` for the chosen purpose, and
what the data lack until one is, said in the frame of the device the user holds (the eye E).

READY is a real calibration's verdict, never a prediction: the node calibrates its buffers as
they grow (``ros/status.py``), and READY means that the latest such result (an
:class:`Outcome`) is ``good`` for the purpose, and not near the line of its rule on precision
and with 1-sigmas that hold the errors correlated over the recording (:func:`~.verdict.settled`):
a result good by a hair, or by error bars that miss a term, is as likely to be doubtful a second
of recording later, when the user stops and calibrates. Between results the status shows what the
motion so far observes (:class:`~.excitation.Motion`): how far the device has turned, and how far
apart the axes it turned about are. A rotation about an axis a says nothing of T_HE's rotation
about a, nor of its translation along a (eq. 2): for the extrinsic, turns about nearly one axis
are told to turn about another one (the device axis most across it); for an evaluation the
lever arm along that axis moves no metric (the world alignment absorbs it), and no such advice
is given to a ground robot that cannot follow it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import Floats
from ..batch.correlated import BLOCKS, MIN_BLOCK_POSES
from ..batch.refine import BatchSolution
from ..config import CalibrationConfig
from ..document import StatusDoc
from ..errors import (
    InputError,
    NoConsensusError,
    NoOverlapError,
    TooFewKeyframesError,
    TooFewMotionsError,
)
from ..time.align import MIN_OVERLAP_S
from .excitation import RECENT_S, Motion
from .verdict import (
    BLOCKS_MARGIN,
    Code,
    Purpose,
    Quality,
    Verdict,
    judged_ratio,
    settled,
    sigmas_of,
)

__all__ = ['AXES', 'MIN_RECORDING_S', 'STILL_DPS', 'Outcome', 'Readiness', 'readiness']

#: The device's axes, as the advice names them.
AXES = ('x', 'y', 'z')
#: Slower than this RMS angular speed (deg/s), the device is held still.
STILL_DPS = 2.0
#: Shorter streams cannot be aligned in time: stage 1 wants MIN_OVERLAP_S of overlap at the
#: offsets it searches, some of which overlap only partly.
MIN_RECORDING_S = 2.0 * MIN_OVERLAP_S
#: A stream missing more than this fraction of its recent samples is said to drop out.
DROPOUT_FRACTION = 0.05
#: Turns whose axes spread less than this (deg, :attr:`.excitation.Turned.axis_spread_deg`) are
#: about nearly one axis: the spread is 2 atan(sqrt(l2 / l1)) of the axes' scatter, and at
#: 2 atan(1/3) the direction across the main axis carries a ninth of its information, a 1-sigma
#: three times as wide.
ONE_AXIS_DEG = float(np.degrees(2.0 * np.arctan(1.0 / 3.0)))


@dataclass(frozen=True)
class Outcome:
    """What the status keeps of a calibration of its buffers.

    good: ``good`` for the purpose judged; label: its verdict and reason codes; held: the first
    reason's message ('' when good); sigmas: the reported 1-sigmas of dt [s], T_HE's
    translation [m] and rotation [deg] (None without a batch stage); recording_helps: more of
    the same recording is the remedy for every reason (precision alone); failed: what to do
    about the refusal that ended the calibration, and the refusal ('' when it did not fail);
    span_s: the buffered span it calibrated [s];
    finished: when it ended (monotonic s); ratio: how far its purpose's rule on precision is
    from its line (:func:`~.verdict.judged_ratio`, above 1 imprecise); complete: its 1-sigmas
    hold the errors correlated over the recording (``BatchSolution.blocks_measured``); READY
    says :attr:`settled`.
    """

    good: bool
    label: str
    held: str
    sigmas: tuple[float, float, float] | None
    recording_helps: bool
    span_s: float
    finished: float
    failed: str = ''
    ratio: float = float('inf')
    complete: bool = True

    @property
    def settled(self) -> bool:
        """``good``, within BLOCKS_MARGIN of its line and complete (:func:`~.verdict.settled`)."""
        return settled(self.good, self.ratio, self.complete)

    @classmethod
    def of(
        cls,
        q: Quality,
        batch: BatchSolution | None,
        span_s: float,
        finished: float,
        precision: tuple[float, float, float],
    ) -> Outcome:
        """A calibration's verdict (as judged for its purpose), batch solution (None without a
        batch stage) and the precision targets (``CalibrationConfig.precision``)."""
        sigmas = None if batch is None else sigmas_of(batch.std)
        ratio = judged_ratio(q, sigmas, precision)
        return cls(
            good=q.verdict == Verdict.GOOD,
            label=q.label(),
            held=q.reasons[0].message if q.reasons else '',
            sigmas=sigmas,
            recording_helps=all(r.code == Code.IMPRECISE for r in q.reasons),
            span_s=span_s,
            finished=finished,
            ratio=ratio,
            complete=batch is not None and batch.blocks_measured,
        )

    @classmethod
    def failure(cls, err: Exception, span_s: float, finished: float) -> Outcome:
        """A calibration that raised ``err``: more recording may remedy it (too few motions),
        but not a refusal of the input itself (positions in millimetres: InputError);
        ``failed`` is what to do, by the error's kind (:func:`_plain`)."""
        helps = not isinstance(err, InputError)
        return cls(False, 'failed', str(err), None, helps, span_s, finished, failed=_plain(err))


@dataclass(frozen=True)
class Readiness:
    """What the status says while recording.

    ready: the latest calibration of these buffers is ``good`` for the purpose and settled
    (:attr:`Outcome.settled`); latest: that
    calibration (None before the first); age_s: how long ago it ended [s]; checking: one runs
    now. rotation_deg: (3,) how far the device has turned about its x, y, z axes (sum of
    |rotation| about each, deg); axis_spread_deg: how far apart the turns' axes are;
    angular_speed_dps: its RMS angular speed; travel_m: the marker's path length; span_s: the
    shorter stream's buffered span; dropout: the fraction of the last RECENT_S each stream
    misses; missing: what to do, in the user's words, most important first.
    """

    ready: bool
    purpose: Purpose
    latest: Outcome | None
    age_s: float
    checking: bool
    rotation_deg: Floats
    axis_spread_deg: float
    angular_speed_dps: float
    travel_m: float
    span_s: float
    dropout: dict[str, float]
    missing: tuple[str, ...]

    def to_dict(self) -> StatusDoc:
        """The status's values (``~/status``, /diagnostics) in plain types."""
        latest = self.latest
        sigma = (None,) * 3 if latest is None or latest.sigmas is None else latest.sigmas
        ms, mm, deg = (None if v is None else float(v) * k for v, k in zip(sigma, (1e3, 1e3, 1)))
        return {
            'ready': self.ready,
            'purpose': str(self.purpose),
            'verdict': None if latest is None else latest.label,
            'calibrated_span_s': None if latest is None else round(latest.span_s, 1),
            'age_s': None if latest is None else round(self.age_s, 1),
            'checking': self.checking,
            'sigma': {'time_offset_ms': ms, 'translation_mm': mm, 'rotation_deg': deg},
            'rotation_deg': dict(zip(AXES, np.round(self.rotation_deg, 1).tolist(), strict=True)),
            'axis_spread_deg': round(float(self.axis_spread_deg), 1),
            'angular_speed_dps': round(float(self.angular_speed_dps), 2),
            'travel_m': round(float(self.travel_m), 3),
            'span_s': round(float(self.span_s), 2),
            'dropout': {k: round(float(v), 3) for k, v in self.dropout.items()},
            'missing': list(self.missing),
        }


def readiness(
    motion: Motion,
    latest: Outcome | None,
    cfg: CalibrationConfig,
    span_s: float,
    now: float,
    checking: bool = False,
    final: bool = False,
) -> Readiness:
    """What the status says of buffers whose shorter stream spans ``span_s`` [s], with the
    motion gathered of them, the latest calibration of them (None: none yet), at monotonic
    time ``now`` [s], while a calibration runs (``checking``). ``final``: the recording has
    ended and the latest calibration holds the whole of it, so a calibration now gives the
    same result, near its line or not: READY is then its being ``good``."""
    purpose = Purpose(cfg.purpose)
    eye, hand = motion.turned('eye'), motion.turned('hand')
    speed = 0.0 if eye is None else eye.rms_dps
    good = bool(latest and latest.good)
    ready = bool(latest and (latest.settled or (final and latest.good)))
    missing: list[str] = []
    # a device held still has no axis to name
    if eye is not None and speed >= STILL_DPS and purpose == Purpose.EXTRINSIC and not good:
        missing += _turn_advice(eye.scatter, eye.axis_spread_deg)
    if checking and not ready:
        missing.append(
            f'checking READY: a calibration of the {span_s:.0f} s so far is judging them'
        )
    if latest is not None and not ready:
        missing.append(_held(latest))
    if speed < STILL_DPS:
        missing.append('the device is held still: move it')
    elif span_s < MIN_RECORDING_S:
        missing.append(
            f'keep recording: {span_s:.0f} s of both streams so far, {MIN_RECORDING_S:.0f} s '
            'needed'
        )
    missing += _health(dict(motion.dropout))
    return Readiness(
        ready=ready,
        purpose=purpose,
        latest=latest,
        age_s=0.0 if latest is None else now - latest.finished,
        checking=checking,
        rotation_deg=np.zeros(3) if eye is None else eye.deg,
        axis_spread_deg=0.0 if eye is None else eye.axis_spread_deg,
        angular_speed_dps=speed,
        travel_m=0.0 if hand is None else hand.travel_m,
        span_s=span_s,
        dropout=dict(motion.dropout),
        missing=tuple(dict.fromkeys(missing)),
    )


def _held(latest: Outcome) -> str:
    """Why the latest calibration holds READY back, with what to do."""
    of = f'the latest calibration ({latest.span_s:.0f} s of data)'
    if latest.failed:
        return f'{of} failed: {latest.failed}'
    if latest.good and not latest.complete:
        return (
            f'{of} is good, but its 1-sigmas do not hold the errors correlated over the '
            f'recording yet (they are measured on {BLOCKS} blocks of at least {MIN_BLOCK_POSES} '
            'eye poses each, and may widen the 1-sigmas); keep recording'
        )
    if latest.good:
        return (
            f'{of} is good, near the line of its precision ({latest.ratio:.0%} of what it '
            f'allows; READY within {BLOCKS_MARGIN:.0%}, as a 1-sigma is itself uncertain by '
            'about a quarter); keep recording'
        )
    remedy = '; keep recording' if latest.recording_helps else ''
    return f'{of} is {latest.label}: {latest.held}{remedy}'


def _health(dropout: dict[str, float]) -> list[str]:
    who = {'hand': 'the MoCap lost the marker', 'eye': 'the device stream misses poses'}
    return [
        f'{who[s]} {f:.0%} of the last {RECENT_S:.0f} s'
        for s, f in dropout.items()
        if f > DROPOUT_FRACTION
    ]


def _plain(err: Exception) -> str:
    """A refusal of stage 1 or 2 as advice, by its kind: what to do, then the refusal."""
    text = str(err)
    if isinstance(err, (TooFewMotionsError, TooFewKeyframesError)):
        return f'turn the device more, about all its axes: too few rotations so far ({text})'
    if isinstance(err, NoConsensusError):
        return (
            'turn the device more, faster and about all its axes: the motions so far do not '
            f'agree on one T_HE ({text})'
        )
    if isinstance(err, NoOverlapError):
        return f'the streams do not overlap in time: check the clocks ({text})'
    return text


def _turn_advice(scatter: Floats, spread_deg: float) -> list[str]:
    """Turns about nearly one axis (u, the scatter's main direction in the device frame) leave
    T_HE about and along it unobserved: say where that axis lies among the device's axes (the
    bars are the turns' projections on them, so a diagonal axis fills two) and name the device
    axis most across it to turn about."""
    if spread_deg >= ONE_AXIS_DEG:
        return []
    _, vecs = np.linalg.eigh(0.5 * (scatter + scatter.T))
    u = np.abs(vecs[:, -1])
    first, second, across = np.argsort(u)[::-1]
    where = (
        f'between its {AXES[min(first, second)]} and {AXES[max(first, second)]} axes'
        if u[second] > 0.5 * u[first]
        else f'near its {AXES[first]} axis'
    )
    said = (
        f'turn the device about its {AXES[across]} axis too (so far it turned mostly about one '
        f"axis, {where}, which leaves the device's offset from the marker along it unobserved)"
    )
    return [said]
