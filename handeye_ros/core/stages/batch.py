"""Stage 3 as the pipeline runs it (:class:`Refined`): the batch refinement from stage 2's
answer (:mod:`.refine`), kept when it converged with a finite covariance and the self-check does
not side against it; otherwise stage 2's answer is kept and the warnings say why. A drift it
estimated is folded into the eye, and a scale with estimate_scale; a metric eye's scale is
fitted beside (dt, T_HE) as a nuisance and marginalised out. Its covariance then gains what a
real VIO's errors over minutes add (:mod:`.correlated`: the blocks refitted here)."""

from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np

from ..arrays import Floats, Indices
from ..batch.correlated import (
    BLOCKS,
    MIN_BLOCK_POSES,
    Blocks,
    Uncertainty,
    cuts,
    error_of_mean,
    inflated,
    scale_share,
    scale_shift,
    varies,
    without,
)
from ..batch.options import BatchOptions
from ..batch.refine import BatchSolution, deviation, refine
from ..checks.selfcheck import Hypothesis, score_candidates, scored_motions
from ..checks.verdict import (
    Findings,
    StagesDisagree,
    batch_moved,
    batch_supported,
    scale_uncertainty_note,
    varies_note,
)
from ..config import CalibrationConfig
from ..errors import HandeyeError
from ..eye_model import EyeModel
from ..geometry import quat_angle
from ..linear.robust import LinearSolution
from ..linear.solve import solve_linear
from ..trajectory import Trajectory
from .linear import LinearStage

#: Each refit of the uncertainty's terms uses at most this many eye poses, evenly decimated: they
#: measure a ratio and a shift, not the estimate (an hour at 200 Hz has 720 000). All of them
#: reuse the estimate's spline of the MoCap, which depends on the MoCap alone: fitting it again
#: for each would double their cost.
MAX_AUX_POSES = 20_000
#: A block is refitted by this many Levenberg-Marquardt steps from the solution: one, its
#: linearised influence, as the blocks' cluster-robust covariance reads it. An iterated refit
#: of a block that hardly determines the rotation wanders into another minimum, where its
#: covariance says nothing of it; one step keeps it within its own sigma, so that it counts as
#: little as it determines (measured on real recordings: bench/results/accuracy.md).
BLOCK_STEPS = 1
#: A nuisance scale uncertain by more than this is not fitted: the eye's translations are too
#: short to tell a scale from the lever arm, and s = 1 is held (the result says so).
SCALE_UNOBSERVABLE = 0.1


@dataclass(frozen=True)
class Refined:
    """The answer after stage 3: dt [s] (the offset left on ``eye``), T_HE as (q_HE, p_HE),
    the batch solution (None: stage 2's answer was kept), the eye and its model with the
    batch stage's drift and scale folded in, and what the stage found (why it was not used,
    the self-check's word on it, the uncertainty's notes)."""

    dt: float
    q_HE: Floats
    p_HE: Floats
    batch: BatchSolution | None
    eye: Trajectory
    model: EyeModel
    found: Findings


def batch_stage(hand: Trajectory, linear: LinearStage, cfg: CalibrationConfig) -> Refined:
    """Stage 3 (see the module docstring)."""
    lin, dt, eye, model = linear.solution, linear.dt, linear.eye, linear.model
    q_HE, p_HE = lin.q_HE, lin.p_HE
    if not cfg.batch:
        return Refined(dt, q_HE, p_HE, None, eye, model, Findings())
    held = lin.held_axis
    if held is not None:  # the lever arm along the only rotation axis: at the user's value
        p_HE = p_HE - (p_HE @ held - cfg.held_lever_arm) * held
    batch, why = run_batch(hand, eye, dt, q_HE, p_HE, cfg, model, held, lin.held_rotation)
    found = Findings()
    if batch is not None:
        batch, found = check_batch(hand, eye, dt, lin, batch, cfg)
    if batch is None:
        why = why or 'the self-check sided with the linear result'
        kept = Findings.warned(f'batch stage not used, the linear result is kept: {why}')
        return Refined(dt, q_HE, p_HE, None, eye, model, found + kept)
    eye, model = fold_batch(eye, model, batch, cfg)
    batch = with_correlated(hand, eye, batch, cfg)
    notes = uncertainty_notes(batch, linear.scale_named)
    found = found + Findings.warned(*batch.warnings) + notes
    return Refined(batch.time_offset_s, batch.q_HE, batch.p_HE, batch, eye, model, found)


