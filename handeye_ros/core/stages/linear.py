"""Stage 2 as the pipeline runs it (:class:`LinearStage`), and what attaches to it at named
points: the eye moved onto the hand's clock by stage 1's offset (and, with ``clock_drift``,
the drift from the windows; with ``estimate_scale``, a first scale); stage 2 (:mod:`.robust`);
the scale check; the eye's breaks (VIO resets) found against the hand and stage 2 again
without them; the vector refinement of the offset, iterated with stage 2; the self-check over
the candidate offsets; the offset along the recording; stage 2's scale. The seed check runs
once the answer is final (:func:`seed_check`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ..association import PosePairs
from ..checks.breaks import find_eye_breaks
from ..checks.excerpt import excerpt, spread_sample
from ..checks.screening import Screening
from ..checks.selfcheck import (
    Candidate,
    Hypothesis,
    eye_keyframes,
    score_candidates,
    screw_disagreement,
    screw_rejects,
)
from ..checks.verdict import (
    ScaleMeasured,
    SeedCompared,
    SeedFailed,
    judge_tie,
    scale_doubtful,
)
from ..config import CalibrationConfig
from ..errors import DegenerateMotionError, HandeyeError, TimeAlignmentError
from ..eye_model import EyeModel
from ..geometry import matrix_from_quat, quat_angle
from ..linear.robust import LinearSolution
from ..linear.solve import solve_linear
from ..time.align import TimeAlignment, align_time_vector
from ..time.clock import DriftFit, covered_span
from ..trajectory import Trajectory
from .drift import clock_along, drift_from_windows
from .findings import Findings
from .prepare import Inputs, check_fraction
from .scale import fold_linear_scale, scale_check, scale_from_rotations
from .time import Offset

if TYPE_CHECKING:  # stage 3 sits above stage 2: its answer only bounds the seed check
    from ..batch.refine import BatchSolution

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


@dataclass(frozen=True)
class LinearStage:
    """eye: T_WE on the hand's clock up to ``dt`` (stage 1's offset, any drift and scale taken
    out), split at its breaks; model: what was applied to it; dt: the offset left [s];
    solution: stage 2's answer; vector: the vector refinement's alignment (None when it did not
    run); clock: the offset measured along the recording (None when not measured);
    screening: what was removed from each stream, the eye's breaks and outliers included."""

    eye: Trajectory
    model: EyeModel
    dt: float
    solution: LinearSolution
    vector: TimeAlignment | None
    clock: DriftFit | None
    screening: tuple[Screening, Screening]


def linear_stage(
    inputs: Inputs, offset: Offset, cfg: CalibrationConfig, run: Findings
) -> LinearStage:
    """Stage 2 and what attaches to it (see the module docstring)."""
    hand, shift_ns, screening = offset.hand, offset.shift_ns, inputs.screening
    # from here on the eye is on the hand's clock (up to stage 1's error): offsets are small
    eye = offset.eye.shifted(-shift_ns)
    model = EyeModel(shift_ns, stamp_ns=covered_span(hand, eye)[2])
    dt = 0.0
    if cfg.clock_drift and not eye.keyframes:
        eye, model = drift_from_windows(hand, eye, model, cfg)
    if cfg.estimate_scale:
        eye, model = scale_from_rotations(hand, eye, model, cfg)
    lin, pairs = _first_solve(hand, eye, offset, cfg)
    scaled = None if cfg.estimate_scale else scale_check(pairs, lin, cfg)
    if scaled is not None:
        run.record(ScaleMeasured(scaled, cfg.precision_translation))
        run.scale_named = scaled.clear  # as a reason or a note
    # a scale that is a reason leaves the eye whole (scale_doubtful says why)
    whole = scaled is not None and scale_doubtful(scaled, cfg.precision_translation)
    if cfg.screening and not whole:
        eye, lin, pairs, screening = split_eye(
            hand, eye, lin, pairs, cfg, screening, shift_ns, run
        )
    tv = clock = None
    if not offset.fixed:
        dt, lin, pairs, tv = refine_vector(hand, eye, dt, lin, pairs, cfg, run)
        dt, lin, pairs = self_check(
            hand, eye, offset.alignment, shift_ns, dt, lin, pairs, cfg, run
        )
        # the offset along the recording, with stage 2's rotation
        eye, model, clock, moved = clock_along(hand, eye, model, dt, lin, cfg, run)
        if moved is not None:
            dt = moved
            lin, pairs = solve_linear(hand, eye, dt, cfg)
    if cfg.estimate_scale:
        eye, model = fold_linear_scale(eye, model, lin, run)
    return LinearStage(eye, model, dt, lin, tv, clock, screening)


