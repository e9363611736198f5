"""The whole calibration: the one function every front end (offline tool, node) calls.

:func:`calibrate` reads as the method. Each step (:mod:`.stages`) returns a frozen record the
next one reads, with what it found (its warnings, notes and facts: a
:class:`.checks.verdict.Findings`); the verdict reads their sum once, at the end:

1. **Inputs** (:func:`.stages.prepare.prepare`): explicit inversions, stamp units read against the
   streams' rates, clock epochs named, a keyframe-only eye recognised, each stream screened
   (damaged rows, placeholders, marker swaps, glitches).
2. **Stage 1** (Section III-A, :func:`.stages.time.align_stage`): the angular-speed correlation
   over every lag (or a window), quadratic peak; the keyframe search for a keyframe-only eye;
   then the orientation conventions at that offset (the correlation is blind to a swapped
   quaternion order or inverted poses; AX = XB is not).
3. **Stage 2** (Section III-B, :func:`.stages.linear.linear_stage`) on the eye moved onto the
   hand's clock, with what attaches to it: the eye's breaks (VIO resets), the self-check over
   the candidate offsets, the offset along the recording (drift), the scale.
4. **Stage 3** (Section III-C, :func:`.stages.batch.batch_stage`) from stage 2's answer, with a
   covariance that holds for residuals correlated in time; the self-check decides when it moves
   the answer beyond its own sigmas.
5. **The result** (:func:`_finish`): the world alignment and metrics at the final (dt, T_HE),
   the seed check, the verdict's remaining rules (:mod:`.checks.verdict`), the MoCap's coverage.

When the offset measured along the recording drifts beyond its uncertainty (the verdict's
``clock_drift``) and ``auto_drift`` is on, the stages run once more with ``clock_drift``
(:func:`_with_drift`), and a note says so. So they do when the windows' drift is not
significant but the batch stage's quarters disagree on the offset; that drift is kept when it
explains them (:func:`_with_drift_if_it_explains`).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from .arrays import Floats
from .association import PosePairs, associate
from .batch.refine import BatchSolution
from .checks.coverage import mocap_coverage
from .checks.selfcheck import motion_consistency
from .checks.verdict import (
    Code,
    Findings,
    Purpose,
    assess_answer,
    assess_model,
    assess_streams,
    drift_explains,
    drift_explains_note,
    drift_fitted_note,
    judged,
)
from .config import CalibrationConfig
from .errors import ConfigError, HandeyeError
from .result import CalibrationResult, UsedStreams
from .stages.batch import Refined, batch_stage
from .stages.linear import LinearStage, linear_stage, seed_check
from .stages.prepare import Inputs, prepare
from .stages.time import Offset, align_stage
from .trajectory import Trajectory
from .world import MIN_PLANAR_SPREAD_M, Metrics, WorldAlignment, align_worlds, metrics_of

LOG = logging.getLogger(__name__)

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
    result = _calibrate(hand, eye, cfg, progress)
    if cfg.auto_drift and not cfg.clock_drift:
        if Code.CLOCK_DRIFT in result.quality.codes:
            return _with_drift(hand, eye, cfg, result)
        varied = _varies(result.batch)
        if 'time_offset' in varied:
            return _with_drift_if_it_explains(hand, eye, cfg, result, varied['time_offset'][0])
    return result


def _with_drift(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig, measured: CalibrationResult
) -> CalibrationResult:
    """The calibration again with the clock drift the first one measured along the recording
    (``measured``: its CLOCK_DRIFT reason), said in a note; ``measured`` itself when the drift
    cannot be fitted."""
    try:
        result = _calibrate(hand, eye, replace(cfg, clock_drift=True), None)
    except HandeyeError:
        return measured
    if result.clock_drift is None or measured.clock is None:
        return measured
    note = drift_fitted_note(measured.clock, result.clock_drift)
    quality = replace(result.quality, notes=(note, *result.quality.notes))
    return replace(result, quality=quality)


def _with_drift_if_it_explains(
    hand: Trajectory,
    eye: Trajectory,
    cfg: CalibrationConfig,
    varied: CalibrationResult,
    spread_s: float,
) -> CalibrationResult:
    """The calibration again with a clock drift, when the first one's time offset varied along
    the recording (``varied``, its quarters ``spread_s`` apart) though its windows' drift was
    not significant (two windows of MoCap, far apart); kept when the drift explains the
    variation (:func:`drift_explains`), said in a note; ``varied`` itself otherwise."""
    try:
        result = _calibrate(hand, eye, replace(cfg, clock_drift=True), None)
    except HandeyeError:
        return varied
    model, batch = result.eye_model, result.batch
    if result.clock_drift is None or model is None or batch is None:
        return varied
    still = 'time_offset' in _varies(batch)
    if not drift_explains(model.drift, model.drift_std, still):
        return varied
    note = drift_explains_note(spread_s, model.drift)
    return replace(result, quality=replace(result.quality, notes=(note, *result.quality.notes)))


def _varies(batch: BatchSolution | None) -> dict[str, tuple[float, float]]:
    """The groups whose quarters disagree beyond their noise (``Uncertainty.varies``)."""
    return {} if batch is None or batch.uncertainty is None else batch.uncertainty.varies


def _calibrate(
    hand: Trajectory,
    eye: Trajectory,
    cfg: CalibrationConfig,
    progress: Callable[[str], None] | None,
) -> CalibrationResult:
    """The stages once, with the options as given (:func:`calibrate`)."""
    step = progress or (lambda name: None)
    clock = [time.perf_counter()]

    step(STEPS[0])
    inputs = prepare(hand, eye, cfg)
    step(STEPS[1])
    offset = align_stage(inputs, cfg)
    clock.append(time.perf_counter())
    step(STEPS[2])
    linear = linear_stage(inputs, offset, cfg)
    clock.append(time.perf_counter())
    step(STEPS[3])
    refined = batch_stage(offset.hand, linear, cfg)
    clock.append(time.perf_counter())
    step(STEPS[4])
    result = _finish(inputs, offset, linear, refined, cfg)

    LOG.info(
        'stage 1 + conventions %.3f s, stage 2 + checks %.3f s, batch %.3f s, %d pairs, '
        '%d motions',
        *np.diff(clock),
        result.n_pairs,
        linear.solution.n_motions,
    )
    return result


def _world_warning(world: WorldAlignment) -> Findings:
    """A warning when the positions were too small to fix the world alignment's rotation."""
    if world.method == 'positions':
        return Findings()
    return Findings.warned(
        f'the positions span less than {2 * MIN_PLANAR_SPREAD_M * 100:.0f} cm in a plane; the '
        "world alignment T_WG's rotation comes from the orientations, alone or with them"
    )


