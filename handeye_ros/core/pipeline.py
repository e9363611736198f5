"""The whole calibration: the one function every front end (offline tool, node) calls.

Stages: time offset (Section III-A) -> pose pairs at common instants -> relative motions from
keyframes -> robust linear AX = XB (Section III-B) -> continuous-time batch refinement with
covariance (Section III-C, kept only if it converges and lowers the cost) -> world alignment
and metrics at the final (dt, T_HE).
"""

from __future__ import annotations

import logging
import time

import numpy as np

from .association import associate
from .batch import BatchSolution, refine
from .config import CalibrationConfig
from .linear import build_motions, calibrate_linear
from .result import CalibrationResult
from .errors import HandeyeError, TimeAlignmentError
from .time_align import TimeAlignment, align_time
from .trajectory import Trajectory
from .world import align_worlds, evaluate

LOG = logging.getLogger('handeye_ros')

#: A correlation peak below this means the two angular-speed profiles hardly agree.
WEAK_PEAK_CORRELATION = 0.5
#: A second peak this close to the main one means the offset is ambiguous (periodic motion).
AMBIGUOUS_PEAK_RATIO = 0.9
#: Fewer RANSAC inliers than this fraction of the motions: noisy eye or wrong offset.
LOW_INLIER_FRACTION = 0.2


def calibrate(hand: Trajectory, eye: Trajectory,
              config: CalibrationConfig | None = None) -> CalibrationResult:
    """Time offset and extrinsic T_HE of a hand (T_GH) and an eye (T_WE) trajectory.

    Raises a :class:`~handeye_ros.core.errors.HandeyeError` subclass with a user-facing message
    when the input cannot give a result; soft problems end up in ``result.warnings``.
    """
    cfg = config or CalibrationConfig()
    warnings: list[str] = []
    t0 = time.perf_counter()
    if cfg.time_offset is not None:
        ta = TimeAlignment(time_offset_s=cfg.time_offset, method='fixed')
        warnings.extend(_check_fixed_offset(hand, eye, cfg))
    else:
        ta = align_time(hand, eye, max_time_offset=cfg.max_time_offset,
                        time_offset_guess=cfg.time_offset_guess,
                        resample_rate_hz=cfg.resample_rate_hz, peak_fit=cfg.peak_fit)
        if ta.peak_correlation < WEAK_PEAK_CORRELATION:
            warnings.append(f'weak angular-speed correlation peak ({ta.peak_correlation:.2f}): '
                            'the time offset may be wrong; check that both streams show the '
                            'same motion')
        if ta.second_peak_ratio > AMBIGUOUS_PEAK_RATIO:
            warnings.append(f'a second correlation peak reaches {ta.second_peak_ratio:.0%} of '
                            'the main one: the time offset may be ambiguous (repetitive '
                            'motion); narrow max_time_offset around the expected value')
    t1 = time.perf_counter()
    pairs = associate(hand, eye, ta.time_offset_s)
    motions = build_motions(pairs, cfg.relative_poses, np.deg2rad(cfg.eta))
    linear = calibrate_linear(
        motions, robust_kernel=cfg.robust_kernel, mu=cfg.mu,
        ransac_iterations=cfg.ransac_iterations,
        inlier_rotation_rad=np.deg2rad(cfg.inlier_rotation),
        inlier_translation_m=cfg.inlier_translation, min_motions=cfg.min_motions,
        adaptive_inliers=cfg.adaptive_inliers, decoupled_refit=cfg.decoupled_refit,
        rng=np.random.default_rng(cfg.seed))
    warnings.extend(linear.warnings)
    if linear.n_inliers < LOW_INLIER_FRACTION * linear.n_motions:
        warnings.append(f'only {linear.n_inliers} of {linear.n_motions} motions are RANSAC '
                        'inliers: the eye poses are noisier than the inlier thresholds '
                        f'({cfg.inlier_rotation} deg / {cfg.inlier_translation} m) or the time '
                        'offset is off')
    t2 = time.perf_counter()
    dt, q_HE, p_HE = ta.time_offset_s, linear.q_HE, linear.p_HE
    batch = None
    if cfg.batch:
        batch, why = _run_batch(hand, eye, dt, q_HE, p_HE, cfg)
        if batch is not None:
            dt, q_HE, p_HE = batch.time_offset_s, batch.q_HE, batch.p_HE
            warnings.extend(batch.warnings)
        else:
            warnings.append(f'batch stage not used, the linear result is kept: {why}')
    t3 = time.perf_counter()
    if dt != ta.time_offset_s:
        pairs = associate(hand, eye, dt)
    world = align_worlds(pairs, q_HE, p_HE)
    if world.method != 'positions':
        warnings.append('the positions do not span a plane; the world alignment T_WG was '
                        'taken from the orientations')
    metrics = evaluate(pairs, q_HE, p_HE, world)
    LOG.info('time alignment %.3f s, linear calibration %.3f s, batch %.3f s, %d pairs, '
             '%d motions', t1 - t0, t2 - t1, t3 - t2, pairs.t_eye_s.size, linear.n_motions)
    return CalibrationResult(
        time_offset_s=dt, q_HE=q_HE, p_HE=p_HE, world=world,
        time_alignment=ta, linear=linear, metrics=metrics, n_pairs=int(pairs.t_eye_s.size),
        hand=hand, eye=eye, config=cfg, warnings=tuple(warnings), batch=batch)