def _first_solve(
    hand: Trajectory, eye: Trajectory, offset: Offset, cfg: CalibrationConfig
) -> tuple[LinearSolution, PosePairs]:
    """Stage 2 at stage 1's offset; a degenerate answer inside a narrowed search window says
    that the offset may lie outside it."""
    try:
        return solve_linear(hand, eye, 0.0, cfg)
    except DegenerateMotionError as err:
        if offset.fixed or (cfg.max_time_offset is None and cfg.time_offset_guess is None):
            raise
        lo, hi = offset.alignment.window_s
        msg = (
            f'{err}. The time offset was searched in [{lo:+.3f}, {hi:+.3f}] s only: if it '
            'lies outside, the correlation found a false peak there; widen max_time_offset '
            'or move time_offset_guess (or leave both unset to search every lag)'
        )
        raise DegenerateMotionError(msg) from None


def split_eye(
    hand: Trajectory,
    eye: Trajectory,
    lin: LinearSolution,
    pairs: PosePairs,
    cfg: CalibrationConfig,
    screening: tuple[Screening, Screening],
    shift_ns: int,
    run: Findings,
) -> tuple[Trajectory, LinearSolution, PosePairs, tuple[Screening, Screening]]:
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
    check_fraction(se, eye, cfg)
    if found.breaks_ns.size:
        note = (
            f'the eye stream was split at {found.breaks_ns.size} break(s) (a VIO reset or '
            "jump of its world frame: its motion there disagrees with the hand's); no "
            'motion or residual spans one'
        )
        run.warnings.append(note)
        run.note(note)
    lin, pairs = solve_linear(hand, found.eye, 0.0, cfg)
    return found.eye, lin, pairs, (sh, se)


def refine_vector(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    lin: LinearSolution,
    pairs: PosePairs,
    cfg: CalibrationConfig,
    run: Findings,
) -> tuple[float, LinearSolution, PosePairs, TimeAlignment | None]:
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
        lin, pairs = solve_linear(hand, eye, dt, cfg)
    return dt, lin, pairs, tv


def self_check(
    hand: Trajectory,
    eye: Trajectory,
    ta: TimeAlignment,
    shift_ns: int,
    dt: float,
    lin: LinearSolution,
    pairs: PosePairs,
    cfg: CalibrationConfig,
    run: Findings,
) -> tuple[float, LinearSolution, PosePairs]:
    """Stage 2 at every distinct candidate offset, on a bounded excerpt of the recording
    (:mod:`~handeye_ros.core.checks.excerpt`), scored alike; the best one wins, and stage 2
    runs on the whole recording at it."""
    same = max(SAME_OFFSET_S, DISTINCT_STEPS * ta.step_s)
    tried = [_Tried(dt, 'vector refinement' if dt != 0.0 else 'correlation peak', lin)]
    proposals = [(0.0, 'correlation peak')] + [
        (c - shift_ns * 1e-9, f'correlation runner-up ({r:.2f})') for c, r in ta.candidates
    ]
    # eq. 9 first: an offset whose motions turn by other angles than the eye's is wrong
    # whatever T_HE is, and costs no RANSAC to rule out
    i, j = eye_keyframes(eye, np.deg2rad(cfg.eta))
    motions = spread_sample(i, j)
    examined = len(run.candidates)
    in_hand = screw_disagreement(hand, eye, dt, *motions)
    for offset, source in proposals:
        if any(abs(offset - t.offset_s) < same for t in tried):
            continue
        there = screw_disagreement(hand, eye, offset, *motions)
        if screw_rejects(there, in_hand):
            run.note(
                f'candidate offset {(shift_ns * 1e-9 + offset):+.4f} s ({source}) rejected: '
                f'the motions turn by angles {there:.2g} deg apart there in the median, '
                f'{in_hand:.2g} deg at {(shift_ns * 1e-9 + dt):+.4f} s (eq. 9)'
            )
            run.candidates.append(_unscored(offset, f'{source}: rejected by eq. 9', lin))
            continue
        found = _stage2_at(hand, eye, offset, source, shift_ns, lin, i.size, cfg, run)
        if found is not None and not any(abs(found.offset_s - t.offset_s) < same for t in tried):
            tried.append(found)
    if len(tried) == 1:
        if len(run.candidates) > examined:  # every other candidate was ruled out
            run.candidates.append(replace(_unscored(dt, tried[0].source, lin), chosen=True))
        return dt, lin, pairs
    scored = score_candidates(hand, eye, [t.hypothesis() for t in tried], motions)
    best = judge_tie(scored, shift_ns, run)
    run.candidates.extend(replace(c, chosen=k == best) for k, c in enumerate(scored))
    if best == 0:
        return dt, lin, pairs
    # the winner was judged on the excerpt: stage 2 and its refinement on the whole recording
    won = tried[best].offset_s
    won, won_lin, won_pairs, _ = refine_vector(
        hand, eye, won, *solve_linear(hand, eye, won, cfg), cfg, Findings()
    )
    return won, won_lin, won_pairs


