"""The calibrator's auto mode (``auto_calibrate``): calibrations started by the readiness
status (:mod:`.status`), and which of their results are published.

With ``auto_calibrate`` the node calibrates as soon as the status is READY, then again each time
the buffered span has grown by GROWTH, READY or not (the status carries the last result's factors
and reasons: only a new result settles them, and READY waits for one that is ``good``). A result is
measured by its *precision ratio*, its largest reported 1-sigma over that sigma's ``precision_*``
target (:func:`precision_ratio`: below 1, the verdict is not ``imprecise``). A later result of auto
mode's own is published when its ratio is no larger than the published one's (or when the published
one's sigmas lack the blocks' term and its own have it, or its estimate moved beyond the published
sigma); once one improves it by no more than IMPROVEMENT of itself (or of 1, the targets), or is
not published, auto mode has converged (said in the status; *stalled* when the published result is
doubtful for a reason that more of the same recording does not remedy). A published result held
back only by its precision, or by sigmas that lack the blocks' term, is not converged on: more
recording is their remedy, and one later result no better is no evidence of a floor (a sigma of
four blocks moves by a quarter between calibrations), so auto mode calibrates at each GROWTH
until a result is ``good`` or the buffers are full (done, said so: their span can no longer grow
by GROWTH). Converged, stalled or done, it calibrates again when the status's predicted ratio falls
below the one predicted at its last calibration by more than RECALIBRATE of it (or of 1): richer
motion than the data it converged on.
``~/calibrate`` works at any time, and its result is always published.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from ..core.arrays import Floats
from ..core.checks.carry import (
    LACKS_BLOCKS,
    held_reasons,
    held_words,
    predictor_factors,
    recording_remedies,
)
from ..core.checks.verdict import precision_ratio, precision_ratios, sigmas_of
from ..core.document import ReadinessDoc, ResultDoc
from ..stream import STREAMS
from .host import StatusHost
from .jobs import Calibrated

#: With auto_calibrate: calibrate again once the buffered span has grown by this factor.
GROWTH = 1.5
#: With auto_calibrate: converged when the precision ratio shrinks by no more than this fraction
#: of itself or of 1 (the targets), whichever is larger. Of itself: for sigmas that stop at a
#: floor, as errors that are not white (drift, a MoCap bias) should make them do. Of the
#: targets: white noise shrinks them by 18 % at each GROWTH for ever (1 - 1/sqrt(1.5)), and
#: this ends it once they are about half the targets, where more recording no longer matters
#: to the verdict.
IMPROVEMENT = 0.1
#: With auto_calibrate, converged or done: calibrate again when the predicted precision ratio
#: has fallen by more than this fraction of itself or of 1 since the last calibration (twice
#: IMPROVEMENT: a gain the last result could not have had, not the next 18 % of white noise).
RECALIBRATE = 2 * IMPROVEMENT


class AutoMode:
    """Auto mode of ``node`` (a :class:`~handeye_ros.ros.node.CalibratorNode`); ``said`` is
    where it stands, as the status says it ('off' when not asked for)."""

    def __init__(self, node: StatusHost, on: bool) -> None:
        self._node = node
        self.said = 'waiting for READY' if on else 'off'
        self._span_calibrated = 0.0
        #: the published auto result's reported 1-sigmas (s, m, deg), and the status's
        #: predicted precision ratio when auto mode last calibrated
        self._sigmas: tuple[float, float, float] | None = None
        self._predicted_then = math.inf
        #: the published result's reported over predicted 1-sigmas (``predictor_factors``),
        #: which the status's predictions carry, and the reasons that make it doubtful (they
        #: hold READY back)
        self.factors: dict[str, float] = {}
        self.held: list[str] = []
        #: whether more of the same recording is the remedy for every one of those reasons
        #: (precision, the blocks' term)
        self._recording_helps = False
        #: whether a result of these buffers (published, or a check of READY) set them
        self.confirmed = False
        #: the published auto result's estimate: dt [s], translation [m], rotation (x y z w)
        self._estimate: tuple[float, Floats, Floats] | None = None

    @property
    def ended(self) -> bool:
        """Converged, stalled or done: it calibrates again only for richer motion."""
        return self.said.startswith(('converged', 'stalled', 'done'))

    def step(self, last: ReadinessDoc | None, ended: bool = False) -> None:
        """On each tick of the status, with its last readiness: calibrate once READY is
        predicted (its first result is the one that confirms it), again as the buffers grow by
        GROWTH, and once more when the recording has ended (``ended``) on more than the last
        calibration had; converged or done, when the motion gets richer."""
        # READY starts it; once it has calibrated, the buffers growing do (READY then carries
        # the last result's factors and reasons, which only a new result can settle)
        if not (last and (last['ready'] or last.get('checking') or self._span_calibrated)):
            return
        if self.said in ('waiting for READY', 'calibrating'):
            self._calibrate(last, final=ended)
        elif self.ended and richer(self._predicted_then, self._predicted(last)):
            self._calibrate(last, grown=True)

    def reset(self) -> None:
        """A new recording: its first result is published whatever the last one reported."""
        if self.said != 'off':
            self.said, self._span_calibrated, self._sigmas = 'waiting for READY', 0.0, None
            self._predicted_then, self._estimate = math.inf, None
        self.factors, self.held, self.confirmed = {}, [], False
        self._recording_helps = False

    def _predicted(self, last: ReadinessDoc | None) -> float:
        """The status's predicted precision ratio (inf while a sigma is unknown)."""
        sigma = last['sigma'] if last else {}
        ms, mm, deg = (
            sigma.get('time_offset_ms'),
            sigma.get('translation_mm'),
            sigma.get('rotation_deg'),
        )
        if ms is None or mm is None or deg is None:
            return math.inf
        seconds_metres_degrees = (ms * 1e-3, mm * 1e-3, deg)
        return precision_ratio(seconds_metres_degrees, self._node.calib_cfg.precision)

    def _calibrate(self, last: ReadinessDoc, grown: bool = False, final: bool = False) -> None:
        buffers = [self._node.recorder.buffers[s] for s in STREAMS]
        span = min(b.span_s for b in buffers)
        # a recording that ended grows no more: its whole is calibrated once, however little
        # it grew since the last calibration
        last_of_it = final and span > self._span_calibrated
        if (
            not grown
            and not last_of_it
            and self._span_calibrated
            and span < GROWTH * self._span_calibrated
        ):
            if any(b.dropped for b in buffers):  # a full buffer's span grows no more
                self.said = (
                    f'done: the buffers are full ({span:.0f} s; buffer_duration, buffer_size), '
                    'so later results would not see more data; ~/calibrate still works'
                )
            return
        if self._node.calibrate(auto=True) is not None:
            self._span_calibrated = span
            self._predicted_then = self._predicted(last)
            self.said = 'calibrating'

    def admit(self, session: Calibrated, auto: bool) -> str:
        """A new result, before it is published: '' when it replaces the published one, else
        why not (with the numbers).

        A result of ``~/calibrate`` always does. One that auto mode started does when its
        precision ratio is no larger than the published result's; auto mode has converged
        (said in the status) once a result of its own is not admitted, or improves the ratio by
        no more than IMPROVEMENT of itself or of 1 (:func:`judge`)."""
        doc = session.document
        batch = doc.get('std')
        if self.said == 'off' or not batch:
            self._published(doc)
            return ''
        sigmas = sigmas_of(np.r_[batch['time_offset'], batch['translation'], batch['rotation']])
        targets = self._node.calib_cfg.precision
        published = self._sigmas
        admitted, converged = judge(sigmas, published, auto, targets)
        moved = moved_beyond(_estimate_of(doc), self._estimate, published) if auto else None
        # a published sigma without the blocks' term is no bar for one with it: it lacks what
        # dominates a real VIO's (EuRoC MH_01 stereo, live: a `good` 8.4-mm result of 393
        # covered eye poses kept every later result, all with the term, from being published)
        completes = LACKS_BLOCKS in self.held and LACKS_BLOCKS not in held_reasons(doc)
        if moved or completes:  # moved: the data since the published result move it beyond it
            admitted, converged = True, False
        if admitted:
            self._sigmas = sigmas
        if admitted or published is None:
            self._published(doc)
        if converged and not (self.held and self._recording_helps):
            self.said = self._ended(self._sigmas or sigmas)
        if admitted or published is None:
            return ''
        return (
            f'auto_calibrate keeps the published result: its largest sigma against its target, '
            f"{_largest(sigmas, targets)}, is above the published one's, "
            f'{_largest(published, targets)}'
        )

    def _ended(self, best: tuple[float, float, float]) -> str:
        """What auto mode says once more of the same motion no longer improves the published
        result: converged when that result is ``good``, stalled when it is not (the motion, or
        the recording, must change before it can be)."""
        gain = f'no longer improves the result by {IMPROVEMENT:.0%} of the targets'
        if self.held:
            return (
                f'stalled: more of the same motion {gain}, and it {held_words(self.held[0])}; it '
                'calibrates again if the motion gets richer'
            )
        return (
            f'converged: more of the same motion {gain} (1-sigma {_sigmas_text(best)}); it '
            'calibrates again if the motion gets richer'
        )

    def confirm(self, session: Calibrated) -> str:
        """A calibration that checked a predicted READY: the status carries its factors and
        reasons as a published one's; returns why it is not published."""
        self._published(session.document)
        return 'it checked READY'

    def _published(self, doc: ResultDoc) -> None:
        """What the status carries of the result being published (or checking READY)."""
        self.confirmed = True
        self.factors = predictor_factors(doc)
        self.held = held_reasons(doc)
        self._recording_helps = recording_remedies(doc)
        self._estimate = _estimate_of(doc)


