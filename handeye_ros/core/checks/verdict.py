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
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # for the rules' signatures only: checks sit above the stages
    from ..batch.refine import BatchSolution
    from ..config import CalibrationConfig
    from ..eye_model import EyeModel
    from ..findings import Findings
    from ..linear.robust import LinearSolution
    from ..time.align import TimeAlignment
    from ..time.clock import DriftFit
    from ..world import Metrics
    from .screening import Screening


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


def assess(
    ta: TimeAlignment,
    tv: TimeAlignment | None,
    lin: LinearSolution,
    batch: BatchSolution | None,
    screening: tuple[Screening, Screening],
    metrics: Metrics,
    cfg: CalibrationConfig,
    run: Findings,
) -> None:
    """The reasons judged on the finished run: the screening's share, a peak no self-check
    settled, weak correlation, few inliers, unobservable parts, weak excitation, no or too large
    an uncertainty, residuals not white, AX = XB failing (the others are added where they arise,
    their severities here: :data:`SEVERITY`)."""
    for rep in screening:
        if rep.fraction > OUTLIER_FRACTION_DOUBTFUL:
            run.reason(
                Code.OUTLIERS_REMOVED,
                f'screening removed {rep.fraction:.1%} of the '
                f'{rep.stream} stream ({rep.n_removed} of {rep.n_input} poses)',
            )
        elif rep.n_removed:
            run.notes.append(
                f'screening removed {rep.n_removed} of {rep.n_input} {rep.stream} poses'
            )
    checked = any(c.chosen for c in run.candidates)
    if ta.method != 'fixed' and ta.second_peak_ratio > AMBIGUOUS_PEAK_RATIO and not checked:
        run.reason(
            Code.AMBIGUOUS_OFFSET,
            f'the correlation has a second peak at '
            f'{ta.second_peak_ratio:.0%} of the main one (repetitive motion) and no '
            'other candidate offset could be checked',
        )
    peaks = [ta.peak_correlation] + ([tv.peak_correlation] if tv is not None else [])
    if ta.method != 'fixed' and max(peaks) < WEAK_CORRELATION:
        run.reason(
            Code.WEAK_CORRELATION,
            f'the angular velocities of the two streams hardly agree '
            f'(correlation {max(peaks):.2f}): check that both show the same motion',
        )
    _assess_linear(lin, run)
    _assess_uncertainty(batch, cfg, run)
    _assess_consistency(metrics, run)


def _assess_linear(lin: LinearSolution, run: Findings) -> None:
    """Stage 2's consensus and excitation."""
    if lin.n_inliers < LOW_INLIER_FRACTION * lin.n_motions:
        run.reason(
            Code.FEW_INLIERS, f'only {lin.n_inliers} of {lin.n_motions} motions are RANSAC inliers'
        )
    if lin.unobservable:
        run.reason(
            Code.UNOBSERVABLE,
            'part of the extrinsic cannot be observed from this motion: '
            + '; '.join(lin.unobservable),
        )
    elif lin.axis_spread_deg < WEAK_EXCITATION_DEG:
        run.reason(
            Code.WEAK_EXCITATION,
            f'the rotation axes spread only {lin.axis_spread_deg:.1f} '
            'deg: the extrinsic is weakly constrained; rotate about more different axes',
        )


def _assess_uncertainty(
    batch: BatchSolution | None, cfg: CalibrationConfig, run: Findings
) -> None:
    """Stage 3's uncertainty: none, larger than required, or shaped by something unmodelled."""
    if cfg.batch and batch is None and not any(r.code == 'unobservable' for r in run.reasons):
        run.reason(
            Code.NO_UNCERTAINTY,
            'the batch stage did not run, so the result has no uncertainty (see the warnings)',
        )
    if batch is not None:
        s = batch.std
        sd = (s[0], float(np.linalg.norm(s[1:4])), float(np.degrees(np.linalg.norm(s[4:7]))))
        need = (cfg.precision_time_offset, cfg.precision_translation, cfg.precision_rotation)
        over = [
            f'{name} {v * k:.3g} {unit} (required {n * k:.3g})'
            for name, v, n, k, unit in zip(
                ('time offset', 'translation', 'rotation'),
                sd,
                need,
                (1e3, 1e3, 1.0),
                ('ms', 'mm', 'deg'),
                strict=True,
            )
            if v > n
        ]
        if over:
            run.reason(
                Code.IMPRECISE,
                'the 1-sigma uncertainty exceeds the required precision: '
                + ', '.join(over)
                + '. More varied rotation (faster, about all axes) or '
                'a longer recording narrows it; the precision_* options set what is '
                'required',
            )
    if batch is not None and float(np.max(batch.inflation)) > INFLATION_DOUBTFUL:
        run.reason(
            Code.RESIDUALS_NOT_WHITE,
            f'the residuals are strongly correlated in time (the '
            f'long-run sigmas are up to {np.max(batch.inflation):.1f}x the white ones): '
            'something the model lacks (clock drift, a scale error) shapes them',
        )


def _assess_consistency(m: Metrics, run: Findings) -> None:
    """AX = XB at the result, over the keyframe motions: failing it fails the result."""
    if m.n_motions and (
        m.motion_rotation_deg > FAILED_MOTION_ROTATION_DEG
        or (
            m.motion_translation_m > FAILED_MOTION_TRANSLATION_M
            and m.motion_translation_m > FAILED_MOTION_TRANSLATION_FRACTION * m.motion_length_m
        )
    ):
        run.reason(
            Code.INCONSISTENT,
            f'AX = XB does not hold at the result: over {m.n_motions} '
            f'keyframe motions the median error is {m.motion_rotation_deg:.2f} deg and '
            f'{m.motion_translation_m * 1e3:.0f} mm (the motions are '
            f'{m.motion_length_m * 1e3:.0f} mm long)',
        )


def assess_model(
    model: EyeModel, clock: DriftFit | None, cfg: CalibrationConfig, run: Findings
) -> None:
    """Reasons about the clock drift and the scale, when they were estimated."""
    if cfg.estimate_scale:
        std = model.scale_std
        if not model.scale_observable:
            sd = f' +- {std:.2g}' if np.isfinite(std) else ''
            run.reason(
                Code.UNOBSERVABLE,
                f"the eye's scale cannot be observed (s = "
                f'{model.scale:.4g}{sd}): the hand translates too little for its '
                'translations to be told from a lever arm, so the translation of T_HE '
                'is as uncertain. Move the rig through space, not only about itself',
            )
    if cfg.clock_drift and model.drift_estimated and clock is not None:
        half = 0.5 * clock.span_s * model.drift_std
        if half > cfg.precision_time_offset:
            run.reason(
                Code.IMPRECISE,
                f'the clock drift is {model.drift * 1e6:+.1f} +- '
                f'{model.drift_std * 1e6:.1f} ppm: at the ends of the recording the '
                f'offset is uncertain by {half * 1e3:.2g} ms from the drift alone '
                f'(required {cfg.precision_time_offset * 1e3:.3g} ms)',
            )
