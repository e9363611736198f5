"""The verdict: how far a calibration can be trusted, and why.

Every calibration ends with ``quality.verdict``:

- ``good``: every check passed; the numbers and their sigmas can be used as they are;
- ``doubtful``: a number is given, but something the user must look at is wrong or unknown
  (each ``reason`` says what); an evaluation built on it needs that looked at first;
- ``failed``: the data contradict the result (the calibrated MoCap does not explain the VIO);
  the numbers are given only to help find out why.

The reasons (``code``: what, and when; :class:`Code` names them, :data:`SEVERITY` gives each
its verdict, and the thresholds below are the rules' numbers):

==========================  =========  =================================================
code                        severity   when
==========================  =========  =================================================
convention_corrected        doubtful   a stamp unit, quaternion order or pose inversion was
                                       assumed (the file still holds the mistake)
outliers_removed            doubtful   screening removed more than OUTLIER_FRACTION_DOUBTFUL
                                       of a stream
ambiguous_offset            doubtful   two offsets explain the data almost equally (the
                                       self-check's runner-up scores within
                                       AMBIGUOUS_SCORE_RATIO of the winner), or the
                                       correlation has a second peak above 0.9 that no
                                       self-check ran on
weak_correlation            doubtful   the angular velocities hardly agree (correlation
                                       below 0.5)
stages_disagree             doubtful   the batch stage moved the offset or the extrinsic
                                       beyond its sigmas and the self-check sided against it
few_inliers                 doubtful   fewer than 20 % of the motions are RANSAC inliers
weak_excitation             doubtful   the rotation axes spread less than 10 deg
unobservable                doubtful   a component of T_HE, the clock drift or the scale
                                       cannot be determined (named)
seed_dependent              doubtful   the linear stage's answer moves with the RANSAC seed
no_uncertainty              doubtful   the batch stage could not run: no sigmas
imprecise                   doubtful   a 1-sigma exceeds the required precision
                                       (options precision_time_offset, _translation,
                                       _rotation; default 1 ms, 1 cm, 0.5 deg)
clock_drift                 doubtful   without clock_drift: the offset measured in windows
                                       changes along the recording by more than 2 ms and 3
                                       of its sigmas (the rate is named)
scale                       doubtful   without estimate_scale: a scale explains the eye's
                                       translations (named with its value)
residuals_not_white         doubtful   the long-run covariance is more than
                                       INFLATION_DOUBTFUL times the white one (an
                                       unmodelled effect: clock drift, scale, ...)
inconsistent                failed     AX = XB does not hold: over the keyframe motions
                                       (eq. 6), the median rotation error exceeds
                                       FAILED_MOTION_ROTATION_DEG, or the median translation
                                       error exceeds FAILED_MOTION_TRANSLATION_M and
                                       FAILED_MOTION_TRANSLATION_FRACTION of the median
                                       motion (relative motions: the VIO's drift does not
                                       enter, unlike APE)
==========================  =========  =================================================

Notes that do not lower the verdict (resets split, an epoch difference, a self-check that
settled clearly) are in ``notes``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum


class Verdict(StrEnum):
    """How far a calibration can be trusted (a ``str``: compares and serialises as its value)."""

    GOOD = 'good'
    DOUBTFUL = 'doubtful'
    FAILED = 'failed'


class Code(StrEnum):
    """Why a verdict is not better (the table of the module docstring)."""

    CONVENTION_CORRECTED = 'convention_corrected'
    OUTLIERS_REMOVED = 'outliers_removed'
    AMBIGUOUS_OFFSET = 'ambiguous_offset'
    WEAK_CORRELATION = 'weak_correlation'
    STAGES_DISAGREE = 'stages_disagree'
    FEW_INLIERS = 'few_inliers'
    WEAK_EXCITATION = 'weak_excitation'
    UNOBSERVABLE = 'unobservable'
    SEED_DEPENDENT = 'seed_dependent'
    NO_UNCERTAINTY = 'no_uncertainty'
    IMPRECISE = 'imprecise'
    CLOCK_DRIFT = 'clock_drift'
    SCALE = 'scale'
    RESIDUALS_NOT_WHITE = 'residuals_not_white'
    INCONSISTENT = 'inconsistent'


#: The verdict each reason makes: every code is doubtful but one.
SEVERITY = {code: Verdict.DOUBTFUL for code in Code} | {Code.INCONSISTENT: Verdict.FAILED}

#: Outlier fraction of a stream above which the verdict is doubtful: a tenth of a recording
#: that no motion produced is a recording to look at, even when screening coped with it.
OUTLIER_FRACTION_DOUBTFUL = 0.10
#: A correlation second peak above this, with no self-check, leaves the offset ambiguous.
AMBIGUOUS_PEAK_RATIO = 0.9
#: Below this the angular velocities hardly agree.
WEAK_CORRELATION = 0.5
#: A self-check runner-up whose score is within this factor of the winner's is a tie.
AMBIGUOUS_SCORE_RATIO = 1.25
#: Fewer inliers than this fraction of the motions.
LOW_INLIER_FRACTION = 0.2
#: Rotation axes spread below this (deg).
WEAK_EXCITATION_DEG = 10.0
#: Long-run over white sigma of any parameter above this.
INFLATION_DOUBTFUL = 5.0
#: AX = XB fails over the keyframe motions beyond these (median errors): on the real flights
#: of ../shared/data/real they are 0.05-0.14 deg and 3-26 mm (4-9 % of the motion).
FAILED_MOTION_ROTATION_DEG = 2.0
FAILED_MOTION_TRANSLATION_M = 0.05
FAILED_MOTION_TRANSLATION_FRACTION = 0.5


@dataclass(frozen=True)
class Reason:
    """Why the verdict is not better: a stable ``code`` and a ``message`` for people; its
    ``severity`` is the code's (:data:`SEVERITY`)."""

    code: Code
    message: str

    @property
    def severity(self) -> Verdict:
        return SEVERITY[self.code]


@dataclass(frozen=True)
class Quality:
    """The verdict, its reasons (worst first) and notes that did not lower it."""

    verdict: Verdict
    reasons: tuple[Reason, ...] = ()
    notes: tuple[str, ...] = field(default=())

    @classmethod
    def from_reasons(cls, reasons: list[Reason], notes: list[str]) -> Quality:
        worst = list(Verdict)[::-1]  # failed first
        reasons = sorted(reasons, key=lambda r: worst.index(r.severity))
        verdict = reasons[0].severity if reasons else Verdict.GOOD
        return cls(verdict, tuple(reasons), tuple(notes))

    @property
    def codes(self) -> tuple[str, ...]:
        return tuple(r.code for r in self.reasons)

    def label(self, sep: str = ', ') -> str:
        """The verdict and its reason codes, e.g. ``doubtful (ambiguous_offset)``."""
        return self.verdict + (f' ({sep.join(self.codes)})' if self.reasons else '')

    def to_dict(self) -> dict:
        return {
            'verdict': str(self.verdict),
            'reasons': [
                {'code': str(r.code), 'severity': str(r.severity), 'message': r.message}
                for r in self.reasons
            ],
            'notes': list(self.notes),
        }