def _estimate_of(doc: ResultDoc) -> tuple[float, Floats, Floats]:
    ext = doc['extrinsic']
    return doc['time_offset'], np.asarray(ext['translation']), np.asarray(ext['rotation'])


def moved_beyond(
    new: tuple[float, Floats, Floats],
    old: tuple[float, Floats, Floats] | None,
    old_sigmas: tuple[float, float, float] | None,
) -> str | None:
    """Whether a new estimate (dt [s], translation [m], rotation x y z w) lies beyond the
    published one's 1-sigmas (:func:`sigmas_of`: s, m, deg) from it, said with the group that
    did; None if not (or nothing published)."""
    if old is None or old_sigmas is None:
        return None
    q_new, q_old = Rotation.from_quat(new[2]), Rotation.from_quat(old[2])
    moves = (
        abs(new[0] - old[0]),
        float(np.linalg.norm(new[1] - old[1])),
        float(np.degrees((q_old.inv() * q_new).magnitude())),
    )
    names = ('time offset', 'translation', 'rotation')
    over = [n for n, m, s in zip(names, moves, old_sigmas, strict=True) if m > s]
    return ', '.join(over) or None


#: The three reported 1-sigmas, named and in the units they are said in.
_SAID = (('time offset', 1e3, 'ms'), ('translation', 1e3, 'mm'), ('rotation', 1.0, 'deg'))