#: The batch result is distrusted when it moves dt by more than this (s) or T_HE by more than
#: these (m, deg) from the linear result: a local refinement that travels that far has
#: diverged (the linear stage is within a few ms, cm and tenths of a degree on real data).
MAX_BATCH_DT_CHANGE_S = 0.02
MAX_BATCH_TRANSLATION_CHANGE_M = 0.10
MAX_BATCH_ROTATION_CHANGE_DEG = 5.0


def _run_batch(hand: Trajectory, eye: Trajectory, dt: float, q_HE: np.ndarray,
               p_HE: np.ndarray, cfg: CalibrationConfig) -> tuple[BatchSolution | None, str]:
    """The batch refinement, or None and why it was not used (never raises)."""
    try:
        sol = refine(hand, eye, dt, q_HE, p_HE, knot_spacing=cfg.knot_spacing,
                     order=cfg.spline_order,
                     hand_noise=(cfg.hand_noise_rotation, cfg.hand_noise_translation),
                     eye_noise=(cfg.eye_noise_rotation, cfg.eye_noise_translation),
                     huber_delta=cfg.huber_delta, max_iterations=cfg.batch_max_iterations,
                     joint=cfg.batch_joint, fix_time_offset=cfg.time_offset is not None,
                     decoupled=cfg.batch_decoupled)
    except HandeyeError as err:
        return None, str(err)
    except (ValueError, np.linalg.LinAlgError, RuntimeError) as err:
        return None, f'the solver failed ({err})'
    moved_rot = float(np.degrees(2 * np.arccos(min(1.0, abs(float(np.dot(sol.q_HE, q_HE)))))))
    moved = (abs(sol.time_offset_s - dt), float(np.linalg.norm(sol.p_HE - p_HE)), moved_rot)
    if not np.all(np.isfinite(sol.covariance)):
        return None, 'the solution has no finite covariance (degenerate motion)'
    # each solve only takes steps that lower its cost; the decoupled one trades the full cost
    # for a rotation free of translation errors, so only the plain solve is held to it
    if not sol.decoupled and sol.cost_after > sol.cost_before * (1 + 1e-9):
        return None, (f'it made the cost worse ({sol.cost_before:.6g} -> '
                      f'{sol.cost_after:.6g})')
    if moved[0] > MAX_BATCH_DT_CHANGE_S or moved[1] > MAX_BATCH_TRANSLATION_CHANGE_M or \
            moved[2] > MAX_BATCH_ROTATION_CHANGE_DEG:
        return None, (f'it diverged from the linear result (moved dt by {moved[0] * 1e3:.1f} ms,'
                      f' T_HE by {moved[1] * 1e3:.0f} mm and {moved[2]:.1f} deg)')
    return sol, ''


#: A fixed offset further than this from the correlation peak is reported (s): a few grid
#: steps, well above the peak's own error (< 2 ms on the paper's protocol).
FIXED_OFFSET_DISAGREEMENT_S = 0.01


def _check_fixed_offset(hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig) -> list[str]:
    """Warn when a user-fixed offset disagrees with the angular-speed correlation.

    Why: the linear stage cannot tell a wrong offset from a noisy eye (a 50 ms error still gives
    most motions as inliers at moderate speed), so a wrong fixed value would pass silently.
    """
    try:
        est = align_time(hand, eye, max_time_offset=cfg.max_time_offset,
                         time_offset_guess=cfg.time_offset, resample_rate_hz=cfg.resample_rate_hz)
    except TimeAlignmentError as err:
        return [f'could not check the fixed time offset against the data: {err}']
    if est.peak_correlation >= WEAK_PEAK_CORRELATION and \
            abs(est.time_offset_s - cfg.time_offset) > FIXED_OFFSET_DISAGREEMENT_S:
        return [f'the fixed time offset {cfg.time_offset * 1e3:+.1f} ms disagrees with the '
                f'angular-speed correlation, which peaks at {est.time_offset_s * 1e3:+.1f} ms '
                f'(correlation {est.peak_correlation:.2f}); check the fixed value']
    return []
