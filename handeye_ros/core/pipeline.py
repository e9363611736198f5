"""The whole calibration: the one function every front end (offline tool, node) calls.

The paper's three stages, wrapped in the checks real recordings need (each step names what it
guards against):

1. **Input conventions**: explicit inversions (``invert_hand`` / ``invert_eye``); stamp units
   read against the streams' rates (:func:`.checks.conventions.check_stamp_units`); clock epochs named.
2. **Screening** of each stream (:func:`.checks.screening.screen`): placeholders, marker swaps, glitches
   removed and counted; a stream that would lose more than ``max_outlier_fraction`` is refused.
3. **Stage 1** (Section III-A): angular-speed correlation over every lag the recordings allow
   (or a window), quadratic peak.
4. **Orientation conventions** at that offset (:func:`.checks.conventions.check_orientations`): the
   correlation of stage 1 is blind to a swapped quaternion order or inverted poses; AX = XB
   is not.
5. The eye's stamps are moved by stage 1's offset (in integer nanoseconds), so that every later
   offset is a small correction in float seconds whatever the two clocks' epochs.
6. **Stage 2** (Section III-B); then the eye's breaks (VIO resets) and leftover wild poses found
   against the hand (:func:`.checks.screening.find_eye_breaks`), and stage 2 again without them.
7. **Vector refinement** of the offset from the body angular velocities with stage 2's rotation
   (:func:`.time.align.align_time_vector`), iterated with stage 2.
8. **Self-check** (:mod:`.checks.selfcheck`) when the candidate offsets (the correlation peak, its
   runner-ups, the vector refinement) differ: stage 2 at each, scored on one set of motions.
9. **Stage 3** (Section III-C) from the winner, with a covariance that holds for residuals
   correlated in time (:mod:`.batch.long_run`). When it moves the offset or the extrinsic beyond
   its own sigmas, the self-check decides between it and the linear result (instead of a cap on
   how far it may move, which threw away refinements that were right).
10. World alignment (per eye segment) and metrics at the final (dt, T_HE), and the verdict
    (:mod:`.checks.verdict`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from .association import PosePairs, associate
from .batch.refine import BatchSolution, refine
from .checks.conventions import (
    Correction,
    check_orientations,
    check_stamp_units,
    epoch_note,
    reread,
)
from .checks.coverage import mocap_coverage
from .checks.screening import Screening, damaged, describe_damage, find_eye_breaks, screen
from .checks.selfcheck import Candidate, motion_consistency, score_candidates
from .checks.verdict import (
    AMBIGUOUS_PEAK_RATIO,
    AMBIGUOUS_SCORE_RATIO,
    FAILED_MOTION_ROTATION_DEG,
    FAILED_MOTION_TRANSLATION_FRACTION,
    FAILED_MOTION_TRANSLATION_M,
    INFLATION_DOUBTFUL,
    LOW_INLIER_FRACTION,
    OUTLIER_FRACTION_DOUBTFUL,
    WEAK_CORRELATION,
    WEAK_EXCITATION_DEG,
    Code,
    Quality,
    Reason,
)
from .config import CalibrationConfig
from .errors import (
    ConfigError,
    DegenerateMotionError,
    HandeyeError,
    InputError,
    TimeAlignmentError,
)
from .eye_model import EyeModel
from .geometry import matrix_from_quat, quat_angle
from .linear.axxb import build_motions
from .linear.refits import drift_weights
from .linear.robust import LinearSolution, calibrate_linear
from .linear.scale import ScaleFit, observable, scale_prior, translation_and_scale
from .result import CalibrationResult, UsedStreams
from .time.align import TimeAlignment, align_time, align_time_vector
from .time.clock import DriftFit, covered_span, measure_drift
from .time.keyframes import align_time_keyframes
from .trajectory import Trajectory, is_keyframe_only
from .world import Metrics, align_worlds, evaluate

LOG = logging.getLogger(__name__)

#: A search window given by its guess alone is this wide on each side (s).
DEFAULT_HALF_WINDOW_S = 0.5
#: Two candidate offsets closer than this (s), or than DISTINCT_STEPS grid steps of stage 1,
#: are one: the batch stage refines within that, and the self-check cannot separate offsets a
#: few milliseconds apart on a slow motion anyway.
SAME_OFFSET_S = 2e-3
DISTINCT_STEPS = 3
#: Stage 2 is run again when the vector refinement moved dt by more than this (s).
LINEAR_REDO_S = 5e-3
#: The vector refinement searches this far (s) on each side of the current offset.
VECTOR_HALF_WINDOW_S = 0.15
MAX_VECTOR_ITERATIONS = 3
#: The batch stage disagrees with the linear result when it moves dt by more than this many
#: of its sigmas and at least BATCH_DT_MIN_S, or T_HE by more than 3 sigmas and at least these.
BATCH_SIGMAS = 3.0
BATCH_DT_MIN_S = 2e-3
BATCH_TRANSLATION_MIN_M = 0.02
BATCH_ROTATION_MIN_DEG = 1.0
#: The batch stage's extrinsic is rejected when the self-check scores it this much worse.
BATCH_SCORE_FACTOR = 1.5
#: The linear stage with the next RANSAC seed must land within these (deg, m).
SEED_ROTATION_DEG = 0.5
SEED_TRANSLATION_M = 0.01
#: A fixed offset further than this from the correlation peak is reported (s): a few grid
#: steps, well above the peak's own error (< 2 ms on the paper's protocol).
FIXED_OFFSET_DISAGREEMENT_S = 0.01


@dataclass
class _Run:
    """What the pipeline learns on the way, for the result and the verdict."""

    warnings: list[str] = field(default_factory=list)
    reasons: list[Reason] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    corrections: list[Correction] = field(default_factory=list)
    candidates: list[Candidate] = field(default_factory=list)

    def reason(self, code: Code, message: str) -> None:
        """A reason for the verdict (its severity is the code's: :data:`.checks.verdict.SEVERITY`)."""
        self.reasons.append(Reason(code, message))


#: The steps :func:`calibrate` reports to its ``progress`` callback, in order.
STEPS = (
    'screening',
    'stage 1: time alignment',
    'stage 2: linear calibration',
    'stage 3: batch',
    'world alignment and metrics',
)


def calibrate(
    hand: Trajectory,
    eye: Trajectory,
    config: CalibrationConfig | None = None,
    progress: Callable[[str], None] | None = None,
) -> CalibrationResult:
    """Time offset and extrinsic T_HE of a hand (T_GH) and an eye (T_WE) trajectory.

    ``progress``: called with each name of :data:`STEPS` as that step starts (a front end's
    progress bar; the core draws nothing itself).

    Raises a :class:`~handeye_ros.core.errors.HandeyeError` subclass with a user-facing message
    when the input cannot give a result; everything else ends in ``result.quality`` (the
    verdict and its reasons) and ``result.warnings``.
    """
    cfg = config or CalibrationConfig()
    if cfg.clock_drift and cfg.time_offset is not None:
        raise ConfigError(
            'time_offset fixes one constant offset and clock_drift estimates one '
            'that changes along the recording: give one of them'
        )
    run = _Run()
    step = progress or (lambda name: None)
    step(STEPS[0])
    t0 = time.perf_counter()
    hand_in, eye_in = hand, eye
    run.warnings += [*hand.notes, *eye.notes]
    hand, eye = _prepare(hand, eye, cfg, run)
    hand, eye, screening = _screen(hand, eye, cfg, run)
    eta = np.deg2rad(cfg.eta)
    step(STEPS[1])

    # stage 1 (or the fixed offset), then the orientation conventions at that offset
    fixed = cfg.time_offset is not None
    if fixed:
        ta = TimeAlignment(
            time_offset_s=cfg.time_offset,
            method='fixed',
            time_offset_ns=round(cfg.time_offset * 1e9),
        )
        run.warnings += _check_fixed_offset(hand, eye, cfg)
    elif eye.keyframes:
        guess, half = _window(cfg)
        ta = align_time_keyframes(hand, eye, max_time_offset=half, time_offset_guess=guess)
    else:
        guess, half = _window(cfg)
        ta = align_time(
            hand,
            eye,
            max_time_offset=half,
            time_offset_guess=guess,
            resample_rate_hz=cfg.resample_rate_hz,
            peak_fit=cfg.peak_fit,
        )
    if cfg.check_conventions:
        hand, eye, found = check_orientations(hand, eye, ta.time_offset_s, eta)
        _corrected(found, run)
    t1 = time.perf_counter()
    step(STEPS[2])

    # from here on the eye is on the hand's clock (up to stage 1's error): offsets are small
    shift_ns = ta.time_offset_ns
    eye_c = eye.shifted(-shift_ns)
    model = EyeModel(shift_ns, stamp_ns=covered_span(hand, eye_c)[2])
    dt = 0.0
    if cfg.clock_drift and not eye.keyframes:
        eye_c, model = _drift_from_windows(hand, eye_c, model, cfg)
    if cfg.estimate_scale:
        eye_c, model = _scale_from_rotations(hand, eye_c, model, cfg)
    try:
        lin, pairs = _linear(hand, eye_c, dt, cfg)
    except DegenerateMotionError as err:
        if fixed or (cfg.max_time_offset is None and cfg.time_offset_guess is None):
            raise
        lo, hi = ta.window_s
        msg = (
            f'{err}. The time offset was searched in [{lo:+.3f}, {hi:+.3f}] s only: if it '
            'lies outside, the correlation found a false peak there; widen max_time_offset '
            'or move time_offset_guess (or leave both unset to search every lag)'
        )
        raise DegenerateMotionError(msg) from None
    scaled = None if cfg.estimate_scale else _scale_check(pairs, lin, cfg)
    if scaled is not None and scaled.costs(cfg.precision_translation):
        # the eye's motion disagrees with the hand's everywhere by the same factor: splitting
        # it at "breaks" would only hide that
        run.reason(Code.SCALE, _scale_message(scaled))
    else:
        if scaled is not None and scaled.clear:  # named, but it costs less than the precision
            run.notes.append(_scale_message(scaled))
        if cfg.screening:
            eye_c, lin, pairs, screening = _split_eye(
                hand, eye_c, lin, pairs, cfg, screening, shift_ns, run
            )
    tv = None
    clock = None
    if not fixed:
        dt, lin, pairs, tv = _refine_vector(hand, eye_c, dt, lin, pairs, cfg, run)
        dt, lin, pairs = _self_check(hand, eye_c, ta, shift_ns, dt, lin, pairs, cfg, run)
        # the offset along the recording, with stage 2's rotation
        eye_c, model, clock, moved = _clock_along(hand, eye_c, model, dt, lin, cfg, run)
        if moved is not None:
            dt = moved
            lin, pairs = _linear(hand, eye_c, dt, cfg)
    if cfg.estimate_scale:
        eye_c, model = _fold_linear_scale(eye_c, model, lin, run)
    t2 = time.perf_counter()
    step(STEPS[3])

    q_HE, p_HE = lin.q_HE, lin.p_HE
    batch = None
    if cfg.batch and lin.unobservable:
        run.warnings.append('batch stage not used: part of the extrinsic is unobservable')
    elif cfg.batch:
        batch, why = _run_batch(hand, eye_c, dt, q_HE, p_HE, cfg, model)
        if batch is not None:
            batch = _check_batch(hand, eye_c, dt, lin, batch, cfg, run)
        if batch is not None:
            dt, q_HE, p_HE = batch.time_offset_s, batch.q_HE, batch.p_HE
            run.warnings.extend(batch.warnings)
            eye_c, model = _fold_batch(eye_c, model, batch)
        else:
            why = why or 'the self-check sided with the linear result'
            run.warnings.append(f'batch stage not used, the linear result is kept: {why}')
    t3 = time.perf_counter()
    step(STEPS[4])

    pairs = associate(hand, eye_c, dt)
    world = align_worlds(pairs, q_HE, p_HE)
    if world.method != 'positions':
        run.warnings.append(
            'the positions do not span a plane; the world alignment T_WG was '
            'taken from the orientations'
        )
    metrics = evaluate(pairs, q_HE, p_HE, world)
    m_rot, m_trans, m_len, n_mot = motion_consistency(hand, eye_c, dt, q_HE, p_HE, eta)
    metrics = replace(
        metrics,
        motion_rotation_deg=m_rot,
        motion_translation_m=m_trans,
        motion_length_m=m_len,
        n_motions=n_mot,
    )
    seed_lin = _seed_check(hand, eye_c, dt, lin, batch, cfg, run, pairs)
    _assess(ta, tv, lin, batch, screening, metrics, cfg, run)
    _assess_model(model, clock, cfg, run)
    LOG.info(
        'stage 1 + conventions %.3f s, stage 2 + checks %.3f s, batch %.3f s, %d pairs, '
        '%d motions',
        t1 - t0,
        t2 - t1,
        t3 - t2,
        pairs.t_eye_s.size,
        lin.n_motions,
    )
    covered = mocap_coverage(hand, eye_c, dt)
    if covered.note():
        run.notes.append(covered.note())
    quality = Quality.from_reasons(run.reasons, run.notes)
    return CalibrationResult(
        time_offset_s=cfg.time_offset if fixed else shift_ns * 1e-9 + dt,
        q_HE=q_HE,
        p_HE=p_HE,
        world=world,
        time_alignment=ta,
        linear=lin,
        metrics=metrics,
        n_pairs=int(pairs.t_eye_s.size),
        hand=hand_in.info(),
        eye=eye_in.info(),
        config=cfg,
        warnings=tuple(run.warnings),
        batch=batch,
        time_offset_ns=shift_ns + round(dt * 1e9),
        vector_alignment=_absolute(tv, shift_ns),
        screening=screening,
        corrections=tuple(run.corrections),
        candidates=tuple(
            replace(c, time_offset_s=shift_ns * 1e-9 + c.time_offset_s) for c in run.candidates
        ),
        quality=quality,
        seed_check=seed_lin,
        eye_model=model,
        clock=clock,
        used=UsedStreams(hand, eye_c, model.own_clock_ns(eye_c.t_ns, eye.t_ns), dt),
        coverage=covered,
    )


# ----------------------------------------------------------------------------- inputs


def _prepare(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig, run: _Run
) -> tuple[Trajectory, Trajectory]:
    """Explicit inversions, stamp units, epochs."""
    if cfg.invert_hand:
        hand = reread(hand, 'inverse')
    if cfg.invert_eye:
        eye = reread(eye, 'inverse')
    if cfg.check_conventions:
        hand, eye, found = check_stamp_units(hand, eye)
        _corrected(found, run)
    note = epoch_note(hand, eye)
    if note:
        run.warnings.append(note)
        run.notes.append(note)
    if is_keyframe_only(eye):
        eye = replace(eye, keyframes=True)
        step = np.diff(eye.t_ns) * 1e-9
        note = (
            f'{eye.name} holds keyframes only ({len(eye)} poses, {np.median(step):.2f} s apart '
            f'at the median, up to {step.max():.2f} s): the time offset comes from the '
            'rotation angles over keyframe pairs (screw congruence), not from the angular-speed '
            'correlation; no vector refinement and no drift windows'
        )
        run.warnings.append(note)
        run.notes.append(note)
    return hand, eye


def _corrected(found: list[Correction], run: _Run) -> None:
    for c in found:
        run.corrections.append(c)
        run.warnings.append(c.message)
        run.reason(Code.CONVENTION_CORRECTED, c.message)


def _screen(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig, run: _Run
) -> tuple[Trajectory, Trajectory, tuple[Screening, Screening]]:
    """Both streams screened (see :mod:`.checks.screening`); refuse a stream that would lose too much."""
    if not cfg.screening:
        return (
            hand,
            eye,
            (
                Screening('hand', len(hand), np.zeros(0, np.int64), ()),
                Screening('eye', len(eye), np.zeros(0, np.int64), ()),
            ),
        )
    out, reports = [], []
    for traj, stream in ((hand, 'hand'), (eye, 'eye')):
        kept, rep = screen(traj, stream, cfg.outlier_threshold)
        wrecked = damaged(traj)
        damage = describe_damage(traj, wrecked) if wrecked.any() else ''
        _check_fraction(rep, traj, cfg, damage)
        if damage:
            run.warnings.append(f'{damage}; those rows were left out')
        out.append(kept)
        reports.append(rep)
    return out[0], out[1], (reports[0], reports[1])


def _check_fraction(
    rep: Screening, traj: Trajectory, cfg: CalibrationConfig, damage: str = ''
) -> None:
    """Refuse a stream screening would take too much of; damaged rows are named first."""
    if rep.fraction > cfg.max_outlier_fraction:
        counts = ', '.join(f'{v} {k.replace("_", " ")}' for k, v in rep.counts.items() if v)
        msg = (
            (
                f'{damage}. Without them too little of the stream is left: screening would remove '
                f'{rep.fraction:.1%} of it ({counts}), more than max_outlier_fraction '
                f'{cfg.max_outlier_fraction:.0%}. Repair or re-export the file'
            )
            if damage
            else (
                f'{traj.name}: screening would remove {rep.fraction:.1%} of the {rep.stream} '
                f'stream ({counts}), more than max_outlier_fraction '
                f'{cfg.max_outlier_fraction:.0%}: the stream is not what the tool expects '
                f'(check that it holds the {"MoCap" if rep.stream == "hand" else "VIO"} poses '
                'of this recording), or raise max_outlier_fraction / outlier_threshold'
            )
        )
        raise InputError(msg)


def _window(cfg: CalibrationConfig) -> tuple[float | None, float | None]:
    """(guess, half-width) of stage 1's search; (None, None) searches every lag."""
    if cfg.max_time_offset is None and cfg.time_offset_guess is None:
        return None, None
    return (
        cfg.time_offset_guess or 0.0,
        cfg.max_time_offset if cfg.max_time_offset is not None else DEFAULT_HALF_WINDOW_S,
    )


# ----------------------------------------------------------------------------- stage 2 and checks


def _linear(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    cfg: CalibrationConfig,
    seed: int | None = None,
    pairs: PosePairs | None = None,
) -> tuple[LinearSolution, PosePairs]:
    """Stage 2 at offset dt (``pairs``: the streams associated at dt, when already made)."""
    pairs = associate(hand, eye, dt) if pairs is None else pairs
    motions = build_motions(pairs, cfg.relative_poses, np.deg2rad(cfg.eta))
    lin = calibrate_linear(
        motions,
        robust_kernel=cfg.robust_kernel,
        mu=cfg.mu,
        ransac_iterations=cfg.ransac_iterations,
        inlier_rotation_rad=np.deg2rad(cfg.inlier_rotation),
        inlier_translation_m=cfg.inlier_translation,
        min_motions=cfg.min_motions,
        adaptive_inliers=cfg.adaptive_inliers,
        decoupled_refit=cfg.decoupled_refit,
        estimate_scale=cfg.estimate_scale,
        rng=np.random.default_rng(cfg.seed if seed is None else seed),
    )
    return lin, pairs


def _split_eye(
    hand: Trajectory,
    eye: Trajectory,
    lin: LinearSolution,
    pairs: PosePairs,
    cfg: CalibrationConfig,
    screening: tuple[Screening, Screening],
    shift_ns: int,
    run: _Run,
):
    """Breaks (VIO resets) and leftover wild poses of the eye, against the hand; stage 2 again
    when any were found."""
    found = find_eye_breaks(hand, eye, 0.0, matrix_from_quat(lin.q_HE), lin.p_HE)
    if not (found.breaks_ns.size or found.outliers_ns.size or found.short_ns.size):
        return eye, lin, pairs, screening
    sh, se = screening
    # the report keeps the eye's own stamps; this eye was moved by shift_ns
    se = se.merged(found.outliers_ns + shift_ns, 'outlier').merged(
        found.short_ns + shift_ns, 'short_segment', found.breaks_ns + shift_ns
    )
    _check_fraction(se, eye, cfg)
    if found.breaks_ns.size:
        note = (
            f'the eye stream was split at {found.breaks_ns.size} break(s) (a VIO reset or '
            "jump of its world frame: its motion there disagrees with the hand's); no "
            'motion or residual spans one'
        )
        run.warnings.append(note)
        run.notes.append(note)
    lin, pairs = _linear(hand, found.eye, 0.0, cfg)
    return found.eye, lin, pairs, (sh, se)


def _refine_vector(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    lin: LinearSolution,
    pairs: PosePairs,
    cfg: CalibrationConfig,
    run: _Run,
):
    """dt from the body angular velocities with stage 2's rotation, iterated with stage 2."""
    if not cfg.vector_refinement or lin.unobservable or eye.keyframes:
        return dt, lin, pairs, None
    tv = None
    for _ in range(MAX_VECTOR_ITERATIONS):
        try:
            tv = align_time_vector(
                hand,
                eye,
                matrix_from_quat(lin.q_HE),
                around_s=dt,
                half_window_s=VECTOR_HALF_WINDOW_S,
                resample_rate_hz=cfg.resample_rate_hz,
            )
        except TimeAlignmentError as err:
            run.warnings.append(f'vector refinement of the time offset not used: {err}')
            return dt, lin, pairs, tv
        moved = tv.time_offset_s - dt
        dt = tv.time_offset_s
        if abs(moved) <= LINEAR_REDO_S:
            break
        lin, pairs = _linear(hand, eye, dt, cfg)
    return dt, lin, pairs, tv


def _self_check(
    hand: Trajectory,
    eye: Trajectory,
    ta: TimeAlignment,
    shift_ns: int,
    dt: float,
    lin: LinearSolution,
    pairs: PosePairs,
    cfg: CalibrationConfig,
    run: _Run,
):
    """Stage 2 at every distinct candidate offset, scored alike; the best one wins."""
    same = max(SAME_OFFSET_S, DISTINCT_STEPS * ta.step_s)
    hyps = [(dt, 'vector refinement' if dt != 0.0 else 'correlation peak', lin, pairs)]
    proposals = [(0.0, 'correlation peak')] + [
        (c - shift_ns * 1e-9, f'correlation runner-up ({r:.2f})') for c, r in ta.candidates
    ]
    for offset, source in proposals:
        if any(abs(offset - h[0]) < same for h in hyps):
            continue
        try:
            lin_c, pairs_c = _linear(hand, eye, offset, cfg)
            if offset != 0.0 and cfg.vector_refinement and not lin_c.unobservable:
                offset, lin_c, pairs_c, _ = _refine_vector(
                    hand, eye, offset, lin_c, pairs_c, cfg, _Run()
                )
        except HandeyeError as err:
            run.notes.append(
                f'candidate offset {(shift_ns * 1e-9 + offset):+.4f} s ({source}) rejected: {err}'
            )
            # counted in the result with the others, unscored
            run.candidates.append(
                Candidate(
                    offset,
                    f'{source}: rejected, stage 2 fails there',
                    float('nan'),
                    float('nan'),
                    float('nan'),
                    lin.q_HE,
                    lin.p_HE,
                )
            )
            continue
        if not any(abs(offset - h[0]) < same for h in hyps):
            hyps.append((offset, source, lin_c, pairs_c))
    if len(hyps) == 1:
        return dt, lin, pairs
    scored = score_candidates(
        hand, eye, [(h[0], h[1], h[2].q_HE, h[2].p_HE) for h in hyps], np.deg2rad(cfg.eta)
    )
    best = _judge_tie(scored, shift_ns, run)
    run.candidates.extend(replace(c, chosen=k == best) for k, c in enumerate(scored))
    return hyps[best][0], hyps[best][2], hyps[best][3]


def _judge_tie(scored: list[Candidate], shift_ns: int, run: _Run) -> int:
    """Index of the winner. Candidates scoring within AMBIGUOUS_SCORE_RATIO of the best are a
    tie (the verdict says so); a tie goes to the smallest offset, the likelier one when two
    clocks were started together."""
    best = next(k for k, c in enumerate(scored) if c.chosen)
    win = scored[best]
    if not np.isfinite(win.score):
        run.reason(
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
    run.reason(
        Code.AMBIGUOUS_OFFSET,
        f'the motion repeats itself: the self-check cannot separate '
        f'the candidate offsets {text}; the smallest of the tied ones was taken. Narrow '
        'the search with time_offset_guess and max_time_offset (less than half the '
        'period of the motion), or record a less repetitive motion',
    )
    return best


def _seed_check(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    lin: LinearSolution,
    batch: BatchSolution | None,
    cfg: CalibrationConfig,
    run: _Run,
    pairs: PosePairs | None = None,
) -> LinearSolution | None:
    """Stage 2 again with the next RANSAC seed: the answer must not hinge on it beyond its own
    uncertainty (3 sigmas of the batch stage, and at least SEED_ROTATION_DEG /
    SEED_TRANSLATION_M). ``pairs``: the streams associated at dt, when already made."""
    if cfg.ransac_iterations == 0:
        return None
    try:
        other, _ = _linear(hand, eye, dt, cfg, seed=(cfg.seed + 1) % 2**31, pairs=pairs)
    except HandeyeError as err:
        run.reason(
            Code.SEED_DEPENDENT, f'with RANSAC seed {cfg.seed + 1} the linear stage fails ({err})'
        )
        return None
    d_rot = float(np.degrees(quat_angle(other.q_HE, lin.q_HE)))
    d_t = float(np.linalg.norm(other.p_HE - lin.p_HE))
    lim_rot, lim_t = SEED_ROTATION_DEG, SEED_TRANSLATION_M
    if batch is not None:
        lim_t = max(lim_t, 3.0 * float(np.linalg.norm(batch.std[1:4])))
        lim_rot = max(lim_rot, 3.0 * float(np.degrees(np.linalg.norm(batch.std[4:7]))))
    if d_rot > lim_rot or d_t > lim_t:
        run.reason(
            Code.SEED_DEPENDENT,
            f'with RANSAC seed {cfg.seed + 1} the linear stage gives '
            f'an extrinsic {d_t * 1e3:.0f} mm / {d_rot:.2f} deg away: the motions do not '
            'single out one answer',
        )
    return other


# ----------------------------------------------------------------------------- clock and scale


def _drift_from_windows(
    hand: Trajectory, eye: Trajectory, model: EyeModel, cfg: CalibrationConfig
) -> tuple[Trajectory, EyeModel]:
    """With clock_drift, before stage 2: the drift from stage 1 in windows (magnitudes: no
    rotation of T_HE yet), taken out of the eye's stamps so that stage 2 sees one offset.
    When it cannot be measured here, :func:`_clock_along` says so."""
    fit = measure_drift(hand, eye, None, cfg.resample_rate_hz)
    if not fit.estimated:
        return eye, model
    return model.add_drift(eye, fit.drift, fit.drift_std)


def _clock_along(
    hand: Trajectory,
    eye: Trajectory,
    model: EyeModel,
    dt: float,
    lin: LinearSolution,
    cfg: CalibrationConfig,
    run: _Run,
):
    """The offset measured in windows along the recording with stage 2's rotation (the vector
    form of stage 1): named when it drifts (default run), taken out of the eye's stamps with
    clock_drift. Returns (eye, model, the fit on the eye's own clock, the offset at the
    reference stamp when the stamps moved, else None)."""
    if eye.keyframes:  # the windows correlate angular velocities, which keyframes do not give
        if cfg.clock_drift:
            run.reason(
                Code.UNOBSERVABLE,
                'the clock drift is measured in windows of angular velocity, which a '
                'keyframe-only eye does not give; one constant offset was estimated instead',
            )
        return eye, model, None, None
    R_HE = None if lin.unobservable else matrix_from_quat(lin.q_HE)
    fit = measure_drift(hand, eye, R_HE, cfg.resample_rate_hz, around_s=dt)
    clock = _absolute_clock(fit, model)
    if not cfg.clock_drift:
        if fit.significant:
            run.reason(Code.CLOCK_DRIFT, _drift_message(fit))
        elif fit.estimated:
            run.notes.append(
                f'the offset measured in {int(fit.inliers.sum())} windows along '
                f'the recording is constant within its uncertainty (drift '
                f'{fit.drift * 1e6:+.1f} +- {fit.drift_std * 1e6:.1f} ppm)'
            )
        return eye, model, clock, None
    if not fit.estimated:
        if model.drift_estimated:
            run.warnings.append(
                'the clock drift comes from the angular-speed magnitudes only: ' + fit.why
            )
        else:
            run.reason(
                Code.UNOBSERVABLE,
                f'the clock drift cannot be observed: {fit.why}. One '
                'constant offset was estimated instead',
            )
        return eye, model, clock, None
    eye, model = model.add_drift(eye, fit.drift, fit.drift_std * (1.0 - model.drift))
    return eye, model, clock, float(fit.offset_at(model.stamp_ns))


def _drift_message(fit: DriftFit) -> str:
    n = int(fit.inliers.sum())
    return (
        f'the time offset drifts: measured in {n} windows along the recording it changes '
        f'at {fit.drift * 1e6:+.1f} +- {fit.drift_std * 1e6:.1f} ppm, '
        f'{fit.change_s * 1e3:+.1f} ms between the first and the last eye pose; the '
        'result holds one mean offset, so the ends are off by about '
        f'{abs(fit.change_s) * 0.5e3:.1f} ms. Estimate the drift with --clock-drift (node '
        'parameter clock_drift)'
    )


def _absolute_clock(fit: DriftFit, model: EyeModel) -> DriftFit:
    """A window fit measured on an eye the model was applied to, on the eye's own clock:
    the model's drift added back to the offsets and the rate."""

    def back(t_ns: np.ndarray | int) -> np.ndarray:
        return model.drift * (np.asarray(t_ns) - np.int64(model.stamp_ns)) * 1e-9

    out = fit.shifted(model.shift_ns)
    return replace(
        out,
        offsets_s=out.offsets_s + back(fit.centres_ns),
        offset_s=out.offset_s + float(back(fit.stamp_ns)),
        drift=fit.drift + model.drift * (1.0 - fit.drift),
    )


def _scale_from_rotations(
    hand: Trajectory, eye: Trajectory, model: EyeModel, cfg: CalibrationConfig
) -> tuple[Trajectory, EyeModel]:
    """With estimate_scale, before stage 2: a first scale (:func:`.linear.scale.scale_prior`) from the
    rotation of T_HE that the rotations alone give (RANSAC with no translation threshold), so
    that stage 2's thresholds in metres mean metres."""
    pairs = associate(hand, eye, 0.0)
    m = build_motions(pairs, cfg.relative_poses, np.deg2rad(cfg.eta))
    rot = calibrate_linear(
        m,
        robust_kernel=False,
        ransac_iterations=cfg.ransac_iterations,
        inlier_rotation_rad=np.deg2rad(cfg.inlier_rotation),
        inlier_translation_m=np.inf,
        min_motions=cfg.min_motions,
        adaptive_inliers=False,
        decoupled_refit=True,
        rng=np.random.default_rng(cfg.seed),
    )
    if rot.unobservable:
        return eye, model
    k = rot.inliers
    fit = scale_prior(m.A[0][k], m.A[1][k], m.B[1][k], rot.q_HE, drift_weights(m, k))
    if not fit.observable:  # the eye stays as it is; the verdict will say why
        return eye, replace(model, scale_std=fit.scale_std, scale_estimated=True)
    return model.add_scale(eye, fit.scale, fit.scale_std)


def _fold_linear_scale(
    eye: Trajectory, model: EyeModel, lin: LinearSolution, run: _Run
) -> tuple[Trajectory, EyeModel]:
    """Stage 2's scale (on top of the first one) into the eye, whose translations its T_HE
    assumes."""
    if not model.scale_observable or not observable(lin.scale, lin.scale_std):
        std = lin.scale_std * model.scale if np.isfinite(lin.scale_std) else np.inf
        return eye, replace(model, scale_std=max(std, model.scale_std))
    if lin.scale_dq > 0 and abs(lin.scale_dq / lin.scale - 1.0) > 0.05:
        run.notes.append(
            f'the dual-quaternion path gives a scale {lin.scale_dq:.4f} against '
            f"the translation refit's {lin.scale:.4f} (relative to the first "
            'estimate)'
        )
    return model.add_scale(eye, lin.scale, model.scale * lin.scale_std)


def _fold_batch(
    eye: Trajectory, model: EyeModel, batch: BatchSolution
) -> tuple[Trajectory, EyeModel]:
    """The batch stage's drift and scale corrections into the eye and the model."""
    k = 7
    if batch.clock_drift is not None:
        eye, model = model.add_drift(
            eye, batch.clock_drift, float(batch.std[k]) * (1.0 - model.drift)
        )
        k += 1
    if batch.scale is not None:
        eye, model = model.add_scale(
            eye, batch.scale, float(batch.std[k]) * model.scale * batch.scale
        )
    return eye, model


def _scale_check(pairs: PosePairs, lin: LinearSolution, cfg: CalibrationConfig) -> ScaleFit | None:
    """Without estimate_scale: the translation part of AX = XB fitted with and without a scale
    (all motions, Huber loss), to name an eye whose translations a scale explains."""
    if lin.unobservable:
        return None
    m = build_motions(pairs, cfg.relative_poses, np.deg2rad(cfg.eta))
    if len(m) < cfg.min_motions:
        return None
    every = np.ones(len(m), bool)
    return translation_and_scale(
        m.A[0], m.A[1], m.B[1], matrix_from_quat(lin.q_HE), drift_weights(m, every), robust=True
    )


def _scale_message(fit: ScaleFit) -> str:
    return (
        f"the eye's translations look scaled: s = {fit.scale:.4g} +- "
        f"{fit.scale_std:.2g} (s * eye positions metric) makes them fit the hand's "
        f'(median translation residual {fit.rms_with * 1e3:.0f} mm with it, '
        f'{fit.rms_without * 1e3:.0f} mm without), and taking s = 1 moves the translation '
        f'of T_HE by {fit.shift_m * 1e3:.0f} mm: a monocular VO, a metric VIO whose scale is '
        f'off by {abs(fit.scale - 1.0):.1%}, or positions in other units. Estimate it with '
        '--scale (node parameter estimate_scale)'
    )


def _assess_model(
    model: EyeModel, clock: DriftFit | None, cfg: CalibrationConfig, run: _Run
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


# ----------------------------------------------------------------------------- stage 3


def _run_batch(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    q_HE: np.ndarray,
    p_HE: np.ndarray,
    cfg: CalibrationConfig,
    model: EyeModel | None = None,
) -> tuple[BatchSolution | None, str]:
    """The batch refinement, or None and why it was not used (never raises). It estimates a
    clock drift when one was estimated before it, and a scale when asked."""
    try:
        sol = refine(
            hand,
            eye,
            dt,
            q_HE,
            p_HE,
            knot_spacing=cfg.knot_spacing,
            order=cfg.spline_order,
            hand_noise=(cfg.hand_noise_rotation, cfg.hand_noise_translation),
            eye_noise=(cfg.eye_noise_rotation, cfg.eye_noise_translation),
            huber_delta=cfg.huber_delta,
            max_iterations=cfg.batch_max_iterations,
            joint=cfg.batch_joint,
            fix_time_offset=cfg.time_offset is not None,
            decoupled=cfg.batch_decoupled,
            drift_stamp_ns=(
                model.stamp_ns if model is not None and model.drift_estimated else None
            ),
            scale=cfg.estimate_scale and model is not None and model.scale_observable,
        )
    except HandeyeError as err:
        return None, str(err)
    except (ValueError, np.linalg.LinAlgError, RuntimeError) as err:
        return None, f'the solver failed ({err})'
    if not np.all(np.isfinite(sol.covariance)):
        return None, 'the solution has no finite covariance (degenerate motion)'
    # each solve only takes steps that lower its cost; the decoupled one trades the full cost
    # for a rotation free of translation errors, so only the plain solve is held to it
    if not sol.decoupled and sol.cost_after > sol.cost_before * (1 + 1e-9):
        return None, (f'it made the cost worse ({sol.cost_before:.6g} -> {sol.cost_after:.6g})')
    return sol, ''


def _check_batch(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    lin: LinearSolution,
    sol: BatchSolution,
    cfg: CalibrationConfig,
    run: _Run,
) -> BatchSolution | None:
    """When the batch stage moves dt or T_HE beyond its own sigmas, let the self-check decide
    between it and the linear result. Returns the batch solution, or None when rejected."""
    s = sol.std
    moved_dt = abs(sol.time_offset_s - dt)
    moved_t = float(np.linalg.norm(sol.p_HE - lin.p_HE))
    moved_r = float(np.degrees(quat_angle(sol.q_HE, lin.q_HE)))
    far_dt = moved_dt > max(BATCH_SIGMAS * s[0], BATCH_DT_MIN_S)
    far_x = moved_t > max(
        BATCH_SIGMAS * float(np.linalg.norm(s[1:4])), BATCH_TRANSLATION_MIN_M
    ) or moved_r > max(
        BATCH_SIGMAS * float(np.degrees(np.linalg.norm(s[4:]))), BATCH_ROTATION_MIN_DEG
    )
    if not (far_dt or far_x):
        return sol
    what = (
        f'the batch stage moved dt by {moved_dt * 1e3:.1f} ms and T_HE by '
        f'{moved_t * 1e3:.0f} mm / {moved_r:.2f} deg from the linear result'
    )
    # the offset: stage 2 at each offset, scored alike; the extrinsic: the batch's against
    # stage 2's at the batch's offset
    hyps = [(dt, 'linear stage', lin.q_HE, lin.p_HE)]
    lin_b = lin
    if far_dt:
        try:
            lin_b, _ = _linear(hand, eye, sol.time_offset_s, cfg)
        except HandeyeError as err:
            run.reason(Code.STAGES_DISAGREE, f'{what}, and stage 2 fails at its offset ({err})')
            return None
        hyps.append(
            (sol.time_offset_s, 'linear stage at the batch offset', lin_b.q_HE, lin_b.p_HE)
        )
    hyps.append((sol.time_offset_s, 'batch stage', sol.q_HE, sol.p_HE))
    scored = score_candidates(hand, eye, hyps, np.deg2rad(cfg.eta))
    run.candidates.extend(scored)
    score = [c.score for c in scored]
    if not np.all(np.isfinite(score)):
        run.reason(Code.STAGES_DISAGREE, f'{what}, and the self-check could not compare them')
        return sol
    offset_ok = not far_dt or score[1] <= AMBIGUOUS_SCORE_RATIO * score[0]
    extrinsic_ok = score[-1] <= BATCH_SCORE_FACTOR * score[-2]
    if offset_ok and extrinsic_ok:
        run.notes.append(
            f'{what}; the self-check supports it (scores '
            + ', '.join(f'{c.source} {c.score:.3g}' for c in scored)
            + ')'
        )
        return sol
    run.reason(
        Code.STAGES_DISAGREE,
        f'{what}; the self-check sides with the linear result (scores '
        + ', '.join(f'{c.source} {c.score:.3g}' for c in scored)
        + '), which is kept',
    )
    return None


def _check_fixed_offset(hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig) -> list[str]:
    """Warn when a user-fixed offset disagrees with the angular-speed correlation.

    Why: the linear stage cannot tell a wrong offset from a noisy eye (a 50 ms error still gives
    most motions as inliers at moderate speed), so a wrong fixed value would pass silently.
    """
    half = cfg.max_time_offset or DEFAULT_HALF_WINDOW_S
    try:
        est = align_time(
            hand,
            eye,
            max_time_offset=half,
            time_offset_guess=cfg.time_offset,
            resample_rate_hz=cfg.resample_rate_hz,
        )
    except TimeAlignmentError as err:
        return [f'could not check the fixed time offset against the data: {err}']
    if (
        est.peak_correlation >= WEAK_CORRELATION
        and abs(est.time_offset_s - cfg.time_offset) > FIXED_OFFSET_DISAGREEMENT_S
    ):
        return [
            (
                f'the fixed time offset {cfg.time_offset * 1e3:+.1f} ms disagrees with the '
                f'angular-speed correlation, which peaks at {est.time_offset_s * 1e3:+.1f} ms '
                f'(correlation {est.peak_correlation:.2f}); check the fixed value'
            )
        ]
    return []


# ----------------------------------------------------------------------------- verdict


def _absolute(tv: TimeAlignment | None, shift_ns: int) -> TimeAlignment | None:
    """The vector refinement's result on the original clocks."""
    if tv is None:
        return None
    return replace(
        tv,
        time_offset_s=shift_ns * 1e-9 + tv.time_offset_s,
        time_offset_ns=shift_ns + tv.time_offset_ns,
        window_s=(shift_ns * 1e-9 + tv.window_s[0], shift_ns * 1e-9 + tv.window_s[1]),
        lags_s=None if tv.lags_s is None else shift_ns * 1e-9 + tv.lags_s,
        candidates=tuple((shift_ns * 1e-9 + c, r) for c, r in tv.candidates),
    )


def _assess(
    ta: TimeAlignment,
    tv: TimeAlignment | None,
    lin: LinearSolution,
    batch: BatchSolution | None,
    screening: tuple[Screening, Screening],
    metrics: Metrics,
    cfg: CalibrationConfig,
    run: _Run,
) -> None:
    """The remaining reasons of :mod:`.checks.verdict` (the others were added where they arose)."""
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
    m = metrics
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
