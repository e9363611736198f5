"""Stage 3: continuous-time batch refinement of (dt, T_HE) with uncertainty (Section III-C).

The hand trajectory is a cumulative B-spline T_GH(t) (:mod:`.batch.spline`, eq. 14); the eye is
predicted as ``T_WE(t) = T_WG T_GH(t - dt) T_HE`` (the model of Section III-C, stated with
eq. 15) and compared with the eye's relative
poses between consecutive observations (eq. 16, so T_WG drops out); the hand with each MoCap
pose. The residual blocks and their Jacobians are in :mod:`.batch.residuals`, the Huber loss and the
Levenberg-Marquardt solvers in :mod:`.batch.levenberg_marquardt`, the covariance in :mod:`.batch.covariance`;
this module chooses what is solved, in which steps, with which noise, and says what it did.

Why the hand residuals differ from eq. 15's relative form: the MoCap measures T_GH in G
directly, so there is no unknown world frame to remove, and its noise is white per pose, which
per-pose residuals model exactly; relative ones would be correlated between neighbours and
leave a rigid motion of the whole spline free. (The VIO's error is a drift, white in its
increments: there the relative form is the right one.)

The spline is fitted to the hand alone and held, and (dt, T_HE) are solved on the eye
residuals with it by a Huber Levenberg-Marquardt with the analytic Jacobian
(:meth:`.batch.residuals.BatchProblem.eye_chunk`), the eye pairs taken in chunks and their normal
equations summed (an hour of 200 Hz VIO is 720 000 pairs), in two steps: (dt, rotation of T_HE)
on the rotation residuals, then (dt, translation) on all of them
(:func:`.batch.solves.solve_offset_extrinsic` says why). Freeing the control poses too (the
whole problem of eq. 15) agrees with it while the MoCap is much less noisy than the VIO, at a
far higher cost (docs/method.md).

The noise of each stream is estimated from its own residuals unless given.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial.transform import Rotation

from ..arrays import Floats
from ..errors import BatchError
from ..geometry import quat_from_matrix
from ..trajectory import Trajectory
from .correlated import Uncertainty
from .levenberg_marquardt import SolverReport
from .noise import Noise, sigmas
from .options import BatchOptions
from .parameters import ParameterLayout
from .pieces import hand_pieces
from .residuals import BatchProblem
from .solves import Solve, solve_offset_extrinsic
from .spacing import EXACT_ROTATION, WIDER, WIDER_FROM_SHARE, noisier_hand, wider_spacing
from .spline import PoseSpline, fit_pieces

#: Fewest MoCap samples a knot interval for the spline to be fitted rather than pass through
#: them (:func:`supported_spacing`).
MIN_SAMPLES_PER_KNOT = 2

__all__ = ['BatchError', 'BatchOptions', 'BatchSolution', 'Noise', 'SolverReport', 'refine']


@dataclass(frozen=True)
class BatchSolution:
    """Result of stage 3.

    time_offset_s, q_HE, p_HE: the refined dt and T_HE.
    covariance: (7, 7), order (dt [s], translation [m] x3, rotation [rad] x3); the rotation is
    the tangent of T_HE on the right, ``R_HE Exp(dtheta)`` (eye frame); then, when estimated,
    the clock drift [s/s] and the scale correction (a row and column each). It is the long-run
    covariance of :mod:`.batch.long_run`, which holds for residuals correlated in time.
    clock_drift, time_offset_stamp_ns: the drift [s/s] the stage added to the eye's clock and
    the eye stamp [ns] at which time_offset_s holds (None without a drift parameter).
    scale: the factor the stage put on the eye's translations (None without one).
    std: sqrt of its diagonal.
    covariance_white: the same under white residuals (``s^2 (J^T J)^-1``), for comparison.
    bandwidth: the long-run covariance's bandwidth, in eye poses (0: the residuals look white).
    knot_spacing: the hand spline's [s] (:func:`supported_spacing`).
    """

    time_offset_s: float
    q_HE: Floats
    p_HE: Floats
    covariance: Floats
    std: Floats
    cost_before: float
    cost_after: float
    iterations: int
    evaluations: int
    termination: str
    success: bool
    hand_noise: Noise
    eye_noise: Noise
    n_hand_residuals: int
    n_eye_residuals: int
    n_control_points: int
    seconds: float
    reduced_chi2: float
    knot_spacing: float
    covariance_white: Floats
    decoupled: bool = False
    warnings: tuple[str, ...] = field(default=())
    bandwidth: int = 0
    clock_drift: float | None = None
    time_offset_stamp_ns: int | None = None
    scale: float | None = None
    #: the unit direction (hand frame) along which T_HE's translation was held at its start
    #: (the covariance has no variance along it), None when every direction was estimated
    held_axis: Floats | None = None
    #: the rotation of T_HE about held_axis was held too (a rig turned in place)
    held_rotation: bool = False
    #: the covariance's parts (:mod:`.correlated`), once the stage has added them
    uncertainty: Uncertainty | None = None
    #: the hand's spline the solution was found on, for refits of the same hand (dropped once
    #: the stage is done with it: an hour at 1 kHz has 72 000 control poses)
    spline: PoseSpline | None = field(default=None, repr=False, compare=False)
    #: how far the MoCap's noise drawn once more moved dt or T_HE, in this solve's sigmas
    #: (the largest component, before :mod:`.correlated` adds its terms; :mod:`.spacing`):
    #: about the bias its present noise put in them. None when the MoCap is not noisy for
    #: its eye (a spline_share below WIDER_FROM_SHARE) or exact
    mocap_noise_move: float | None = None

    @property
    def drift_std(self) -> float | None:
        """The clock drift's 1-sigma [s/s] (None when not estimated): the entry after the 7 of
        (dt, T_HE) in ``std``."""
        return None if self.clock_drift is None else float(self.std[7])

    @property
    def scale_std(self) -> float | None:
        """The eye scale's 1-sigma (None when not estimated): the entry after the drift's."""
        return None if self.scale is None else float(self.std[7 + (self.clock_drift is not None)])

    @property
    def blocks_measured(self) -> bool:
        """Its covariance holds the errors correlated over the recording: the blocks' term of
        :mod:`.correlated` was measured (enough covered eye poses for its blocks)."""
        return self.uncertainty is not None and self.uncertainty.factors is not None

    @property
    def spline_share(self) -> float:
        """The hand spline's own error over the eye's noise, the larger of rotation and
        translation: the hand's noise a pose (``hand_noise``) over the square root of its poses
        a control pose, against the eye's a relative pose (``eye_noise``). The solve holds the
        spline as exact, which it is not when this is not small."""
        per = float(np.sqrt(max(self.n_hand_residuals / max(self.n_control_points, 1), 1.0)))
        h, e = self.hand_noise, self.eye_noise
        return max(h.rotation / e.rotation, h.translation / e.translation) / per

    @property
    def inflation(self) -> Floats:
        """(7,) long-run over white standard deviation (1: the residuals look white)."""
        lr = self.covariance if self.uncertainty is None else self.uncertainty.long_run
        w = np.sqrt(np.clip(np.diag(self.covariance_white), 1e-300, None))
        out: Floats = np.sqrt(np.clip(np.diag(lr), 0.0, None)) / w
        return out


def refine(
    hand: Trajectory,
    eye: Trajectory,
    time_offset_s: float,
    q_HE: Floats,
    p_HE: Floats,
    options: BatchOptions | None = None,
    spline: PoseSpline | None = None,
) -> BatchSolution:
    """Refine dt and T_HE from the linear result (see the module docstring), as ``options``
    say (default: :class:`BatchOptions`'s).

    ``spline``: the hand's spline from an earlier solve on the same hand with the same
    knot spacing and order (:attr:`BatchSolution.spline`): the fit is not repeated. Without
    it, a MoCap noisy for its eye (:attr:`BatchSolution.spline_share` of at least
    WIDER_FROM_SHARE) gets the wider spacing its eye supports and the move its noise makes
    measured (:mod:`.spacing`).

    Raises
    ------
    BatchError
        When the input cannot support the stage (overlap too short, no gap-free part of the
        hand long enough for a spline).
    """
    o = options or BatchOptions()
    if o.held_axis is not None:
        # about one axis the eye's relative rotations do not depend on T_HE's rotation about
        # it (a conjugation by a rotation about the axis of the motion itself): only the
        # translations tell it, so the rotation cannot be solved for first
        o = replace(o, decoupled=False)
    start = (time_offset_s, q_HE, p_HE)
    if spline is not None:  # the spline of an earlier solve on this hand: its spacing
        return _solved(hand, eye, start, replace(o, knot_spacing=spline.dt), spline)[0]
    asked = o.knot_spacing
    o = replace(o, knot_spacing=supported_spacing(hand, asked))
    sol, prob, solved = _solved(hand, eye, start, o)
    # a spline through the samples (a MoCap too slow for the spacing asked) leaves no
    # residual to measure the MoCap's noise by: only a wider spacing can tell it
    noisy = sol.spline_share >= WIDER_FROM_SHARE and sol.hand_noise.rotation > EXACT_ROTATION
    if not noisy and o.knot_spacing == asked:
        return sol
    return _noisy_mocap(hand, eye, start, o, asked, (sol, prob, solved))


def _noisy_mocap(
    hand: Trajectory,
    eye: Trajectory,
    start: tuple[float, Floats, Floats],
    o: BatchOptions,
    asked: float,
    first: tuple[BatchSolution, BatchProblem, Solve],
) -> BatchSolution:
    """The solve of a MoCap that may be noisy for its eye (:mod:`.spacing`), from the ``first``
    at ``o``'s spacing: at the spacing among WIDER times the one ``asked`` for that predicts
    the eye best, with the move its noise drawn once more makes (unless its rotations are exact:
    a spline through exact samples)."""
    t_start = time.perf_counter()
    sol, prob, solved = first
    fitted = MIN_SAMPLES_PER_KNOT / hand.rate_hz
    wider = [asked * f for f in WIDER if asked * f > o.knot_spacing and asked * f >= fitted]

    def problem_at(spacing: float) -> BatchProblem | None:
        try:
            return _problem(hand, eye, start, replace(o, knot_spacing=spacing))[0]
        except BatchError:
            return None

    best = wider_spacing(prob, solved.x, solved.weights, o.huber_delta, problem_at, wider)
    # the solves after the first start from its answer: a few steps from there, not the
    # linear result's many; at a wider spacing, on the spline its test fitted
    if best is not prob:
        o = replace(o, knot_spacing=best.spline0.dt)
        answer = (sol.time_offset_s, sol.q_HE, sol.p_HE)
        sol, prob, solved = _solved(hand, eye, answer, o, best.spline0)
    if sol.hand_noise.rotation <= EXACT_ROTATION:
        return sol
    noisier = fit_pieces(
        prob.th, *noisier_hand(prob, sol.hand_noise), o.knot_spacing, o.order, prob.pieces
    )
    again = _solved(hand, eye, (sol.time_offset_s, sol.q_HE, sol.p_HE), o, noisier)[0]
    seconds = first[0].seconds + time.perf_counter() - t_start
    return replace(sol, mocap_noise_move=_move(sol, again), seconds=seconds)


def _problem(
    hand: Trajectory,
    eye: Trajectory,
    start: tuple[float, Floats, Floats],
    o: BatchOptions,
    spline: PoseSpline | None = None,
) -> tuple[BatchProblem, str]:
    """The problem of the module docstring from ``start`` (dt, q_HE, p_HE) with ``o``'s
    spacing, and the note of the hand's pieces."""
    hand, pieces, piece_note = hand_pieces(hand, eye, start[0], o.knot_spacing, o.order)
    prob = BatchProblem(
        hand,
        eye,
        *start,
        o.knot_spacing,
        o.order,
        o.drift_stamp_ns,
        o.scale,
        pieces,
        spline,
        None if o.held_axis is None else np.asarray(o.held_axis, float),
        o.held_rotation,
    )
    return prob, piece_note


def _solved(
    hand: Trajectory,
    eye: Trajectory,
    start: tuple[float, Floats, Floats],
    o: BatchOptions,
    spline: PoseSpline | None = None,
) -> tuple[BatchSolution, BatchProblem, Solve]:
    """One solve with ``o``'s spacing (on ``spline`` when given): its solution, its problem
    and what the solver found."""
    t_start = time.perf_counter()
    prob, piece_note = _problem(hand, eye, start, o, spline)
    hn = _hand_noise(prob, o.hand_noise)
    held = o.held_axis is not None
    layout = ParameterLayout.of(prob, o.fix_time_offset, held, held and o.held_rotation)
    solved = solve_offset_extrinsic(prob, layout, hn, o)
    sol = _solution(prob, solved, solved.x, o, piece_note, time.perf_counter() - t_start)
    return sol, prob, solved


def deviation(fit: BatchSolution, of: BatchSolution) -> Floats:
    """(7,) ``fit``'s (dt, translation, rotation) from ``of``'s, the rotation in the tangent
    of T_HE on the right (eye frame), as the covariance's."""
    rot = (Rotation.from_quat(of.q_HE).inv() * Rotation.from_quat(fit.q_HE)).as_rotvec()
    return np.concatenate(([fit.time_offset_s - of.time_offset_s], fit.p_HE - of.p_HE, rot))


def _move(sol: BatchSolution, again: BatchSolution) -> float:
    """The largest move of dt, T_HE's translation and its rotation (per axis) from ``sol`` to
    ``again`` (:func:`deviation`), in ``sol``'s sigmas (axes held, with no sigma, left out)."""
    d, std = deviation(again, sol), sol.std[:7]
    return float(np.max(np.abs(d[std > 0]) / std[std > 0], initial=0.0))


def supported_spacing(hand: Trajectory, spacing: float) -> float:
    """The knot spacing the hand's samples support [s]: ``spacing``, or the MoCap's median
    sample period where it gives fewer than MIN_SAMPLES_PER_KNOT samples a knot interval. A
    least-squares fit with about as many control poses as samples is not determined where one
    is missing; at the sample period the spline passes through them (bench/results/accuracy.md,
    "The MoCap's own noise")."""
    period = 1.0 / hand.rate_hz
    return spacing if spacing >= MIN_SAMPLES_PER_KNOT * period else period


def _hand_noise(prob: BatchProblem, given: tuple[float | None, float | None]) -> Noise:
    """The hand's noise (rad, m): as given, else from the spline fit's own residuals (per
    pose)."""
    if given[0] is not None and given[1] is not None:  # no pass over the MoCap to measure it
        return Noise(given[0], given[1], False)
    raw = prob.hand_noise_residuals()
    return Noise(*sigmas(raw, given, prob.M, prob.th.size))


def _solution(
    prob: BatchProblem,
    solved: Solve,
    y: Floats,
    o: BatchOptions,
    piece_note: str,
    seconds: float,
) -> BatchSolution:
    """The stage's answer from a solve (as ``o`` asked; y at its solution): dt, T_HE, their
    covariance in the reported order (dt, translation, rotation, [drift], [scale]), the
    noise, the solver's report, the note of the hand's pieces and the time it took [s]."""
    sol = solved.report
    dof = max(solved.n_residuals - solved.n_free, 1)
    chi2 = 2.0 * solved.cost_after / dof
    # parameter order (dt, dtheta, dp in the translation basis, ...) -> reported order (dt,
    # translation in the hand frame, rotation in the eye frame, ...): T C T^T with T the bases
    perm = np.array([0, 4, 5, 6, 1, 2, 3, *range(7, prob.n_y)])
    T = np.eye(prob.n_y)
    T[1:4, 1:4], T[4:7, 4:7] = prob.translation_basis, prob.rotation_basis
    cov_white = T @ solved.covariance[np.ix_(perm, perm)] @ T.T
    cov = T @ solved.long_run.covariance[np.ix_(perm, perm)] @ T.T
    (dt, drift), X = prob.clock(y), prob.extrinsic(y)
    warnings = [piece_note] if piece_note else []
    if not sol.success:
        warnings.append(f'batch solver stopped without converging: {sol.message}')
    return BatchSolution(
        time_offset_s=float(dt),
        q_HE=quat_from_matrix(X[0]),
        p_HE=X[1],
        covariance=cov,
        std=np.sqrt(np.clip(np.diag(cov), 0.0, None)),
        cost_before=solved.cost_before,
        cost_after=solved.cost_after,
        iterations=sol.iterations,
        evaluations=int(sol.nfev),
        termination=str(sol.message),
        success=bool(sol.success),
        hand_noise=solved.hand_noise,
        eye_noise=solved.eye_noise,
        n_hand_residuals=int(prob.th.size),
        n_eye_residuals=int(prob.ei.size),
        n_control_points=prob.M,
        seconds=seconds,
        knot_spacing=o.knot_spacing,
        reduced_chi2=chi2,
        decoupled=o.decoupled,
        warnings=tuple(warnings),
        covariance_white=cov_white,
        bandwidth=solved.long_run.bandwidth,
        clock_drift=None if prob.i_drift is None else drift,
        time_offset_stamp_ns=o.drift_stamp_ns,
        scale=None if prob.i_scale is None else prob.scale(y),
        held_axis=None if o.held_axis is None else np.asarray(o.held_axis, float),
        held_rotation=o.held_axis is not None and o.held_rotation,
        spline=prob.spline0,
    )
