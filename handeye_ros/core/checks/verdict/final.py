"""The rules judged once a run is finished (:func:`assess_streams`, :func:`assess_answer`,
:func:`assess_model`), the verdict they end in (:func:`judged`: every fact the stages recorded
read, with these rules' reasons), the one "precise enough" rule (:func:`precision_ratio`)
the verdict, the readiness and the node's auto mode share, and how far a result is from it
(:func:`judged_ratio`, :func:`settled`: READY's margin)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

import numpy as np

from ...arrays import Floats
from .codes import (
    AMBIGUOUS_PEAK_RATIO,
    BLOCKS_MARGIN,
    BOTH,
    EVALUATION_SHARE,
    FAILED_MOTION_ROTATION_DEG,
    FAILED_MOTION_TRANSLATION_FRACTION,
    FAILED_MOTION_TRANSLATION_M,
    INFLATION_DOUBTFUL,
    LOW_INLIER_FRACTION,
    NOISE_MOVE_DOUBTFUL,
    OUTLIER_FRACTION_DOUBTFUL,
    WEAK_CORRELATION,
    WEAK_EXCITATION_DEG,
    Code,
    Purpose,
    Quality,
    Reason,
)
from .during import read
from .findings import Entry, Findings

if TYPE_CHECKING:  # for the rules' signatures only: the records of the stages' math
    from ...batch.refine import BatchSolution
    from ...config import CalibrationConfig
    from ...eye_model import EyeModel
    from ...linear.robust import LinearSolution
    from ...time.align import TimeAlignment
    from ...time.clock import DriftFit
    from ...world import Metrics
    from ..screening import Screening


def assess_streams(
    ta: TimeAlignment,
    screening: tuple[Screening, Screening],
    so_far: Findings,
) -> Findings:
    """The reasons and notes judged on the streams of the finished run (after what the stages
    found, ``so_far``): the screening's share, a peak no self-check settled (stage 1's
    alignment ``ta``), weak correlation (of ``ta``)."""
    said: list[Reason | str] = []
    for rep in screening:
        if rep.fraction > OUTLIER_FRACTION_DOUBTFUL:
            said.append(
                Reason(
                    Code.OUTLIERS_REMOVED,
                    f'screening removed {rep.fraction:.1%} of the '
                    f'{rep.stream} stream as wrong ({rep.n_outliers} of {rep.n_input} poses)',
                )
            )
        elif rep.n_outliers:
            said.append(
                f'screening removed {rep.n_outliers} of {rep.n_input} {rep.stream} poses as wrong'
            )
        if rep.n_placeholders:
            said.append(
                f'{rep.n_placeholders} of {rep.n_input} {rep.stream} poses say that there is no '
                'pose (the identity of a toolbox, zeros or the last pose held while the body was '
                'lost) and are left out as missing (not outliers)'
            )
        if rep.n_short:
            said.append(
                f'{rep.n_short} {rep.stream} poses ({rep.short_fraction:.1%}) lie in segments '
                f'between its {rep.breaks_ns.size} break(s) too short to use, and are left out '
                "(not outliers: the result's sigmas are those of the rest)"
            )
    checked = any(c.chosen for c in so_far.candidates)
    if ta.method != 'fixed' and ta.second_peak_ratio > AMBIGUOUS_PEAK_RATIO and not checked:
        said.append(
            Reason(
                Code.AMBIGUOUS_OFFSET,
                f'the correlation has a second peak at '
                f'{ta.second_peak_ratio:.0%} of the main one (repetitive motion) and no '
                'other candidate offset could be checked',
            )
        )
    if ta.method != 'fixed' and ta.peak_correlation < WEAK_CORRELATION:
        said.append(
            Reason(
                Code.WEAK_CORRELATION,
                f'the angular velocities of the two streams hardly agree '
                f'(correlation {ta.peak_correlation:.2f}): check that both show the same motion',
            )
        )
    return Findings.of(*said)


def assess_answer(
    lin: LinearSolution,
    batch: BatchSolution | None,
    metrics: Metrics,
    cfg: CalibrationConfig,
    so_far: Findings,
) -> Findings:
    """The reasons judged on the answer (after what the stages found, ``so_far``): few inliers,
    unobservable parts, weak excitation (stage 2's ``lin``), no or too large an uncertainty,
    residuals not white (stage 3's ``batch``), AX = XB failing at the result (``metrics``). The
    others are read from the stages' facts, their severities here: :data:`SEVERITY`."""
    said = _assess_linear(lin, batch)
    unobservable = Code.UNOBSERVABLE in reasons_in((*so_far.log, *said))
    said += _assess_uncertainty(batch, cfg, unobservable)
    reason = motion_inconsistency(metrics)
    return Findings.of(*said, *([] if reason is None else [reason]))


def _assess_linear(lin: LinearSolution, batch: BatchSolution | None) -> list[Reason | str]:
    """Stage 2's consensus and excitation. A lever arm along the only rotation axis that the
    batch stage held (``batch.held_axis``) changes no figure of an evaluation: the world
    alignment absorbs it, so only the extrinsic's verdict reads it."""
    said: list[Reason | str] = []
    if lin.n_inliers < LOW_INLIER_FRACTION * lin.n_motions:
        said.append(
            Reason(
                Code.FEW_INLIERS,
                f'only {lin.n_inliers} of {lin.n_motions} motions are RANSAC inliers',
            )
        )
    if lin.unobservable:
        held = batch is not None and batch.held_axis is not None
        if batch is not None and batch.held_axis is not None:
            a = batch.held_axis
            said.append(
                'held by the batch stage, as the motion cannot tell it: the translation of '
                f'T_HE along the only rotation axis [{a[0]:+.3f} {a[1]:+.3f} {a[2]:+.3f}] (hand '
                f'frame) at {float(batch.p_HE @ a):+.3f} m (held_lever_arm)'
                + (', and the rotation about it' if batch.held_rotation else '')
                + '; no APE/RPE figure depends on it (the world alignment absorbs it)'
            )
        said.append(
            Reason(
                Code.UNOBSERVABLE,
                'part of the extrinsic cannot be observed from this motion: '
                + '; '.join(lin.unobservable)
                + (
                    ' (held there by the batch stage; no APE/RPE figure depends on it)'
                    if held
                    else ''
                ),
                frozenset({Purpose.EXTRINSIC}) if held else BOTH,
            )
        )
    elif lin.axis_spread_deg < WEAK_EXCITATION_DEG:
        said.append(
            Reason(
                Code.WEAK_EXCITATION,
                f'the rotation axes spread only {lin.axis_spread_deg:.1f} '
                'deg: the extrinsic is weakly constrained; rotate about more different axes',
            )
        )
    return said


def sigmas_of(std: Floats) -> tuple[float, float, float]:
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
    precise enough for the extrinsic (:func:`judged_ratio` for either purpose)."""
    ratios = precision_ratios(sigmas, targets)
    return float('inf') if not all(np.isfinite(ratios)) else max(ratios)


#: What narrows a group's 1-sigma, by the term that dominates it (``Uncertainty.dominant``): the
#: words of ``imprecise``.
_MOTION = 'more varied rotation (faster, about all axes) or a longer recording narrows it'
_EYE_OVER_MINUTES = (
    "most of it is the eye's own error, alike over seconds to minutes: a longer recording "
    'narrows it at most as the square root of its length, and faster motion hardly at all'
)
_SCALE = (
    "most of it is not knowing the eye's scale, fitted beside T_HE: translations of the rig "
    'as long as its lever arm, with rotations about varied axes, narrow it'
)
NARROWS = {
    ('time_offset', 'white'): _MOTION,
    ('time_offset', 'correlated'): (
        'most of it is the offset wandering along the recording (a latency that changes) over '
        'parts that weigh unequally: motion as rich over the whole recording narrows it, a '
        'longer recording alone may not'
    ),
    ('time_offset', 'scale'): _SCALE,
    ('translation', 'white'): _MOTION,
    ('translation', 'correlated'): _EYE_OVER_MINUTES,
    ('translation', 'scale'): _SCALE,
    ('rotation', 'white'): _MOTION,
    ('rotation', 'correlated'): _EYE_OVER_MINUTES,
    ('rotation', 'scale'): _SCALE,
}


def _assess_uncertainty(
    batch: BatchSolution | None, cfg: CalibrationConfig, unobservable: bool
) -> list[Reason | str]:
    """Stage 3's uncertainty: none (said unless a part of the answer is ``unobservable``, which
    says why; switched off too: no precision is judged without sigmas), larger than required or
    near it, or shaped by something unmodelled (:func:`_unmodelled`)."""
    said: list[Reason | str] = []
    if batch is None and not unobservable:
        why = 'did not run (see the warnings)' if cfg.batch else 'was switched off (batch: false)'
        said.append(
            Reason(
                Code.NO_UNCERTAINTY,
                f'the batch stage {why}, so the result has no uncertainty and its precision '
                'cannot be judged',
            )
        )
    if batch is not None:
        sd, need = sigmas_of(batch.std), cfg.precision
        unc = batch.uncertainty
        dominant = unc.dominant() if unc is not None else {}
        over = [
            f'{label} {v:.3g} {unit} (required {n:.3g}): '
            + NARROWS[group, dominant.get(group, 'white')]
            for group, label, v, n, unit, r in _figures(sd, need)
            if r > 1.0
        ]
        if over:
            said.append(
                Reason(
                    Code.IMPRECISE,
                    'the 1-sigma uncertainty exceeds the required precision: '
                    + '; '.join(over)
                    + '. The precision_* options set what is required',
                    frozenset({Purpose.EXTRINSIC}),
                )
            )
        near = _near(sd, need)
        if near and not over and batch.blocks_measured:
            said.append(near)
    if batch is not None:
        said += _unmodelled(batch, cfg.knot_spacing)
    return said


def _unmodelled(batch: BatchSolution, asked_spacing: float) -> list[Reason | str]:
    """Stage 3's sigmas shaped by what its model lacks: residuals correlated far beyond white
    ones, or a MoCap whose spline is not exact against the eye (see the codes; below the
    line, a note when its spline was knotted wider than ``asked_spacing`` [s] for it)."""
    said: list[Reason | str] = []
    if float(np.max(batch.inflation)) > INFLATION_DOUBTFUL:
        said.append(
            Reason(
                Code.RESIDUALS_NOT_WHITE,
                f'the residuals are strongly correlated in time (the '
                f'long-run sigmas are up to {np.max(batch.inflation):.1f}x the white ones): '
                'something the model lacks (clock drift, a scale error) shapes them',
            )
        )
    move = batch.mocap_noise_move
    if move is None:
        return said
    h = batch.hand_noise
    noisy = (
        f'the MoCap is noisy for the eye it calibrates ({np.degrees(h.rotation):.2g} deg and '
        f'{h.translation * 1e3:.2g} mm a pose; its spline is knotted every '
        f'{batch.knot_spacing:.3g} s, the spacing that predicts the eye best): its noise drawn '
        f'once more moves the answer by {move:.1f} sigma'
    )
    if move <= NOISE_MOVE_DOUBTFUL:
        said += [noisy] if batch.knot_spacing > asked_spacing else []
        return said
    said.append(
        Reason(
            Code.NOISY_MOCAP,
            f'{noisy}, about the bias it has put in it already (the spline holds that noise '
            'as exact, which draws the lever arm toward zero). A MoCap body with more markers '
            'spread wider, or a faster MoCap, narrows it',
        )
    )
    return said


def _figures(
    sd: tuple[float, float, float], need: tuple[float, float, float]
) -> list[tuple[str, str, float, float, str, float]]:
    """Per group: its name and label, its 1-sigma (:func:`sigmas_of`) and target in the unit
    said (ms, mm, deg), that unit, and their ratio."""
    return [
        (group, group.replace('_', ' '), v * k, n * k, unit, r)
        for group, v, n, k, unit, r in zip(
            ('time_offset', 'translation', 'rotation'),
            sd,
            need,
            (1e3, 1e3, 1.0),
            ('ms', 'mm', 'deg'),
            precision_ratios(sd, need),
            strict=True,
        )
    ]


def _near(sd: tuple[float, float, float], need: tuple[float, float, float]) -> str:
    """A note of the 1-sigmas ``sd`` (:func:`sigmas_of`) beyond BLOCKS_MARGIN of their targets
    ``need`` and within them, '' when none is: near a target, a 1-sigma that the blocks measure
    may be found above it by a calibration of more data."""
    near = [
        f'{label} {v:.3g} {unit} against {n:.3g}'
        for _, label, v, n, unit, r in _figures(sd, need)
        if BLOCKS_MARGIN < r <= 1.0
    ]
    if not near:
        return ''
    return (
        'near the required precision: '
        + '; '.join(near)
        + f' required (beyond {BLOCKS_MARGIN:.0%} of it). A 1-sigma measured on four blocks is '
        'itself uncertain by about a quarter: a calibration of more of this recording may find '
        'it above'
    )


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


def assess_model(model: EyeModel, clock: DriftFit | None, cfg: CalibrationConfig) -> Findings:
    """Reasons about the clock drift and the scale, when they were estimated."""
    said: list[Reason | str] = []
    if cfg.estimate_scale:
        std = model.scale_std
        if not model.scale_observable:
            sd = f' +- {std:.2g}' if np.isfinite(std) else ''
            said.append(
                Reason(
                    Code.UNOBSERVABLE,
                    f"the eye's scale cannot be observed (s = "
                    f'{model.scale:.4g}{sd}): the hand translates too little for its '
                    'translations to be told from a lever arm, so the translation of T_HE '
                    'is as uncertain. Move the rig through space, not only about itself',
                )
            )
    if cfg.clock_drift and model.drift_estimated and clock is not None:
        half = 0.5 * clock.span_s * model.drift_std
        if half > cfg.precision_time_offset:
            said.append(
                Reason(
                    Code.IMPRECISE,
                    f'the clock drift is {model.drift * 1e6:+.1f} +- '
                    f'{model.drift_std * 1e6:.1f} ppm: at the ends of the recording the '
                    f'offset is uncertain by {half * 1e3:.2g} ms from the drift alone '
                    f'(required {cfg.precision_time_offset * 1e3:.3g} ms)',
                    frozenset({Purpose.EXTRINSIC}),
                )
            )
    return Findings.of(*said)


def reasons_in(log: tuple[Entry, ...]) -> set[Code]:
    """The codes of the reasons the entries of a log (notes, facts, reasons) make."""
    return {r.code for r in (read(e)[0] for e in log if not isinstance(e, str)) if r}


#: An evaluation's figure: its label, its value and its calibration 1-sigma in the unit said
#: ('mm' or 'deg'; the value NaN, or the 1-sigma None, when it has none), and the group of
#: parameters that moves it most (a key of THROUGH; '' when none can be named).
Figure = tuple[str, float, float | None, str, str]

#: The groups of parameters that move a figure, as ``imprecise`` names them.
THROUGH = {
    'time_offset': 'the time offset',
    'translation': "T_HE's translation",
    'rotation': "T_HE's rotation",
    'clock_drift': 'the clock drift',
    'scale': "the eye's scale",
}


def _narrows(group: str, dominant: Mapping[str, str], one_axis: bool) -> str:
    """What narrows a group's 1-sigma: by the term that dominates it (``dominant``:
    ``Uncertainty.dominant``) for dt and T_HE, as for the extrinsic's ``imprecise``; a motion
    about ``one_axis`` (a ground robot, a turntable) is not told to turn about the others."""
    if group == 'clock_drift':
        return 'a longer recording narrows it'
    if group == 'scale':
        return _SCALE
    term = dominant.get(group, 'white')
    if one_axis and term == 'white':
        return 'more turning or a longer recording narrows it'
    return NARROWS[group, term]


def judged_ratio(
    quality: Quality, sigmas: tuple[float, float, float] | None, precision: tuple[float, ...]
) -> float:
    """How far the judged purpose's rule on precision is from its line: the largest ratio of a
    1-sigma to what the rule allows (above 1 ``imprecise``). Purpose evaluation: its figures'
    (``Quality.share_ratio``) once judged; purpose extrinsic, and the evaluation's stand-in
    until then: dt's and T_HE's 1-sigmas (``sigmas``, :func:`sigmas_of`; None: inf) against
    ``precision`` (``CalibrationConfig.precision``)."""
    if quality.purpose == Purpose.EVALUATION and quality.evaluated:
        return quality.share_ratio
    return math.inf if sigmas is None else precision_ratio(sigmas, precision)


def settled(good: bool, ratio: float, complete: bool) -> bool:
    """A ``good`` result whose rule on precision is at ``ratio`` (:func:`judged_ratio`) within
    BLOCKS_MARGIN of its line, with 1-sigmas that hold the errors correlated over the recording
    (``complete``: the blocks' term of :mod:`~handeye_ros.core.batch.correlated` measured): a
    calibration of a little more of the recording stays on this side of the line, where near it
    the 1-sigma's own uncertainty (about a quarter, measured on four blocks) may put the next
    one beyond, and without the blocks the next one may add their term, which widens the
    1-sigmas of a VIO whose errors persist over parts of the recording. No ratio (no figure to
    judge) sets no margin."""
    return good and complete and not ratio > BLOCKS_MARGIN


def assess_evaluation(
    figures: list[Figure],
    why_none: str,
    dominant: Mapping[str, str] | None = None,
    one_axis: bool = False,
) -> tuple[list[Reason], list[str], float]:
    """Purpose evaluation's rule on the evaluation's own figures (:data:`Figure`): each is
    settled when its calibration 1-sigma is at most EVALUATION_SHARE of it, and noted when
    beyond BLOCKS_MARGIN of that. A figure with no value (an RPE step longer than the
    recording) is noted and left out; no 1-sigmas at all (``why_none``) is
    ``no_uncertainty``. A figure beyond or near the line names the group of parameters that
    moves it most and what narrows that (``dominant``: the batch stage's ``Uncertainty.dominant``;
    ``one_axis``: the motion turned about one axis only, its lever arm along it held).
    Returns (reasons, notes, the largest of the judged figures' 1-sigmas over
    EVALUATION_SHARE of the figure: ``Quality.share_ratio``, NaN without one)."""
    only = frozenset({Purpose.EVALUATION})
    if why_none:
        text = f'the APE/RPE figures have no error bars from the calibration: {why_none}'
        return [Reason(Code.NO_UNCERTAINTY, text, only)], [], math.nan
    over: list[str] = []
    near: list[str] = []
    notes, ratios = [], []
    for label, value, sigma, unit, through in figures:
        if not np.isfinite(value) or sigma is None or value <= 0.0:
            why = (
                ' (no two eye poses lie that step apart: a step longer than the recording, or '
                'shorter than its pose spacing)'
                if label.startswith('RPE') and not np.isfinite(value)
                else ''
            )
            notes.append(f'{label} could not be computed and is not judged{why}')
            continue
        ratios.append(sigma / (EVALUATION_SHARE * value))
        if not sigma > BLOCKS_MARGIN * EVALUATION_SHARE * value:
            continue
        said = f'{label} {value:.3g} (+-{sigma:.2g}) {unit}: {sigma / value:.1%}'
        if through:
            narrows = _narrows(through, dominant or {}, one_axis)
            said += f', moved most by {THROUGH[through]}: {narrows}'
        (over if sigma > EVALUATION_SHARE * value else near).append(said)
    if near and not over:
        notes.append(
            f'near the {EVALUATION_SHARE:.0%} line (beyond {BLOCKS_MARGIN:.0%} of it): '
            + '; '.join(near)
            + '. A 1-sigma measured on four blocks is itself uncertain by about a quarter: a '
            'calibration of more of this recording may find it above'
        )
    ratio = max(ratios) if ratios else math.nan
    if not over:
        return [], notes, ratio
    text = (
        "the calibration's 1-sigma exceeds "
        f'{EVALUATION_SHARE:.0%} of the figures it would change: '
        + '; '.join(over)
        + ' (with purpose extrinsic its own targets judge it instead)'
    )
    return [Reason(Code.IMPRECISE, text, only)], notes, ratio


def judged(found: Findings, purpose: Purpose = Purpose.EVALUATION) -> Quality:
    """The verdict of a finished run for ``purpose``: every fact read into its reason or
    note, in the order found, beside the notes the stages wrote."""
    reasons, notes = [], []
    for entry in found.log:
        reason, note = (None, entry) if isinstance(entry, str) else read(entry)
        if reason is not None:
            reasons.append(reason)
        if note is not None:
            notes.append(note)
    return Quality.from_reasons(reasons, notes, purpose)