def _finish(
    inputs: Inputs,
    offset: Offset,
    linear: LinearStage,
    refined: Refined,
    cfg: CalibrationConfig,
) -> CalibrationResult:
    """World alignment and metrics at the final (dt, T_HE), the seed check, the verdict's
    remaining rules, the MoCap's coverage, and the result."""
    hand, eye, dt = offset.hand, refined.eye, refined.dt
    q_HE, p_HE, shift_ns = refined.q_HE, refined.p_HE, offset.shift_ns
    pairs = associate(hand, eye, dt)
    world = align_worlds(pairs, q_HE, p_HE)
    metrics = metrics_at(hand, eye, pairs, world, (dt, q_HE, p_HE), cfg.eta)
    seed_lin, seeded = seed_check(hand, linear.eye, linear.dt, linear.solution, refined.batch, cfg)
    found = inputs.found + offset.found + linear.found + refined.found
    found = found + _world_warning(world) + seeded
    found = found + assess_streams(offset.alignment, linear.screening, found)
    found = found + assess_answer(linear.solution, refined.batch, metrics, cfg, found)
    covered = mocap_coverage(hand, eye, dt)
    found = found + assess_model(refined.model, linear.clock, cfg)
    found = found + Findings.of(*([covered.note()] if covered.note() else []))
    time_offset_s = shift_ns * 1e-9 + dt if cfg.time_offset is None else cfg.time_offset
    return CalibrationResult(
        time_offset_s=time_offset_s,
        q_HE=q_HE,
        p_HE=p_HE,
        world=world,
        time_alignment=offset.alignment,
        linear=linear.solution,
        metrics=metrics,
        n_pairs=int(pairs.t_eye_s.size),
        hand=inputs.given[0],
        eye=inputs.given[1],
        config=cfg,
        warnings=found.warnings,
        batch=refined.batch,
        time_offset_ns=shift_ns + round(dt * 1e9),
        screening=linear.screening,
        corrections=found.corrections,
        candidates=tuple(
            replace(c, time_offset_s=shift_ns * 1e-9 + c.time_offset_s) for c in found.candidates
        ),
        quality=judged(found, Purpose(cfg.purpose)),
        seed_check=seed_lin,
        eye_model=refined.model,
        clock=linear.clock,
        used=UsedStreams(hand, eye, refined.model.own_clock_ns(eye.t_ns, offset.eye.t_ns), dt),
        coverage=covered,
    )


def metrics_at(
    hand: Trajectory,
    eye: Trajectory,
    pairs: PosePairs,
    world: WorldAlignment,
    solved: tuple[float, Floats, Floats],
    eta_deg: float,
) -> Metrics:
    """APE/ARE of the eye at (dt, T_HE) ``solved`` with its world alignment, and AX = XB over
    the eye's keyframe motions (eq. 6, keyframes at ``eta_deg``)."""
    dt, q_HE, p_HE = solved
    m_rot, m_trans, m_len, n_mot = motion_consistency(
        hand, eye, dt, q_HE, p_HE, np.deg2rad(eta_deg)
    )
    return replace(
        metrics_of(pairs, q_HE, p_HE, world),
        motion_rotation_deg=m_rot,
        motion_translation_m=m_trans,
        motion_length_m=m_len,
        n_motions=n_mot,
    )
