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


class Purpose(StrEnum):
    """What the calibration is for, which decides what "precise enough" means: the APE/RPE
    of an evaluation (the calibration's share of each figure) or T_HE and dt themselves (the
    ``precision_*`` targets). Every other rule judges both."""

    EVALUATION = 'evaluation'
    EXTRINSIC = 'extrinsic'


BOTH = frozenset(Purpose)


class Code(StrEnum):
    """Why a verdict is not better (the table of the module docstring)."""

    CONVENTION_CORRECTED = 'convention_corrected'
    OUTLIERS_REMOVED = 'outliers_removed'
    AMBIGUOUS_OFFSET = 'ambiguous_offset'
    OFFSET_DISAGREES = 'offset_disagrees'
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
    NOISY_MOCAP = 'noisy_mocap'
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
#: The batch stage holds the spline fitted to the MoCap as exact (docs/method.md). Its rotation
#: noise is noise in the regressor of T_HE's translation (eq. 16), which draws the lever arm
#: toward zero by about the square of that noise: where the MoCap's noise drawn once more (its
#: variance doubled) moves dt or T_HE by more than this many sigmas, the noise already in it
#: has biased the answer about as far (:mod:`..batch.spacing`).
NOISE_MOVE_DOUBTFUL = 1.0
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
#: is noted to be near its target (a calibration of more data may find it above), and READY
#: waits (:func:`.final.settled`). The same for an evaluation's figures, whose 1-sigmas are
#: the covariance's drawn through them.
BLOCKS_MARGIN = 1.0 / (1.0 + 1.0 / math.sqrt(2.0 * 3 * (BLOCKS - 1)))
#: For purpose evaluation, an APE/RPE figure is settled when the calibration's 1-sigma on it is
#: at most this share of it: two systems whose figures differ by 15 % (three such sigmas) are
#: then told apart whatever the calibration's error, and the share stays below the spread a
#: figure has between runs of one system on one sequence (commonly 5-10 %).
EVALUATION_SHARE = 0.05


@dataclass(frozen=True)
class Reason:
    """Why the verdict is not better: a stable ``code`` and a ``message`` for people; its
    ``severity`` is the code's (:data:`SEVERITY`); ``purposes``: the purposes whose verdict it
    lowers (:class:`Purpose`; both unless it judges only one)."""

    code: Code
    message: str
    purposes: frozenset[Purpose] = BOTH

    @property
    def severity(self) -> Verdict:
        return SEVERITY[self.code]


def _worst_first(reasons: tuple[Reason, ...]) -> tuple[Reason, ...]:
    worst = list(Verdict)[::-1]  # failed first
    return tuple(sorted(reasons, key=lambda r: worst.index(r.severity)))


@dataclass(frozen=True)
class Quality:
    """The verdict for ``purpose``, its reasons (worst first) and notes that did not lower
    it; ``found``: every purpose's reasons, from which :meth:`judged_for` gives the other's.
    ``evaluated``: the evaluation's own figures were judged (their calibration 1-sigmas,
    which the evaluation layer computes: :func:`.final.assess_evaluation`); until then the
    extrinsic's rules stand in for the evaluation's, which are never looser unjudged.
    ``share_ratio``: then the largest of the figures' calibration 1-sigmas over
    EVALUATION_SHARE of the figure (above 1 ``imprecise``; NaN until judged or without
    one)."""

    verdict: Verdict
    reasons: tuple[Reason, ...] = ()
    notes: tuple[str, ...] = field(default=())
    purpose: Purpose = Purpose.EVALUATION
    found: tuple[Reason, ...] = ()
    evaluated: bool = False
    share_ratio: float = math.nan

    @classmethod
    def from_reasons(
        cls,
        reasons: list[Reason],
        notes: list[str],
        purpose: Purpose = Purpose.EVALUATION,
        evaluated: bool = False,
        share_ratio: float = math.nan,
    ) -> Quality:
        found = _worst_first(tuple(reasons))
        judge = Purpose.EXTRINSIC if purpose == Purpose.EVALUATION and not evaluated else purpose
        mine = tuple(r for r in found if judge in r.purposes)
        verdict = mine[0].severity if mine else Verdict.GOOD
        return cls(verdict, mine, tuple(notes), purpose, found, evaluated, share_ratio)

    def judged_for(self, purpose: Purpose) -> Quality:
        """The same findings judged for ``purpose``."""
        return Quality.from_reasons(
            list(self.found), list(self.notes), purpose, self.evaluated, self.share_ratio
        )

    def with_evaluation(
        self, reasons: list[Reason], notes: list[str], share_ratio: float = math.nan
    ) -> Quality:
        """With the rules on the evaluation's figures (:func:`.final.assess_evaluation`) and
        their largest ratio to their line."""
        return Quality.from_reasons(
            [*self.found, *reasons], [*self.notes, *notes], self.purpose, True, share_ratio
        )

    @property
    def other(self) -> Quality:
        """The verdict for the purpose not judged."""
        (other,) = set(Purpose) - {self.purpose}
        return self.judged_for(other)

    @property
    def codes(self) -> tuple[str, ...]:
        return tuple(r.code for r in self.reasons)

    def label(self, sep: str = ', ') -> str:
        """The verdict and its reason codes, e.g. ``doubtful (ambiguous_offset)``."""
        return self.verdict + (f' ({sep.join(self.codes)})' if self.reasons else '')

    def to_dict(self) -> QualityDoc:
        judged = {p: self.judged_for(p) for p in Purpose}
        return {
            'verdict': str(self.verdict),
            'purpose': str(self.purpose),
            'reasons': [
                {'code': str(r.code), 'severity': str(r.severity), 'message': r.message}
                for r in self.reasons
            ],
            'notes': list(self.notes),
            'for_evaluation': {
                'verdict': str(judged[Purpose.EVALUATION].verdict),
                'codes': [str(c) for c in judged[Purpose.EVALUATION].codes],
                'figures_judged': self.evaluated,
            },
            'for_extrinsic': {
                'verdict': str(judged[Purpose.EXTRINSIC].verdict),
                'codes': [str(c) for c in judged[Purpose.EXTRINSIC].codes],
            },
        }