def uncertainty_notes(batch: BatchSolution, scale_named: bool) -> Findings:
    """The notes of the batch solution's uncertainty: the terms it could not estimate, the
    parameters that vary along the recording, and the eye's scale (unless stage 2 named it,
    ``scale_named``)."""
    unc = batch.uncertainty
    assert unc is not None, 'with_correlated measured it'
    notes = [f'uncertainty: {w}' for w in unc.not_estimated]
    for group, (spread, ratio) in unc.varies.items():
        sigma = float(np.linalg.norm(unc.std(group)))
        notes.append(varies_note(group, spread, ratio, sigma))
    if unc.scale is not None and not scale_named:
        s, std, shift = unc.scale
        note = scale_uncertainty_note(s, std, float(np.linalg.norm(shift[1:4])))
        notes += [note] if note else []
    return Findings.of(*notes)


def run_batch(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    q_HE: Floats,
    p_HE: Floats,
    cfg: CalibrationConfig,
    model: EyeModel | None = None,
    held_axis: Floats | None = None,
    held_rotation: bool = False,
) -> tuple[BatchSolution | None, str]:
    """The batch refinement, or None and why it was not used (never raises). It estimates a
    clock drift when one was estimated before it, and a scale: with estimate_scale when the
    model's is observable, and for a metric eye as a nuisance (:func:`_metric`). ``held_axis``:
    the only rotation axis (hand frame), along which the translation stays at p_HE's, and
    about which the rotation stays at q_HE's with ``held_rotation``."""
    try:
        options = replace(
            batch_options(cfg),
            held_axis=None if held_axis is None else tuple(float(v) for v in held_axis),
            held_rotation=held_rotation,
            drift_stamp_ns=model.stamp_ns if model is not None and model.drift_estimated else None,
            scale=cfg.estimate_scale and model is not None and model.scale_observable,
        )
        if cfg.estimate_scale:
            sol = refine(hand, eye, dt, q_HE, p_HE, options)
        else:
            sol = _metric(hand, eye, dt, q_HE, p_HE, options)
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


def _metric(
    hand: Trajectory, eye: Trajectory, dt: float, q_HE: Floats, p_HE: Floats, o: BatchOptions
) -> BatchSolution:
    """A metric eye's solve: its scale fitted beside (dt, T_HE) as a nuisance
    (:mod:`.correlated`), or held at 1 where the eye's translations cannot tell it from the
    lever arm (a sigma above SCALE_UNOBSERVABLE, or a singular solve)."""
    try:
        sol = refine(hand, eye, dt, q_HE, p_HE, replace(o, scale=True))
        std = sol.scale_std
        if std is not None and std < SCALE_UNOBSERVABLE and np.all(np.isfinite(sol.covariance)):
            return sol
    except (ValueError, np.linalg.LinAlgError, RuntimeError):
        pass
    return refine(hand, eye, dt, q_HE, p_HE, o)


def check_batch(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    lin: LinearSolution,
    sol: BatchSolution,
    cfg: CalibrationConfig,
) -> tuple[BatchSolution | None, Findings]:
    """When the batch stage moves dt or T_HE beyond its own sigmas, let the self-check decide
    between it and the linear result. Returns the batch solution, or None when rejected, and
    what the self-check found."""
    moved_dt = abs(sol.time_offset_s - dt)
    moved_t = float(np.linalg.norm(sol.p_HE - lin.p_HE))
    moved_r = float(np.degrees(quat_angle(sol.q_HE, lin.q_HE)))
    far_dt, far_x = batch_moved(moved_dt, moved_t, moved_r, sol.std)
    if not (far_dt or far_x):
        return sol, Findings()
    what = (
        f'the batch stage moved dt by {moved_dt * 1e3:.1f} ms and T_HE by '
        f'{moved_t * 1e3:.0f} mm / {moved_r:.2f} deg from the linear result'
    )
    # the offset: stage 2 at each offset, scored alike; the extrinsic: the batch's against
    # stage 2's at the batch's offset
    hyps = [Hypothesis(dt, 'linear stage', lin.q_HE, lin.p_HE)]
    lin_b = lin
    if far_dt:
        try:
            lin_b, _ = solve_linear(hand, eye, sol.time_offset_s, cfg)
        except HandeyeError as err:
            return None, Findings.of(StagesDisagree(what, failed=str(err)))
        hyps.append(
            Hypothesis(
                sol.time_offset_s, 'linear stage at the batch offset', lin_b.q_HE, lin_b.p_HE
            )
        )
    hyps.append(Hypothesis(sol.time_offset_s, 'batch stage', sol.q_HE, sol.p_HE))
    scored = score_candidates(hand, eye, hyps, scored_motions(eye, np.deg2rad(cfg.eta)))
    score = [c.score for c in scored]
    if not np.all(np.isfinite(score)):
        return sol, Findings(log=(StagesDisagree(what),), candidates=tuple(scored))
    if batch_supported(score, far_dt):
        scores = ', '.join(f'{c.source} {c.score:.3g}' for c in scored)
        said = f'{what}; the self-check supports it (scores {scores})'
        return sol, Findings(log=(said,), candidates=tuple(scored))
    return None, Findings(
        log=(StagesDisagree(what, scored=tuple(scored)),), candidates=tuple(scored)
    )


