"""Stage 3 as the pipeline runs it (:class:`Refined`): the batch refinement from stage 2's
answer (:mod:`.refine`), kept when it converged with a finite covariance and the self-check does
not side against it; otherwise stage 2's answer is kept and the warnings say why. A drift or
scale it estimated is folded into the eye."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..checks.selfcheck import score_candidates
from ..checks.verdict import Code, batch_moved, batch_supported
from ..config import CalibrationConfig
from ..errors import HandeyeError
from ..eye_model import EyeModel
from ..findings import Findings
from ..geometry import quat_angle
from ..linear.robust import LinearSolution
from ..linear.stage import LinearStage, solve_linear
from ..trajectory import Trajectory
from .refine import BatchSolution, refine


@dataclass(frozen=True)
class Refined:
    """The answer after stage 3: dt [s] (the offset left on ``eye``), T_HE as (q_HE, p_HE),
    the batch solution (None: stage 2's answer was kept), and the eye and its model with the
    batch stage's drift and scale folded in."""

    dt: float
    q_HE: np.ndarray
    p_HE: np.ndarray
    batch: BatchSolution | None
    eye: Trajectory
    model: EyeModel


def batch_stage(
    hand: Trajectory, linear: LinearStage, cfg: CalibrationConfig, run: Findings
) -> Refined:
    """Stage 3 (see the module docstring)."""
    lin, dt, eye, model = linear.solution, linear.dt, linear.eye, linear.model
    q_HE, p_HE = lin.q_HE, lin.p_HE
    batch = None
    if cfg.batch and lin.unobservable:
        run.warnings.append('batch stage not used: part of the extrinsic is unobservable')
    elif cfg.batch:
        batch, why = run_batch(hand, eye, dt, q_HE, p_HE, cfg, model)
        if batch is not None:
            batch = check_batch(hand, eye, dt, lin, batch, cfg, run)
        if batch is not None:
            dt, q_HE, p_HE = batch.time_offset_s, batch.q_HE, batch.p_HE
            run.warnings.extend(batch.warnings)
            eye, model = fold_batch(eye, model, batch)
        else:
            why = why or 'the self-check sided with the linear result'
            run.warnings.append(f'batch stage not used, the linear result is kept: {why}')
    return Refined(dt, q_HE, p_HE, batch, eye, model)


def run_batch(
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


def check_batch(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    lin: LinearSolution,
    sol: BatchSolution,
    cfg: CalibrationConfig,
    run: Findings,
) -> BatchSolution | None:
    """When the batch stage moves dt or T_HE beyond its own sigmas, let the self-check decide
    between it and the linear result. Returns the batch solution, or None when rejected."""
    moved_dt = abs(sol.time_offset_s - dt)
    moved_t = float(np.linalg.norm(sol.p_HE - lin.p_HE))
    moved_r = float(np.degrees(quat_angle(sol.q_HE, lin.q_HE)))
    far_dt, far_x = batch_moved(moved_dt, moved_t, moved_r, sol.std)
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
            lin_b, _ = solve_linear(hand, eye, sol.time_offset_s, cfg)
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
    if batch_supported(score, far_dt):
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


def fold_batch(
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