@dataclass(frozen=True)
class _Tried:
    """A candidate offset stage 2 solved: offset_s (s, from stage 1's), where it came from,
    and stage 2's solution there."""

    offset_s: float
    source: str
    solution: LinearSolution

    def hypothesis(self) -> Hypothesis:
        return Hypothesis(self.offset_s, self.source, self.solution.q_HE, self.solution.p_HE)


def _stage2_at(
    hand: Trajectory,
    eye: Trajectory,
    offset: float,
    source: str,
    shift_ns: int,
    lin: LinearSolution,
    n_motions: int,
    cfg: CalibrationConfig,
    run: Findings,
) -> _Tried | None:
    """Stage 2 at a candidate offset (s, from ``shift_ns``) with its vector refinement, on the
    recording's excerpt at that offset (the eye has ``n_motions`` keyframe motions), or None
    when stage 2 fails there (noted, and counted among the candidates unscored)."""
    part_hand, part_eye = excerpt(hand, eye, offset, n_motions)
    try:
        lin_c, pairs_c = solve_linear(part_hand, part_eye, offset, cfg)
        if offset != 0.0 and cfg.vector_refinement and not lin_c.unobservable:
            offset, lin_c, pairs_c, _ = refine_vector(
                part_hand, part_eye, offset, lin_c, pairs_c, cfg, Findings()
            )
    except HandeyeError as err:
        run.note(
            f'candidate offset {(shift_ns * 1e-9 + offset):+.4f} s ({source}) rejected: {err}'
        )
        run.candidates.append(_unscored(offset, f'{source}: rejected, stage 2 fails there', lin))
        return None
    return _Tried(offset, source, lin_c)


def _unscored(offset: float, source: str, lin: LinearSolution) -> Candidate:
    """A candidate offset the self-check did not score (ruled out before, or the only one
    left), with the extrinsic in hand."""
    nan = float('nan')
    return Candidate(offset, source, nan, nan, nan, lin.q_HE, lin.p_HE)


def seed_check(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    lin: LinearSolution,
    batch: BatchSolution | None,
    cfg: CalibrationConfig,
    run: Findings,
    pairs: PosePairs | None = None,
) -> LinearSolution | None:
    """Stage 2 again with the next RANSAC seed: the answer must not hinge on it beyond its own
    uncertainty (:func:`~handeye_ros.core.checks.verdict.seed_reason`). ``pairs``: the streams associated at dt, when already made."""
    if cfg.ransac_iterations == 0:
        return None
    try:
        other, _ = solve_linear(hand, eye, dt, cfg, seed=(cfg.seed + 1) % 2**31, pairs=pairs)
    except HandeyeError as err:
        run.record(SeedFailed(cfg.seed + 1, str(err)))
        return None
    d_rot = float(np.degrees(quat_angle(other.q_HE, lin.q_HE)))
    d_t = float(np.linalg.norm(other.p_HE - lin.p_HE))
    run.record(SeedCompared(cfg.seed + 1, d_rot, d_t, None if batch is None else batch.std))
    return other