def _sigmas_text(sigmas: tuple[float, ...]) -> str:
    return ', '.join(f'{v * k:.2g} {unit}' for v, (_, k, unit) in zip(sigmas, _SAID, strict=True))


def _largest(sigmas: tuple[float, ...], targets: tuple[float, ...]) -> str:
    """The sigma that sets the precision ratio, e.g. 'translation 6.7 mm of 10 mm'."""
    k = int(np.argmax(precision_ratios(sigmas, targets)))
    name, scale, unit = _SAID[k]
    return f'{name} {sigmas[k] * scale:.2g} {unit} of {targets[k] * scale:.2g} {unit}'


def richer(predicted_then: float, predicted_now: float) -> bool:
    """Converged or done: whether the predicted precision ratio has fallen well below the one
    predicted at auto mode's last calibration (:data:`RECALIBRATE`): richer motion."""
    then, now = predicted_then, predicted_now
    return bool(math.isfinite(then) and then - now > RECALIBRATE * max(then, 1.0))


def judge(
    sigmas: tuple[float, ...],
    published: tuple[float, ...] | None,
    auto: bool,
    targets: tuple[float, ...],
) -> tuple[bool, bool]:
    """A new result's reported 1-sigmas against the published result's (None: none yet), in
    the targets' units: whether it replaces it, and whether auto mode has converged with it
    (both only for a result that auto mode started; see :meth:`AutoMode.admit`)."""
    if not auto or published is None:
        return True, False
    new, old = precision_ratio(sigmas, targets), precision_ratio(published, targets)
    admitted = new <= old
    converged = not admitted or old - new <= IMPROVEMENT * max(old, 1.0)
    return admitted, converged
