"""The rules of what the stages meet as they run (a fit, a rerun, a comparison): the decisions a
stage needs to go on (:func:`batch_moved`, :func:`batch_supported`, :func:`judge_tie`,
:func:`scale_keeps_whole`), and :func:`read`, which says what each fact a stage recorded
(:mod:`.facts`) means for the verdict. The rules of :mod:`.final` run once, at the end."""

from __future__ import annotations

from typing import TYPE_CHECKING, assert_never

import numpy as np

from ...arrays import Floats
from .codes import (
    AMBIGUOUS_SCORE_RATIO,
    BATCH_DT_MIN_S,
    BATCH_ROTATION_MIN_DEG,
    BATCH_SCORE_FACTOR,
    BATCH_SIGMAS,
    BATCH_TRANSLATION_MIN_M,
    DRIFT_NOTICE_S,
    DRIFT_SIGMAS,
    SEED_ROTATION_DEG,
    SEED_SIGMAS,
    SEED_TRANSLATION_M,
    Code,
    Reason,
)
from .facts import (
    ConventionCorrected,
    DriftMeasured,
    DriftUnobservable,
    Fact,
    FixedOffsetDisagrees,
    ScaleMeasured,
    SeedCompared,
    SeedFailed,
    StagesDisagree,
)

if TYPE_CHECKING:  # for the rules' signatures only: the records of the stages' math
    from ...linear.scale import ScaleFit
    from ...time.clock import DriftFit
    from ..selfcheck import Candidate


def scale_reason(fit: ScaleFit) -> Reason | None:
    """SCALE, without estimate_scale: a scale explains the eye's translations
    (:attr:`~handeye_ros.core.linear.scale.ScaleFit.clear`) and is large (``significant``: a
    monocular VO, other units), so that no metric of the eye as given means much. A smaller
    one (a metric VIO a few per cent off) is a note: the batch stage fits T_HE with the scale
    free (:mod:`...batch.correlated`)."""
    if fit.clear and fit.significant:
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
    seed: int, d_rot_deg: float, d_t_m: float, batch_std: Floats | None
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
    moved_dt_s: float, moved_t_m: float, moved_r_deg: float, std: Floats
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


def judge_tie(scored: list[Candidate], shift_ns: int) -> tuple[int, Reason | str]:
    """Index of the winner, and what the self-check says: a note when one candidate won, the
    AMBIGUOUS_OFFSET reason when candidates scoring within AMBIGUOUS_SCORE_RATIO of the best
    tie; a tie goes to the smallest offset, the likelier one when two clocks were started
    together."""
    best = next(k for k, c in enumerate(scored) if c.chosen)
    win = scored[best]
    if not np.isfinite(win.score):
        return best, Reason(
            Code.AMBIGUOUS_OFFSET,
            'the candidate offsets could not be compared (too few motions covered at all of them)',
        )
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
        return best, (
            f'self-check over the candidate offsets {text}: '
            f'{shift_ns * 1e-9 + win.time_offset_s:+.4f} s ({win.source}) won'
        )
    best = min(tied, key=lambda k: abs(shift_ns * 1e-9 + scored[k].time_offset_s))
    return best, Reason(
        Code.AMBIGUOUS_OFFSET,
        f'the motion repeats itself: the self-check cannot separate '
        f'the candidate offsets {text}; the smallest of the tied ones was taken. Narrow '
        'the search with time_offset_guess and max_time_offset (less than half the '
        'period of the motion), or record a less repetitive motion',
    )


def scale_message(fit: ScaleFit) -> str:
    return (
        f"the eye's translations look scaled: s = {fit.scale:.4g} +- "
        f"{fit.scale_std:.2g} (s * eye positions metric) makes them fit the hand's "
        f'(median translation residual {fit.rms_with * 1e3:.0f} mm with it, '
        f'{fit.rms_without * 1e3:.0f} mm without), and s = 1 moves the translation of '
        f"stage 2's T_HE by {fit.shift_m * 1e3:.0f} mm: a monocular VO, a metric VIO whose "
        f'scale is off by {abs(fit.scale - 1.0):.1%}, or positions in other units. Estimate '
        'it with --scale (node parameter estimate_scale)'
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
        f'{"long" if scale > 1.0 else "short"}): T_HE is fitted with it free (s = 1 would move '
        f'its translation by {shift_m * 1e3:.1f} mm) and the metrics keep the eye as given. '
        'Estimate it with --scale (node parameter estimate_scale) if the eye is not metric'
    )