def fold_batch(
    eye: Trajectory, model: EyeModel, batch: BatchSolution, cfg: CalibrationConfig
) -> tuple[Trajectory, EyeModel]:
    """The batch stage's drift and (with estimate_scale) scale corrections into the eye and
    the model; a metric eye's nuisance scale stays out of it."""
    if batch.clock_drift is not None and batch.drift_std is not None:
        eye, model = model.add_drift(eye, batch.clock_drift, batch.drift_std * (1.0 - model.drift))
    if cfg.estimate_scale and batch.scale is not None and batch.scale_std is not None:
        eye, model = model.add_scale(eye, batch.scale, batch.scale_std * model.scale * batch.scale)
    return eye, model


def with_correlated(
    hand: Trajectory, eye: Trajectory, batch: BatchSolution, cfg: CalibrationConfig
) -> BatchSolution:
    """The batch solution with the terms of :mod:`.correlated` in its covariance, from refits on
    ``eye`` (its drift, and with estimate_scale its scale, folded in; a metric eye's nuisance
    scale held at the solution's), and that nuisance scale marginalised out.
    A term that cannot be estimated is left out and said in :attr:`Uncertainty.not_estimated`."""
    lr, white = batch.covariance, batch.covariance_white
    scaled = batch.scale is not None
    factors, moving, missing = _blocks(hand, eye, batch, cfg)
    cov = inflated(lr, factors or {})
    at = 7 + (batch.clock_drift is not None)
    share = scale_share(cov, at) if scaled else None
    known = white[:7, :7] - scale_share(white, at) if scaled else white[:7, :7]
    nuisance = None
    if batch.scale is not None and batch.scale_std is not None and not cfg.estimate_scale:
        nuisance = (batch.scale, batch.scale_std, scale_shift(white, at, batch.scale))
        cov, lr, white = without(cov, at), without(lr, at), without(white, at)
    elif not scaled and not cfg.estimate_scale:
        why = "the eye's scale could not be told from the lever arm (too little translation)"
        missing.append(f'{why}: the uncertainty holds for a metric eye only')
    unc = Uncertainty(
        white=known,
        long_run=lr,
        factors=factors,
        scale=nuisance,
        covariance=cov,
        not_estimated=tuple(missing),
        varies=moving,
        scale_part=share,
    )
    return replace(
        batch,
        covariance=cov,
        covariance_white=white,
        std=np.sqrt(np.clip(np.diag(cov), 0.0, None)),
        scale=batch.scale if cfg.estimate_scale else None,
        uncertainty=unc,
        spline=None,
    )


def _blocks(
    hand: Trajectory, eye: Trajectory, batch: BatchSolution, cfg: CalibrationConfig
) -> tuple[dict[str, float] | None, dict[str, tuple[float, float]], list[str]]:
    """The correlated term from the blocks refitted alone, in every cutting: the groups' factors
    (None when it could not be estimated), the groups whose quarters vary along the recording,
    and why not."""
    missing: list[str] = []
    covered = np.flatnonzero(_covered(hand, eye, batch.time_offset_s))
    quarters, *later = cuts(covered.size)
    if np.min(np.diff(quarters)) < MIN_BLOCK_POSES:
        missing.append(
            f'the errors correlated over the recording are not in it: {covered.size} covered '
            f'eye poses are too few for {BLOCKS} blocks of {MIN_BLOCK_POSES}'
        )
        return None, {}, missing
    # each block with the solution's scale held: the whole recording's T_HE errs as its one
    # scale does over each part (a VIO's scale wanders), which a block's own would hide
    held = eye if cfg.estimate_scale or batch.scale is None else eye.scaled(batch.scale)
    first = _refitted(hand, held, covered, quarters, batch, cfg)
    if first is None:
        missing.append(
            'the errors correlated over the recording are not in it: two quarters of the '
            'recording alone could not be refitted (too little motion in them)'
        )
        return None, {}, missing
    # a later cutting two of whose blocks cannot be refitted alone is left out
    others = (_refitted(hand, held, covered, edges, batch, cfg) for edges in later)
    cuttings = [first, *(blocks for blocks in others if blocks is not None)]
    return (
        error_of_mean(cuttings, batch.covariance),
        varies(first.deviations, first.covariances),
        missing,
    )


