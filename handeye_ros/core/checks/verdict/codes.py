"""The verdict's words: its three values, the reasons' codes and their severities, the rules'
thresholds, and the records (:class:`Reason`, :class:`Quality`); the table is the package's
docstring."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

from ...batch.correlated import BLOCKS
from ...document import QualityDoc


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
    RECORDING_LEFT_OUT = 'recording_left_out'
    GROUPS = 'groups'
    NO_AGREEMENT = 'no_agreement'


#: The verdict each reason makes: every code is doubtful but two.
SEVERITY = {code: Verdict.DOUBTFUL for code in Code} | {
    Code.INCONSISTENT: Verdict.FAILED,
    Code.NO_AGREEMENT: Verdict.FAILED,
}

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
#: clock_drift: the offset measured in windows changes between the first and the last eye pose
#: by more than DRIFT_NOTICE_S (s) and its drift is beyond DRIFT_SIGMAS Gaussian sigmas
#: (:func:`drift_significant`).
DRIFT_NOTICE_S = 2e-3
DRIFT_SIGMAS = 3.0
#: seed_dependent: the linear stage with the next RANSAC seed moves T_HE by more than
#: SEED_SIGMAS of the batch stage's sigmas and at least these.
SEED_SIGMAS = 3.0
SEED_ROTATION_DEG = 0.5
SEED_TRANSLATION_M = 0.01
#: stages_disagree: the batch stage moved dt by more than BATCH_SIGMAS of its sigmas and at
#: least BATCH_DT_MIN_S, or T_HE by more than BATCH_SIGMAS sigmas and at least these; the
#: self-check then decides, and rejects its extrinsic when it scores BATCH_SCORE_FACTOR worse.
BATCH_SIGMAS = 3.0
BATCH_DT_MIN_S = 2e-3
BATCH_TRANSLATION_MIN_M = 0.02
BATCH_ROTATION_MIN_DEG = 1.0
BATCH_SCORE_FACTOR = 1.5
#: A 1-sigma that the blocks measure (core/batch/correlated.py) is itself uncertain: a norm of
#: three axes with BLOCKS - 1 degrees of freedom each, by about 1 / sqrt(2 dof) of itself
#: (0.24; the blocks' later cuttings make it a little less). Within this share of its
#: target (0.81) it stays below the target by one such uncertainty; beyond it a `good` result
#: is noted to be near its target, and READY carried from a result to more data waits for it
#: (checks/carry.py). Without it, a READY carried from a `good` result at 9.5 mm said so of
#: data whose own calibration reported 10.4 mm.
BLOCKS_MARGIN = 1.0 / (1.0 + 1.0 / math.sqrt(2.0 * 3 * (BLOCKS - 1)))


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

    def to_dict(self) -> QualityDoc:
        return {
            'verdict': str(self.verdict),
            'reasons': [
                {'code': str(r.code), 'severity': str(r.severity), 'message': r.message}
                for r in self.reasons
            ],
            'notes': list(self.notes),
        }