def varies_note(group: str, spread: float, ratio: float, sigma: float) -> str:
    """The note that a group's value moves along the recording: its blocks' ``spread`` (the norm
    over its axes, SI units), ``ratio`` times what their own noise explains; the result holds its
    mean over the recording, uncertain by ``sigma``."""
    what, unit, k, why = {
        'time_offset': (
            'the time offset',
            'ms',
            1e3,
            "the eye's latency wanders or its clock jumped",
        ),
        'translation': (
            'the translation of T_HE',
            'mm',
            1e3,
            'the eye errs alike over minutes or the markers slipped',
        ),
        'rotation': (
            'the rotation of T_HE',
            'deg',
            float(np.degrees(1.0)),
            'the eye errs alike over minutes or the markers slipped',
        ),
    }[group]
    return (
        f'{what} varies along the recording ({why}): its four quarters, fitted alone, spread '
        f'by {spread * k:.2g} {unit}, {ratio:.2g} times what their own noise explains; the '
        f'result is its mean over the recording, uncertain by {sigma * k:.2g} {unit}'
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


def stages_disagree(
    what: str, failed: str | None = None, scored: list[Candidate] | None = None
) -> Reason:
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


def scale_keeps_whole(fit: ScaleFit, precision_m: float) -> bool:
    """Whether stage 2 leaves the eye whole for the scale measured without estimate_scale: one
    that explains the eye's translations and is large, or moves stage 2's T_HE (at s = 1) by
    more than ``precision_m``: the eye's motion then disagrees with the hand's everywhere by
    one factor, and splitting it at "breaks" would only hide that."""
    return fit.clear and (fit.significant or fit.shift_m > precision_m)


def drift_constant_note(fit: DriftFit) -> str | None:
    """The note of a drift measured and not significant (None when it was not measured)."""
    if not fit.estimated:
        return None
    return (
        f'the offset measured in {int(fit.inliers.sum())} windows along '
        f'the recording is constant within its uncertainty (drift '
        f'{fit.drift * 1e6:+.1f} +- {fit.drift_std * 1e6:.1f} ppm)'
    )


def drift_fitted_note(measured: DriftFit, fitted: float) -> str:
    """The note of a drift that a default run measured along the recording (``measured``,
    significant: :func:`drift_significant`) and then fitted (``fitted``, s/s)."""
    return (
        f'clock drift {fitted * 1e6:+.1f} ppm measured ({measured.drift * 1e6:+.1f} +- '
        f'{measured.drift_std * 1e6:.1f} ppm over {int(measured.inliers.sum())} windows along '
        'the recording) and fitted; --no-clock-drift (auto_drift false) keeps one constant '
        'offset'
    )


def drift_explains(drift: float, drift_std: float, still_varies: bool) -> bool:
    """Whether a drift fitted because the time offset varied along the recording (its quarters
    disagreeing, while the windows' drift was not significant) explains that: the drift is
    beyond DRIFT_SIGMAS of its own sigma, and with it the quarters agree."""
    return abs(drift) > DRIFT_SIGMAS * drift_std and not still_varies


def drift_explains_note(spread_s: float, fitted: float) -> str:
    """The note of a drift fitted because it explains how the offset varied (``spread_s``, the
    quarters' spread [s]; ``fitted`` [s/s])."""
    return (
        f'clock drift {fitted * 1e6:+.1f} ppm fitted: the time offset varied along the '
        f'recording (its quarters spread by {spread_s * 1e3:.2g} ms) and the drift explains it; '
        '--no-clock-drift (auto_drift false) keeps one constant offset'
    )


def read(entry: Fact | Reason) -> tuple[Reason | None, str | None]:
    """What a fact of the stages means for the verdict: (a reason or None, a note or None); a
    reason made on the way reads as itself."""
    match entry:
        case Reason():
            return entry, None
        case ConventionCorrected(message=message):
            return convention_corrected(message), None
        case FixedOffsetDisagrees():
            text = (
                f'the fixed time offset {entry.fixed_s * 1e3:+.1f} ms is not where the angular '
                f'speeds agree ({entry.measured_s * 1e3:+.1f} ms, correlation '
                f'{entry.correlation:.2f}): every figure at it is off; check the fixed value'
            )
            return Reason(Code.OFFSET_DISAGREES, text), None
        case ScaleMeasured(fit=fit):
            reason = scale_reason(fit)
            if reason is not None or not fit.clear:
                return reason, None
            return None, scale_message(fit)  # named; T_HE is fitted with it free
        case DriftMeasured(fit=fit):
            reason = drift_reason(fit)
            return (reason, None) if reason is not None else (None, drift_constant_note(fit))
        case DriftUnobservable(why=why):
            return drift_unobservable(why), None
        case SeedFailed(seed=seed, error=error):
            return seed_failed(seed, error), None
        case SeedCompared():
            return seed_reason(
                entry.seed, entry.rotation_deg, entry.translation_m, entry.batch_std
            ), None
        case StagesDisagree():
            scored = None if entry.scored is None else list(entry.scored)
            return stages_disagree(entry.what, entry.failed, scored), None
        case _:
            assert_never(entry)
