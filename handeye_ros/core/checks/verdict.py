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
                                       beyond its sigmas (BATCH_*) and the self-check sided
                                       against it
few_inliers                 doubtful   fewer than 20 % of the motions are RANSAC inliers
weak_excitation             doubtful   the rotation axes spread less than 10 deg
unobservable                doubtful   a component of T_HE, the clock drift or the scale
                                       cannot be determined (named)
seed_dependent              doubtful   the linear stage's answer moves with the RANSAC seed
                                       (beyond SEED_*)
no_uncertainty              doubtful   the batch stage could not run: no sigmas
imprecise                   doubtful   a 1-sigma exceeds the required precision
                                       (options precision_time_offset, _translation,
                                       _rotation; default 1 ms, 1 cm, 0.5 deg)
clock_drift                 doubtful   without clock_drift: the offset measured in windows
                                       changes along the recording by more than
                                       DRIFT_NOTICE_S and DRIFT_SIGMAS (the rate is named)
scale                       doubtful   without estimate_scale: a scale explains the eye's
                                       translations and is large, or moves T_HE by more
                                       than precision_translation (named with its value)
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

Most rules run at the end (:func:`assess`, :func:`assess_model`); those met while a stage
runs (scale, clock_drift, seed_dependent, stages_disagree, the self-check's tie) are the
functions at the end of this module, which the stages call. ``unobservable`` and a failed
rerun are said where the stage finds them: they have no threshold.

A rig of many recordings (:mod:`..shared`) has its own verdict, from its own rules
(:func:`assess_rig`; the groups are :mod:`.consistency`'s):

==========================  =========  =================================================
recording_left_out          doubtful   a recording gave no calibration, or its T_HE
                                       disagrees with the others' (named with the
                                       difference); the rig's T_HE is computed without it
groups                      doubtful   the recordings form groups that agree within
                                       themselves and not with each other (a moved
                                       marker); the rig's T_HE is the largest group's,
                                       each group is reported
no_agreement                failed     fewer than two recordings agree, or the largest
                                       groups are as large as each other (a rig of one
                                       recording and nothing else is not said)
==========================  =========  =================================================

Notes that do not lower the verdict (resets split, an epoch difference, a self-check that
settled clearly) are in ``notes``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:  # for the rules' signatures only: the records of the stages' math below
    from ..batch.refine import BatchSolution
    from ..config import CalibrationConfig
    from ..eye_model import EyeModel
    from ..linear.robust import LinearSolution
    from ..linear.scale import ScaleFit
    from ..time.align import TimeAlignment
    from ..time.clock import DriftFit
    from ..world import Metrics
    from .screening import Screening
    from .selfcheck import Candidate


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


@dataclass(frozen=True)
class Reason:
    """Why the verdict is not better: a stable ``code`` and a ``message`` for people; its
    ``severity`` is the code's (:data:`SEVERITY`)."""

    code: Code
    message: str

    @property
    def severity(self) -> Verdict:
        return SEVERITY[self.code]


class Findings(Protocol):
    """What the rules read and add to: the stages' findings
    (:class:`~handeye_ros.core.stages.findings.Findings`, which sits above the checks)."""

    reasons: list[Reason]
    notes: list[str]
    candidates: list[Candidate]


def _say(run: Findings, code: Code, message: str) -> None:
    """A reason for the verdict, added to the findings (only the rules here make reasons)."""
    run.reasons.append(Reason(code, message))


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
            _say(
                run,
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
        _say(
            run,
            Code.AMBIGUOUS_OFFSET,
            f'the correlation has a second peak at '
            f'{ta.second_peak_ratio:.0%} of the main one (repetitive motion) and no '
            'other candidate offset could be checked',
        )
    peaks = [ta.peak_correlation] + ([tv.peak_correlation] if tv is not None else [])
    if ta.method != 'fixed' and max(peaks) < WEAK_CORRELATION:
        _say(
            run,
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
        _say(
            run,
            Code.FEW_INLIERS,
            f'only {lin.n_inliers} of {lin.n_motions} motions are RANSAC inliers',
        )
    if lin.unobservable:
        _say(
            run,
            Code.UNOBSERVABLE,
            'part of the extrinsic cannot be observed from this motion: '
            + '; '.join(lin.unobservable),
        )
    elif lin.axis_spread_deg < WEAK_EXCITATION_DEG:
        _say(
            run,
            Code.WEAK_EXCITATION,
            f'the rotation axes spread only {lin.axis_spread_deg:.1f} '
            'deg: the extrinsic is weakly constrained; rotate about more different axes',
        )


def sigmas_of(std: np.ndarray) -> tuple[float, float, float]:
    """The three 1-sigmas the precision targets judge, from a batch std (dt [s], translation
    [m] x3, rotation [rad] x3): dt [s], the translation's norm [m], the rotation's [deg]."""
    return (
        float(std[0]),
        float(np.linalg.norm(std[1:4])),
        float(np.degrees(np.linalg.norm(std[4:7]))),
    )


def precision_ratios(sigmas: tuple[float, ...], targets: tuple[float, ...]) -> list[float]:
    """Each 1-sigma (:func:`sigmas_of`) over its target (``CalibrationConfig.precision``):
    above 1 it is ``imprecise``. An unknown sigma (NaN) is no ratio (NaN)."""
    return [s / t for s, t in zip(sigmas, targets, strict=True)]


def precision_ratio(sigmas: tuple[float, ...], targets: tuple[float, ...]) -> float:
    """The largest of :func:`precision_ratios`, inf while a sigma is unknown: at most 1 is
    precise enough, for the verdict, the readiness and the node's auto mode alike."""
    ratios = precision_ratios(sigmas, targets)
    return float('inf') if not all(np.isfinite(ratios)) else max(ratios)


def _assess_uncertainty(
    batch: BatchSolution | None, cfg: CalibrationConfig, run: Findings
) -> None:
    """Stage 3's uncertainty: none, larger than required, or shaped by something unmodelled."""
    if cfg.batch and batch is None and not any(r.code == Code.UNOBSERVABLE for r in run.reasons):
        _say(
            run,
            Code.NO_UNCERTAINTY,
            'the batch stage did not run, so the result has no uncertainty (see the warnings)',
        )
    if batch is not None:
        sd, need = sigmas_of(batch.std), cfg.precision
        over = [
            f'{name} {v * k:.3g} {unit} (required {n * k:.3g})'
            for name, v, n, k, unit, r in zip(
                ('time offset', 'translation', 'rotation'),
                sd,
                need,
                (1e3, 1e3, 1.0),
                ('ms', 'mm', 'deg'),
                precision_ratios(sd, need),
                strict=True,
            )
            if r > 1.0
        ]
        if over:
            _say(
                run,
                Code.IMPRECISE,
                'the 1-sigma uncertainty exceeds the required precision: '
                + ', '.join(over)
                + '. More varied rotation (faster, about all axes) or '
                'a longer recording narrows it; the precision_* options set what is '
                'required',
            )
    if batch is not None and float(np.max(batch.inflation)) > INFLATION_DOUBTFUL:
        _say(
            run,
            Code.RESIDUALS_NOT_WHITE,
            f'the residuals are strongly correlated in time (the '
            f'long-run sigmas are up to {np.max(batch.inflation):.1f}x the white ones): '
            'something the model lacks (clock drift, a scale error) shapes them',
        )


def _assess_consistency(m: Metrics, run: Findings) -> None:
    """AX = XB at the result, over the keyframe motions: failing it fails the result."""
    reason = motion_inconsistency(m)
    if reason is not None:
        run.reasons.append(reason)


def motion_inconsistency(m: Metrics, where: str = 'the result') -> Reason | None:
    """The ``inconsistent`` reason when AX = XB fails over the keyframe motions at ``where``
    (the thresholds FAILED_MOTION_*), else None."""
    if m.n_motions and (
        m.motion_rotation_deg > FAILED_MOTION_ROTATION_DEG
        or (
            m.motion_translation_m > FAILED_MOTION_TRANSLATION_M
            and m.motion_translation_m > FAILED_MOTION_TRANSLATION_FRACTION * m.motion_length_m
        )
    ):
        return Reason(
            Code.INCONSISTENT,
            f'AX = XB does not hold at {where}: over {m.n_motions} '
            f'keyframe motions the median error is {m.motion_rotation_deg:.2f} deg and '
            f'{m.motion_translation_m * 1e3:.0f} mm (the motions are '
            f'{m.motion_length_m * 1e3:.0f} mm long)',
        )
    return None


def assess_model(
    model: EyeModel, clock: DriftFit | None, cfg: CalibrationConfig, run: Findings
) -> None:
    """Reasons about the clock drift and the scale, when they were estimated."""
    if cfg.estimate_scale:
        std = model.scale_std
        if not model.scale_observable:
            sd = f' +- {std:.2g}' if np.isfinite(std) else ''
            _say(
                run,
                Code.UNOBSERVABLE,
                f"the eye's scale cannot be observed (s = "
                f'{model.scale:.4g}{sd}): the hand translates too little for its '
                'translations to be told from a lever arm, so the translation of T_HE '
                'is as uncertain. Move the rig through space, not only about itself',
            )
    if cfg.clock_drift and model.drift_estimated and clock is not None:
        half = 0.5 * clock.span_s * model.drift_std
        if half > cfg.precision_time_offset:
            _say(
                run,
                Code.IMPRECISE,
                f'the clock drift is {model.drift * 1e6:+.1f} +- '
                f'{model.drift_std * 1e6:.1f} ppm: at the ends of the recording the '
                f'offset is uncertain by {half * 1e3:.2g} ms from the drift alone '
                f'(required {cfg.precision_time_offset * 1e3:.3g} ms)',
            )


# ---------------------------------------------------------------- rules met during the run
# The stages meet these as they run (a fit, a rerun, a comparison) and add what they return to
# the run's Findings; the rules above run once, at the end (assess, assess_model).


def scale_reason(fit: ScaleFit, precision_m: float) -> Reason | None:
    """SCALE, without estimate_scale: a scale explains the eye's translations
    (:attr:`~handeye_ros.core.linear.scale.ScaleFit.clear`) and is large (``significant``) or
    moves T_HE by more than ``precision_m`` when s = 1 is taken."""
    if fit.clear and (fit.significant or fit.shift_m > precision_m):
        return Reason(Code.SCALE, scale_message(fit))
    return None


def drift_significant(fit: DriftFit) -> bool:
    """Whether the drift moves the offset by more than DRIFT_NOTICE_S over the recording and
    is further from zero than its own uncertainty explains: beyond the Student-t quantile
    (n - 2 degrees of freedom, n the windows fitted) at the false-alarm rate of DRIFT_SIGMAS
    Gaussian sigmas (:func:`drift_threshold_sigmas`)."""
    return bool(
        fit.estimated
        and abs(fit.change_s) > DRIFT_NOTICE_S
        and abs(fit.drift) > drift_threshold_sigmas(fit) * fit.drift_std
    )


def drift_threshold_sigmas(fit: DriftFit) -> float:
    """How many of its sigmas a drift must reach to be significant. The sigma is itself
    estimated from a few windows' scatter; at 3 Gaussian sigmas 15 windows need 3.8, 6
    windows 6.4."""
    from scipy.special import ndtr, stdtrit

    dof = int(np.sum(fit.inliers)) - 2
    return float(stdtrit(dof, ndtr(DRIFT_SIGMAS))) if dof > 0 else float('inf')


def drift_reason(fit: DriftFit) -> Reason | None:
    """CLOCK_DRIFT, without clock_drift: the offset measured in windows drifts
    (:func:`drift_significant`)."""
    return Reason(Code.CLOCK_DRIFT, drift_message(fit)) if drift_significant(fit) else None


def seed_reason(
    seed: int, d_rot_deg: float, d_t_m: float, batch_std: np.ndarray | None
) -> Reason | None:
    """SEED_DEPENDENT: stage 2 with RANSAC seed ``seed`` lands d_rot_deg / d_t_m away, beyond
    SEED_SIGMAS of the batch stage's sigmas (``batch_std``: dt, p, theta) and at least
    SEED_ROTATION_DEG / SEED_TRANSLATION_M."""
    lim_rot, lim_t = SEED_ROTATION_DEG, SEED_TRANSLATION_M
    if batch_std is not None:
        lim_t = max(lim_t, SEED_SIGMAS * float(np.linalg.norm(batch_std[1:4])))
        lim_rot = max(lim_rot, SEED_SIGMAS * float(np.degrees(np.linalg.norm(batch_std[4:7]))))
    if d_rot_deg > lim_rot or d_t_m > lim_t:
        return Reason(
            Code.SEED_DEPENDENT,
            f'with RANSAC seed {seed} the linear stage gives an extrinsic '
            f'{d_t_m * 1e3:.0f} mm / {d_rot_deg:.2f} deg away: the motions do not single out '
            'one answer',
        )
    return None


def batch_moved(
    moved_dt_s: float, moved_t_m: float, moved_r_deg: float, std: np.ndarray
) -> tuple[bool, bool]:
    """Whether the batch stage moved dt, and T_HE, beyond its own sigmas ``std`` (dt, p,
    theta): BATCH_SIGMAS of them and at least BATCH_DT_MIN_S, BATCH_TRANSLATION_MIN_M,
    BATCH_ROTATION_MIN_DEG. Either sends the question to the self-check."""
    far_dt = moved_dt_s > max(BATCH_SIGMAS * std[0], BATCH_DT_MIN_S)
    far_x = moved_t_m > max(
        BATCH_SIGMAS * float(np.linalg.norm(std[1:4])), BATCH_TRANSLATION_MIN_M
    ) or moved_r_deg > max(
        BATCH_SIGMAS * float(np.degrees(np.linalg.norm(std[4:]))), BATCH_ROTATION_MIN_DEG
    )
    return bool(far_dt), bool(far_x)


def batch_supported(score: list[float], far_dt: bool) -> bool:
    """STAGES_DISAGREE unless this holds: the self-check's scores (linear stage, [linear stage
    at the batch offset when dt moved,] batch stage) keep the batch offset within
    AMBIGUOUS_SCORE_RATIO of the linear one and its extrinsic within BATCH_SCORE_FACTOR of
    stage 2's at the same offset."""
    offset_ok = not far_dt or score[1] <= AMBIGUOUS_SCORE_RATIO * score[0]
    return offset_ok and score[-1] <= BATCH_SCORE_FACTOR * score[-2]


def judge_tie(scored: list[Candidate], shift_ns: int, run: Findings) -> int:
    """Index of the winner. Candidates scoring within AMBIGUOUS_SCORE_RATIO of the best are a
    tie (the verdict says so); a tie goes to the smallest offset, the likelier one when two
    clocks were started together."""
    best = next(k for k, c in enumerate(scored) if c.chosen)
    win = scored[best]
    if not np.isfinite(win.score):
        _say(
            run,
            Code.AMBIGUOUS_OFFSET,
            'the candidate offsets could not be compared (too few motions covered at all of them)',
        )
        return best
    tied = [
        k
        for k, c in enumerate(scored)
        if np.isfinite(c.score) and c.score <= AMBIGUOUS_SCORE_RATIO * win.score
    ]
    text = ', '.join(
        f'{shift_ns * 1e-9 + c.time_offset_s:+.4f} s ({c.source}, score {c.score:.3g})'
        for c in scored
    )
    if len(tied) == 1:
        run.notes.append(
            f'self-check over the candidate offsets {text}: '
            f'{shift_ns * 1e-9 + win.time_offset_s:+.4f} s ({win.source}) won'
        )
        return best
    best = min(tied, key=lambda k: abs(shift_ns * 1e-9 + scored[k].time_offset_s))
    _say(
        run,
        Code.AMBIGUOUS_OFFSET,
        f'the motion repeats itself: the self-check cannot separate '
        f'the candidate offsets {text}; the smallest of the tied ones was taken. Narrow '
        'the search with time_offset_guess and max_time_offset (less than half the '
        'period of the motion), or record a less repetitive motion',
    )
    return best


def scale_message(fit: ScaleFit) -> str:
    return (
        f"the eye's translations look scaled: s = {fit.scale:.4g} +- "
        f"{fit.scale_std:.2g} (s * eye positions metric) makes them fit the hand's "
        f'(median translation residual {fit.rms_with * 1e3:.0f} mm with it, '
        f'{fit.rms_without * 1e3:.0f} mm without), and taking s = 1 moves the translation '
        f'of T_HE by {fit.shift_m * 1e3:.0f} mm: a monocular VO, a metric VIO whose scale is '
        f'off by {abs(fit.scale - 1.0):.1%}, or positions in other units. Estimate it with '
        '--scale (node parameter estimate_scale)'
    )


#: A metric eye whose scale the uncertainty's nuisance fit puts this far from 1, and beyond
#: this many of its own sigmas, is named in a note (a VIO's scale error of a per cent).
SCALE_NAMED = 0.01
SCALE_NAMED_SIGMAS = 3.0


def scale_uncertainty_note(scale: float, std: float, shift_m: float) -> str | None:
    """The note that names a metric eye's scale error the uncertainty carries, or None."""
    d = abs(scale - 1.0)
    if not (d >= SCALE_NAMED and d > SCALE_NAMED_SIGMAS * std):
        return None
    return (
        f"the eye's translations fit a scale s = {scale:.4f} +- {std:.2g} ({d:.1%} "
        f'{"long" if scale > 1.0 else "short"}): taking s = 1 moves the translation of T_HE '
        f'by {shift_m * 1e3:.1f} mm, which its uncertainty includes. Estimate it with --scale '
        '(node parameter estimate_scale) if the eye is not metric'
    )


def drift_message(fit: DriftFit) -> str:
    n = int(fit.inliers.sum())
    return (
        f'the time offset drifts: measured in {n} windows along the recording it changes '
        f'at {fit.drift * 1e6:+.1f} +- {fit.drift_std * 1e6:.1f} ppm, '
        f'{fit.change_s * 1e3:+.1f} ms between the first and the last eye pose; the '
        'result holds one mean offset, so the ends are off by about '
        f'{abs(fit.change_s) * 0.5e3:.1f} ms. Estimate the drift with --clock-drift (node '
        'parameter clock_drift)'
    )


def assess_rig(
    names: list[str], groups: tuple[tuple[int, ...], ...], why_not: dict[str, str]
) -> Quality:
    """The rig's verdict (the second table of the module docstring): ``names`` of the
    recordings that gave a calibration, their ``groups`` (largest first), and ``why_not`` the
    others' reasons; the messages of the left-out ones come with :mod:`.consistency`'s tests."""
    reasons = [
        Reason(Code.RECORDING_LEFT_OUT, f'{name}: left out, {why}')
        for name, why in why_not.items()
    ]
    main = groups[0] if groups else ()
    # one recording alone is a rig of one (the node's first session): nothing to disagree with
    alone = len(names) == 1 and not why_not
    if not alone and (len(main) < 2 or sum(len(g) == len(main) for g in groups) > 1):
        said = ' and '.join(
            '{' + ', '.join(names[k] for k in g) + '}' for g in groups if len(g) == len(main)
        )
        reasons.append(
            Reason(
                Code.NO_AGREEMENT,
                'no group of recordings is the largest to agree on T_HE'
                + (f': {said}' if said else ''),
            )
        )
    if sum(len(g) > 1 for g in groups) > 1:
        said = '; '.join(', '.join(names[k] for k in g) for g in groups if len(g) > 1)
        reasons.append(
            Reason(
                Code.GROUPS,
                f'the recordings form {sum(len(g) > 1 for g in groups)} groups that agree '
                f'within themselves, not with each other (a moved marker?): {said}; the '
                "rig's T_HE is the first group's, each group's is reported",
            )
        )
    return Quality.from_reasons(reasons, [])


def convention_corrected(message: str) -> Reason:
    """CONVENTION_CORRECTED: a reading of the input was assumed (the file keeps the mistake)."""
    return Reason(Code.CONVENTION_CORRECTED, message)


def seed_failed(seed: int, error: str) -> Reason:
    """SEED_DEPENDENT: stage 2 with RANSAC seed ``seed`` finds no answer at all."""
    return Reason(Code.SEED_DEPENDENT, f'with RANSAC seed {seed} the linear stage fails ({error})')


def drift_unobservable(why: str | None) -> Reason:
    """UNOBSERVABLE, with clock_drift: the drift cannot be measured (``why``; None: the eye
    has keyframes only, and the windows need angular velocities)."""
    if why is None:
        return Reason(
            Code.UNOBSERVABLE,
            'the clock drift is measured in windows of angular velocity, which a '
            'keyframe-only eye does not give; one constant offset was estimated instead',
        )
    return Reason(
        Code.UNOBSERVABLE,
        f'the clock drift cannot be observed: {why}. One constant offset was estimated instead',
    )


def stages_disagree(what: str, failed: str | None = None, scored: list | None = None) -> Reason:
    """STAGES_DISAGREE: the batch stage moved the answer (``what``) and the self-check does
    not support it: stage 2 ``failed`` at the batch's offset, the scores could not be compared
    (``scored`` None), or they side with the linear result (``scored``: the candidates)."""
    if failed is not None:
        return Reason(Code.STAGES_DISAGREE, f'{what}, and stage 2 fails at its offset ({failed})')
    if scored is None:
        return Reason(Code.STAGES_DISAGREE, f'{what}, and the self-check could not compare them')
    return Reason(
        Code.STAGES_DISAGREE,
        f'{what}; the self-check sides with the linear result (scores '
        + ', '.join(f'{c.source} {c.score:.3g}' for c in scored)
        + '), which is kept',
    )
