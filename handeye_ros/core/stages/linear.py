"""Stage 2 as the pipeline runs it (:class:`LinearStage`), and what attaches to it at named
points: the eye moved onto the hand's clock by stage 1's offset (and, with ``clock_drift``,
the drift from the windows; with ``estimate_scale``, a first scale); stage 2 (:mod:`.robust`);
the scale check; the eye's breaks (VIO resets) found against the hand and stage 2 again
without them; the self-check over the candidate offsets; the offset along the recording; stage
2's scale. The seed check runs
once the answer is final (:func:`seed_check`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ..association import PosePairs
from ..batch.rank import undetermined
from ..checks.breaks import find_eye_breaks
from ..checks.excerpt import excerpt, spread_sample
from ..checks.positions import scale_said, still_said, units_said
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
    Findings,
    ScaleMeasured,
    SeedCompared,
    SeedFailed,
    judge_tie,
    scale_keeps_whole,
)
from ..config import CalibrationConfig
from ..errors import DegenerateMotionError, HandeyeError, InputError
from ..eye_model import EyeModel
from ..geometry import difference, matrix_from_quat
from ..linear.refits import held_alike
from ..linear.robust import LinearSolution
from ..linear.solve import solve_linear
from ..time.align import TimeAlignment
from ..time.clock import DriftFit, covered_span
from ..trajectory import Trajectory
from .drift import clock_along, drift_from_windows
from .prepare import Inputs, check_fraction
from .scale import fold_linear_scale, rotations_scale, scale_check, scale_from_rotations
from .time import Offset

if TYPE_CHECKING:  # stage 3 sits above stage 2: its answer only bounds the seed check
    from ..batch.refine import BatchSolution

#: Two candidate offsets closer than this (s), or than DISTINCT_STEPS grid steps of stage 1,
#: are one: the batch stage refines within that, and the self-check cannot separate offsets a
#: few milliseconds apart on a slow motion anyway.
SAME_OFFSET_S = 2e-3
DISTINCT_STEPS = 3


@dataclass(frozen=True)
class Solved:
    """Stage 2 at the offset dt [s] (from stage 1's): its solution and the pose pairs it
    associated there."""

    dt: float
    solution: LinearSolution
    pairs: PosePairs


def solve_at(hand: Trajectory, eye: Trajectory, dt: float, cfg: CalibrationConfig) -> Solved:
    """Stage 2 at the offset dt [s] (:func:`~handeye_ros.core.linear.solve.solve_linear`)."""
    return Solved(dt, *solve_linear(hand, eye, dt, cfg))


@dataclass(frozen=True)
class LinearStage:
    """eye: T_WE on the hand's clock up to ``dt`` (stage 1's offset, any drift and scale taken
    out), split at its breaks; model: what was applied to it; dt: the offset left [s];
    solution: stage 2's answer; clock: the offset measured along the recording (None when not
    measured);
    screening: what was removed from each stream, the eye's breaks and outliers included;
    found: what stage 2 and its checks found; scale_named: the scale check named the eye's
    scale (a reason or a note), so that the batch stage does not again."""

    eye: Trajectory
    model: EyeModel
    dt: float
    solution: LinearSolution
    clock: DriftFit | None
    screening: tuple[Screening, Screening]
    found: Findings
    scale_named: bool


def linear_stage(inputs: Inputs, offset: Offset, cfg: CalibrationConfig) -> LinearStage:
    """Stage 2 and what attaches to it (see the module docstring)."""
    hand, shift_ns, screening = offset.hand, offset.shift_ns, inputs.screening
    # from here on the eye is on the hand's clock (up to stage 1's error): offsets are small
    eye = offset.eye.shifted(-shift_ns)
    model = EyeModel(shift_ns, stamp_ns=covered_span(hand, eye)[2])
    if cfg.clock_drift and not eye.keyframes:
        eye, model = drift_from_windows(hand, eye, model, cfg)
    if cfg.estimate_scale:
        eye, model = scale_from_rotations(hand, eye, model, cfg)
    solved = _first_solve(hand, eye, offset, cfg)
    scaled = None if cfg.estimate_scale else scale_check(solved.pairs, solved.solution, cfg)
    measured = () if scaled is None else (ScaleMeasured(scaled),)
    found = Findings.of(*measured)
    # a clear scale leaves the eye whole (scale_keeps_whole says when)
    whole = scaled is not None and scale_keeps_whole(scaled, cfg.precision_translation)
    if cfg.screening and not whole:
        split = split_eye(hand, eye, solved, cfg, screening, shift_ns)
        eye, solved, screening = split.eye, split.solved, split.screening
        found = found + split.found
    clock = None
    if not offset.fixed:
        solved, checked = self_check(hand, eye, offset.alignment, shift_ns, solved, cfg)
        # the offset along the recording, with stage 2's rotation
        along = clock_along(hand, eye, model, solved.dt, solved.solution, cfg)
        eye, model, clock = along.eye, along.model, along.clock
        found = found + checked + along.found
        if along.moved is not None:
            solved = solve_at(hand, eye, along.moved, cfg)
    if cfg.estimate_scale:
        eye, model, folded = fold_linear_scale(eye, model, solved.solution)
        found = found + folded
    named = scaled is not None and scaled.clear
    return LinearStage(eye, model, solved.dt, solved.solution, clock, screening, found, named)


def _first_solve(
    hand: Trajectory, eye: Trajectory, offset: Offset, cfg: CalibrationConfig
) -> Solved:
    """Stage 2 at stage 1's offset; a degenerate answer inside a narrowed search window says
    that the offset may lie outside it."""
    try:
        return solve_at(hand, eye, 0.0, cfg)
    except DegenerateMotionError as err:
        said = _input_said(hand, eye, cfg)
        if said:  # the input's, not the motion's
            raise InputError(f'{said} (stage 2: {err})') from None
        if offset.fixed or (cfg.max_time_offset is None and cfg.time_offset_guess is None):
            raise
        lo, hi = offset.alignment.window_s
        msg = (
            f'{err}. The time offset was searched in [{lo:+.3f}, {hi:+.3f}] s only: if it '
            'lies outside, the correlation found a false peak there; widen max_time_offset '
            'or move time_offset_guess (or leave both unset to search every lag)'
        )
        raise type(err)(msg) from None


def _input_said(hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig) -> str:
    """Why a failed stage 2 lies in the input: positions in millimetres (:func:`units_said`) or
    at a scale (:func:`scale_said`) by the scale the rotations alone give (without
    ``estimate_scale``), or positions that hardly move (:func:`still_said`); '' when none (the
    refusal being explained stands as it is)."""
    fit = None
    if not cfg.estimate_scale:
        try:
            fit = rotations_scale(hand, eye, cfg)
        except DegenerateMotionError:
            pass
    return units_said(fit) or scale_said(fit) or still_said(hand, eye)


@dataclass(frozen=True)
class Split:
    """The eye split at its breaks (VIO resets) with its wild poses left out, stage 2 on it,
    what screening removed (the breaks and outliers added to the eye's report) and the note of
    the breaks."""

    eye: Trajectory
    solved: Solved
    screening: tuple[Screening, Screening]
    found: Findings


def split_eye(
    hand: Trajectory,
    eye: Trajectory,
    solved: Solved,
    cfg: CalibrationConfig,
    screening: tuple[Screening, Screening],
    shift_ns: int,
) -> Split:
    """Breaks (VIO resets) and leftover wild poses of the eye, against the hand, at stage 2's
    answer ``solved`` (at offset 0); stage 2 again when any were found."""
    lin = solved.solution
    breaks = find_eye_breaks(hand, eye, 0.0, matrix_from_quat(lin.q_HE), lin.p_HE)
    if not (breaks.breaks_ns.size or breaks.outliers_ns.size or breaks.short_ns.size):
        return Split(eye, solved, screening, Findings())
    sh, se = screening
    # the report keeps the eye's own stamps; this eye was moved by shift_ns
    se = se.merged(breaks.outliers_ns + shift_ns, 'outlier').merged(
        breaks.short_ns + shift_ns, 'short_segment', breaks.breaks_ns + shift_ns
    )
    check_fraction(se, eye, cfg)
    said = Findings()
    if breaks.breaks_ns.size:
        said = Findings.warned(
            f'the eye stream was split at {breaks.breaks_ns.size} break(s) (a VIO reset or '
            "jump of its world frame: its motion there disagrees with the hand's); no "
            'motion or residual spans one',
            noted=True,
        )
    return Split(breaks.eye, solve_at(hand, breaks.eye, 0.0, cfg), (sh, se), said)


def self_check(
    hand: Trajectory,
    eye: Trajectory,
    ta: TimeAlignment,
    shift_ns: int,
    solved: Solved,
    cfg: CalibrationConfig,
) -> tuple[Solved, Findings]:
    """Stage 2 at every distinct candidate offset, on a bounded excerpt of the recording
    (:mod:`~handeye_ros.core.checks.excerpt`), scored alike; the best one wins, and stage 2
    runs on the whole recording at it. Found: why each candidate lost, the self-check's note
    or tie, the candidates."""
    dt, lin = solved.dt, solved.solution
    same = max(SAME_OFFSET_S, DISTINCT_STEPS * ta.step_s)
    tried = [_Tried(dt, 'correlation peak', lin)]
    proposals = [_Proposal(0.0, 'correlation peak')] + [
        _Proposal(c - shift_ns * 1e-9, f'correlation runner-up ({r:.2f})')
        for c, r in ta.candidates
    ]
    # eq. 9 first: an offset whose motions turn by other angles than the eye's is wrong
    # whatever T_HE is, and costs no RANSAC to rule out
    i, j = eye_keyframes(eye, np.deg2rad(cfg.eta))
    motions = spread_sample(i, j)
    found = Findings()
    in_hand = screw_disagreement(hand, eye, dt, *motions)
    for proposal in proposals:
        if any(abs(proposal.offset_s - t.offset_s) < same for t in tried):
            continue
        there = screw_disagreement(hand, eye, proposal.offset_s, *motions)
        if screw_rejects(there, in_hand):
            why = (
                f'the motions turn by angles {there:.2g} deg apart there in the median, '
                f'{in_hand:.2g} deg at {(shift_ns * 1e-9 + dt):+.4f} s (eq. 9)'
            )
            found = found + proposal.ruled_out(shift_ns, 'rejected by eq. 9', why, lin)
            continue
        try:
            candidate = _stage2_at(hand, eye, proposal, i.size, cfg)
        except HandeyeError as err:
            how = 'rejected, stage 2 fails there'
            found = found + proposal.ruled_out(shift_ns, how, str(err), lin)
            continue
        if not any(abs(candidate.offset_s - t.offset_s) < same for t in tried):
            tried.append(candidate)
    if len(tried) == 1:
        if found.candidates:  # every other candidate was ruled out
            chosen = replace(_unscored(dt, tried[0].source, lin), chosen=True)
            found = found + Findings(candidates=(chosen,))
        return solved, found
    scored = score_candidates(hand, eye, [t.hypothesis() for t in tried], motions)
    best, judged = judge_tie(scored, shift_ns)
    found = found + Findings(
        log=(judged,), candidates=tuple(replace(c, chosen=k == best) for k, c in enumerate(scored))
    )
    if best == 0:
        return solved, found
    # the winner was judged on the excerpt: stage 2 on the whole recording
    return solve_at(hand, eye, tried[best].offset_s, cfg), found


@dataclass(frozen=True)
class _Tried:
    """A candidate offset stage 2 solved: offset_s (s, from stage 1's), where it came from,
    and stage 2's solution there."""

    offset_s: float
    source: str
    solution: LinearSolution

    def hypothesis(self) -> Hypothesis:
        return Hypothesis(self.offset_s, self.source, self.solution.q_HE, self.solution.p_HE)


@dataclass(frozen=True)
class _Proposal:
    """A candidate offset: offset_s (s, from stage 1's) and where it came from."""

    offset_s: float
    source: str

    def ruled_out(self, shift_ns: int, how: str, why: str, lin: LinearSolution) -> Findings:
        """The note of why it lost and the candidate unscored (its source followed by ``how``),
        with stage 2's extrinsic ``lin`` in hand."""
        at = shift_ns * 1e-9 + self.offset_s
        text = f'candidate offset {at:+.4f} s ({self.source}) rejected: {why}'
        lost = _unscored(self.offset_s, f'{self.source}: {how}', lin)
        return Findings(log=(text,), candidates=(lost,))


def _stage2_at(
    hand: Trajectory, eye: Trajectory, proposal: _Proposal, n_motions: int, cfg: CalibrationConfig
) -> _Tried:
    """Stage 2 at a candidate offset, on the recording's excerpt at that offset (the eye has
    ``n_motions`` keyframe motions); raises a HandeyeError when stage 2 fails there."""
    offset = proposal.offset_s
    there = solve_at(*excerpt(hand, eye, offset, n_motions), offset, cfg)
    return _Tried(there.dt, proposal.source, there.solution)


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
) -> tuple[LinearSolution | None, Findings]:
    """Stage 2 again with the next RANSAC seed: the answer must not hinge on it, on the
    directions of T_HE the batch stage determines, beyond its own uncertainty
    (:func:`~handeye_ros.core.checks.verdict.seed_reason`), recorded as a fact. ``eye`` and
    ``dt`` are those stage 2 ran at (``lin``'s): what the batch stage changed since is no
    seed's doing."""
    if cfg.ransac_iterations == 0:
        return None, Findings()
    try:
        other, _ = solve_linear(hand, eye, dt, cfg, seed=(cfg.seed + 1) % 2**31)
    except HandeyeError as err:
        return None, Findings.of(SeedFailed(cfg.seed + 1, str(err)))
    there = (other.q_HE, other.p_HE)
    if lin.held_rotation and lin.motions is not None and lin.held_axis is not None:
        # both hold the rotation about the axis by a rule: compared where the screw the
        # motions leave open brings them together (exact, however far apart the rule put them)
        there = held_alike(lin.motions, lin.inliers, lin.held_axis, there, (lin.q_HE, lin.p_HE))
    d = difference(*there, lin.q_HE, lin.p_HE)
    if batch is not None and np.all(np.isfinite(batch.covariance)):
        # a direction the batch stage held (one rotation axis: the lever arm along it, the
        # rotation about it) is one the motions leave open by design: no seed singles it out
        held = undetermined(batch.covariance[1:7, 1:7])
        d = d - held @ (held.T @ d)
    d_rot, d_t = float(np.degrees(np.linalg.norm(d[3:]))), float(np.linalg.norm(d[:3]))
    std = None if batch is None else batch.std
    return other, Findings.of(SeedCompared(cfg.seed + 1, d_rot, d_t, std))