def _refitted(
    hand: Trajectory,
    eye: Trajectory,
    covered: Indices,
    edges: Indices,
    batch: BatchSolution,
    cfg: CalibrationConfig,
) -> Blocks | None:
    """The blocks of ``eye`` between ``edges`` (into ``covered``) refitted alone, or None when
    more than one could not be: a block whose refit fails determines nothing alone and counts
    as nothing, as one that hardly determines a group counts as little
    (:func:`.correlated.error_of_mean`)."""
    spans = list(itertools.pairwise(edges))
    tried = [_aux(hand, eye.select(covered[a:b]), batch, cfg) for a, b in spans]
    fits = [(f, b - a) for f, (a, b) in zip(tried, spans, strict=True) if f is not None]
    if len(fits) < len(spans) - 1:
        return None
    return Blocks(
        deviations=np.array([deviation(f, batch) for f, _ in fits]),
        covariances=np.array([f.covariance[:7, :7] for f, _ in fits]),
        shares=np.array([n for _, n in fits], dtype=float),
    )


def _covered(hand: Trajectory, eye: Trajectory, dt: float) -> Floats:
    """(N,) bool: eye poses whose instant on the hand's clock (t - dt) the hand covers."""
    t = eye.t_ns - np.int64(round(dt * 1e9))
    k = np.clip(np.searchsorted(hand.t_ns, t, side='right'), 1, len(hand) - 1)
    out: Floats = (t >= hand.t_ns[0]) & (t <= hand.t_ns[-1]) & hand.interval_ok()[k - 1]
    return out


def _decimated(eye: Trajectory) -> Trajectory:
    every = -(-len(eye) // MAX_AUX_POSES)
    return eye if every == 1 else eye.select(np.arange(0, len(eye), every))


def _aux(
    hand: Trajectory,
    eye: Trajectory,
    of: BatchSolution,
    cfg: CalibrationConfig,
) -> BatchSolution | None:
    """A refit of ``eye`` (decimated) by BLOCK_STEPS steps from the solution ``of``, on its
    spline of ``hand`` and with its noise (the default solve, as the estimate's; the noise is
    not measured again: the long-run covariance does not depend on the weights' scale), or
    None."""
    try:
        options = replace(
            batch_options(cfg),
            hand_noise=(of.hand_noise.rotation, of.hand_noise.translation),
            eye_noise=(of.eye_noise.rotation, of.eye_noise.translation),
            max_iterations=BLOCK_STEPS,
            held_axis=None if of.held_axis is None else tuple(float(v) for v in of.held_axis),
            held_rotation=of.held_rotation,
        )
        sol = refine(
            hand, _decimated(eye), of.time_offset_s, of.q_HE, of.p_HE, options, spline=of.spline
        )
    except (HandeyeError, ValueError, np.linalg.LinAlgError, RuntimeError):
        return None
    return sol if np.all(np.isfinite(sol.covariance)) else None


def batch_options(cfg: CalibrationConfig) -> BatchOptions:
    """Stage 3's options from the run's configuration (no drift, no scale: the callers add
    what the run estimates)."""
    return BatchOptions(
        knot_spacing=cfg.knot_spacing,
        order=cfg.spline_order,
        hand_noise=(cfg.hand_noise_rotation, cfg.hand_noise_translation),
        eye_noise=(cfg.eye_noise_rotation, cfg.eye_noise_translation),
        huber_delta=cfg.huber_delta,
        max_iterations=cfg.batch_max_iterations,
        fix_time_offset=cfg.time_offset is not None,
        decoupled=cfg.batch_decoupled,
    )
