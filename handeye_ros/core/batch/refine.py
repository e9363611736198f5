"""Stage 3: continuous-time batch refinement of (dt, T_HE) with uncertainty (Section III-C).

The hand trajectory is a cumulative B-spline T_GH(t) (:mod:`.batch.spline`, eq. 14); the eye is
predicted as ``T_WE(t) = T_WG T_GH(t - dt) T_HE`` (the model of Section III-C, stated with
eq. 15) and compared with the eye's relative
poses between consecutive observations (eq. 16, so T_WG drops out); the hand with each MoCap
pose. The residual blocks and their Jacobians are in :mod:`.batch.residuals`, the Huber loss and the
Levenberg-Marquardt solvers in :mod:`.batch.solver`, the covariance in :mod:`.batch.covariance`;
this module chooses what is solved, in which steps, with which noise, and says what it did.

Why the hand residuals differ from eq. 15's relative form: the MoCap measures T_GH in G
directly, so there is no unknown world frame to remove, and its noise is white per pose, which
per-pose residuals model exactly; relative ones would be correlated between neighbours and
leave a rigid motion of the whole spline free. (The VIO's error is a drift, white in its
increments: there the relative form is the right one.)

By default the spline is fitted to the hand alone and (dt, T_HE) are solved on the eye
residuals with it by a Huber Levenberg-Marquardt with the analytic Jacobian
(:meth:`.batch.residuals.BatchProblem.eye_chunk`), the eye pairs taken in chunks and their normal
equations summed (an hour of 200 Hz VIO is 720 000 pairs), in two steps: (dt, rotation of T_HE)
on the rotation residuals, then (dt, translation) on all of them
(:func:`_solve_offset_extrinsic` says why). ``joint`` solves the whole problem, control poses
included (in the same two steps unless ``decoupled`` is off), by Levenberg-Marquardt with an
analytic sparse Jacobian and a sparse direct solve; it is slower and agrees with the default
while the MoCap is much less noisy than the VIO.

The noise of each stream is estimated from its own residuals unless given.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..errors import BatchError
from ..geometry import quat_from_matrix
from ..trajectory import Trajectory
from .correlated import Uncertainty
from .covariance import eye_covariance, joint_covariance, joint_long_run
from .long_run import LongRunCovariance
from .loss import huber_cost
from .parameters import ParameterLayout, weighted_eye_chunks
from .pieces import check_hand_rate, hand_pieces
from .residuals import BatchProblem, Weights
from .solver import (
    LM_FTOL,
    LM_FTOL_FIRST_PASS,
    NormalSums,
    SolverReport,
    levenberg_marquardt_dense,
    levenberg_marquardt_sparse,
    normal_sums,
)
from .spline import PoseSpline

__all__ = ['BatchError', 'BatchSolution', 'Noise', 'SolverReport', 'refine']

#: Noise estimates never go below these (rad, m): a noise-free stream would get infinite weight.
MIN_SIGMA_ROT = 1e-6
MIN_SIGMA_TRANS = 1e-6
#: Chunks of eye pairs the first of the two noise passes uses on a long recording (spread
#: over it); the second pass and the covariance use every pair.
FIRST_PASS_CHUNKS = 4


@dataclass(frozen=True)
class Noise:
    """Standard deviations per axis (rad, m) of one stream's residuals: of each pose for the
    hand, of the relative pose between consecutive poses for the eye."""

    rotation: float
    translation: float
    estimated: bool


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
    """

    time_offset_s: float
    q_HE: np.ndarray
    p_HE: np.ndarray
    covariance: np.ndarray
    std: np.ndarray
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
    decoupled: bool = False
    warnings: tuple[str, ...] = field(default=())
    covariance_white: np.ndarray | None = None
    bandwidth: int = 0
    clock_drift: float | None = None
    time_offset_stamp_ns: int | None = None
    scale: float | None = None
    #: the covariance's parts (:mod:`.correlated`), once the stage has added them
    uncertainty: Uncertainty | None = None
    #: the hand's spline the solution was found on, for refits of the same hand (dropped once
    #: the stage is done with it: an hour at 1 kHz has 72 000 control poses)
    spline: PoseSpline | None = field(default=None, repr=False, compare=False)

    @property
    def inflation(self) -> np.ndarray:
        """(7,) long-run over white standard deviation (1: the residuals look white)."""
        lr = self.covariance if self.uncertainty is None else self.uncertainty.long_run
        w = np.sqrt(np.clip(np.diag(self.covariance_white), 1e-300, None))
        return np.sqrt(np.clip(np.diag(lr), 0.0, None)) / w


@dataclass(frozen=True)
class _Solve:
    """What one of the two solves hands back to :func:`refine`.

    x: the solution, the joint solve's full vector (control poses then y) or y alone;
    weights: the final 1/sigma of each stream; covariance: white, (n_y, n_y) in the order of
    y (zero rows for entries held fixed); long_run: the reported covariance
    (:mod:`.batch.long_run`); n_residuals, n_free: for the reduced chi^2; report: the last
    solver run's.
    """

    x: np.ndarray
    cost_before: float
    cost_after: float
    hand_noise: Noise
    eye_noise: Noise
    weights: Weights
    covariance: np.ndarray
    long_run: LongRunCovariance
    n_residuals: int
    n_free: int
    report: SolverReport


def refine(
    hand: Trajectory,
    eye: Trajectory,
    time_offset_s: float,
    q_HE: np.ndarray,
    p_HE: np.ndarray,
    *,
    knot_spacing: float = 0.05,
    order: int = 4,
    hand_noise: tuple[float | None, float | None] = (None, None),
    eye_noise: tuple[float | None, float | None] = (None, None),
    huber_delta: float = 1.345,
    max_iterations: int = 50,
    joint: bool = False,
    fix_time_offset: bool = False,
    decoupled: bool = True,
    drift_stamp_ns: int | None = None,
    scale: bool = False,
    spline: PoseSpline | None = None,
) -> BatchSolution:
    """Refine dt and T_HE from the linear result (see the module docstring).

    By default the spline is fitted to the hand and (dt, T_HE) are then solved on the eye
    residuals; ``joint`` also frees the spline's control poses (the full problem of eq. 15,
    analytic sparse Jacobian and sparse direct solve; slower, and the same answer while the
    MoCap is much less noisy than the VIO).

    ``hand_noise`` / ``eye_noise``: (rotation rad, translation m) per axis of each MoCap pose /
    of the eye's relative poses between consecutive frames; None estimates it from the data's
    own residuals.

    ``drift_stamp_ns``: also estimate a clock drift, dt(t) = dt + drift (t - drift_stamp_ns)
    with t the eye's stamps (:mod:`.time.clock`); ``scale``: also a factor on the eye's
    translations. Both are corrections to what the eye already has (0 and 1 to start), and
    only the default (not the joint) solve estimates them.

    ``spline``: the hand's spline from an earlier solve on the same hand with the same
    ``knot_spacing`` and ``order`` (:attr:`BatchSolution.spline`): the fit is not repeated.

    Raises
    ------
    BatchError
        When the input cannot support the stage (overlap too short, no gap-free part of the
        hand long enough for a spline).
    """
    t_start = time.perf_counter()
    if joint and (drift_stamp_ns is not None or scale):
        raise BatchError(
            'the joint solve (batch_joint) does not estimate a clock drift or a '
            'scale; leave batch_joint off to estimate them'
        )
    hand, pieces, piece_note = hand_pieces(hand, eye, time_offset_s, knot_spacing, order)
    check_hand_rate(hand, knot_spacing, joint)
    prob = BatchProblem(
        hand,
        eye,
        time_offset_s,
        q_HE,
        p_HE,
        knot_spacing,
        order,
        drift_stamp_ns,
        scale,
        pieces,
        spline,
    )
    layout = ParameterLayout.of(prob, fix_time_offset)
    hn = _hand_noise(prob, hand_noise, joint)
    if joint:
        solved = _solve_joint(
            prob,
            layout,
            hn,
            hand_noise,
            eye_noise,
            huber_delta,
            max_iterations,
            fix_time_offset,
            decoupled,
        )
        y = prob.unpack(solved.x)[1]
    else:
        solved = _solve_offset_extrinsic(
            prob, layout, hn, eye_noise, huber_delta, max_iterations, decoupled
        )
        y = solved.x
    return _solution(
        prob, solved, y, decoupled, drift_stamp_ns, piece_note, time.perf_counter() - t_start
    )


def _hand_noise(
    prob: BatchProblem, given: tuple[float | None, float | None], joint: bool
) -> Noise:
    """The hand's noise (rad, m): as given, else from the spline fit's own residuals (per pose,
    as in the joint cost)."""
    if given[0] is not None and given[1] is not None:  # no pass over the MoCap to measure it
        return Noise(given[0], given[1], False)
    raw = prob.hand_raw(prob.spline0) if joint else prob.hand_noise_residuals()
    return Noise(*_sigmas(raw, given, prob.M, prob.th.size))


def _solution(
    prob: BatchProblem,
    solved: _Solve,
    y: np.ndarray,
    decoupled: bool,
    drift_stamp_ns: int | None,
    piece_note: str,
    seconds: float,
) -> BatchSolution:
    """The stage's answer from a solve: dt, T_HE, their covariance in the reported order
    (dt, translation, rotation, [drift], [scale]), the noise, the solver's report."""
    sol = solved.report
    dof = max(solved.n_residuals - solved.n_free, 1)
    chi2 = 2.0 * solved.cost_after / dof
    # parameter order (dt, dtheta, dp, ...) -> reported order (dt, translation, rotation, ...)
    perm = np.array([0, 4, 5, 6, 1, 2, 3, *range(7, prob.n_y)])
    cov_white = solved.covariance[np.ix_(perm, perm)]
    cov = solved.long_run.covariance[np.ix_(perm, perm)]
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
        reduced_chi2=chi2,
        decoupled=decoupled,
        warnings=tuple(warnings),
        covariance_white=cov_white,
        bandwidth=solved.long_run.bandwidth,
        clock_drift=None if prob.i_drift is None else drift,
        time_offset_stamp_ns=drift_stamp_ns,
        scale=None if prob.i_scale is None else prob.scale(y),
        spline=prob.spline0,
    )


def _solve_offset_extrinsic(
    prob: BatchProblem,
    layout: ParameterLayout,
    hand_noise: Noise,
    eye_noise: tuple[float | None, float | None],
    delta: float,
    max_iterations: int,
    decoupled: bool,
) -> _Solve:
    """(dt, T_HE) by Huber Levenberg-Marquardt on the eye residuals, the spline fixed to the
    hand, with the analytic Jacobian of :meth:`.batch.residuals.BatchProblem.eye_chunk`
    (:func:`.batch.solver.levenberg_marquardt_dense`). Parameters y = (dt, dtheta_X, dp_X, ...)
    from the start values.

    ``decoupled``: first (dt, dtheta_X) on the rotation residuals alone, then (dt, dp_X) on
    all residuals with the rotation fixed. Why: as in the linear stage's decoupled refit, a
    VIO's relative translations carry errors that are not white (scale, drift), and in a
    joint solve they pull the extrinsic's rotation; on the real flights of bench/real_cases.py
    the joint solve left 0.25-0.80 deg of rotation error where this leaves 0.03-0.31 deg, and on
    the paper protocol it is as good for dt and better for the rotation.

    Two passes: the eye noise is estimated from the residuals at the linear result, then again
    at the first solution (the linear result's residuals include its own error).
    """
    y = np.zeros(layout.size)
    free_all = layout.all
    r_start = prob.eye_raw(y)  # kept: the cost before, at the final weights
    en = Noise(*_sigmas(r_start, eye_noise))
    passes = 2 if en.estimated else 1
    steps = [(layout.a, True), (layout.b, False)] if decoupled else [(free_all, False)]
    for k in range(passes):
        # the hand's weights are not used: the spline is held to the MoCap fit
        weights = Weights(eye_rotation=1.0 / en.rotation, eye_translation=1.0 / en.translation)
        # the first pass only has to get near enough to measure the noise again: from the
        # linear result one Gauss-Newton step does (the second pass starts within a fraction
        # of a sigma and converges in one or two)
        # (and on a long recording from every few chunks of pairs only: FIRST_PASS_CHUNKS
        # chunks spread over the recording hold some 130 000 pairs, enough for both)
        last_pass = k + 1 == passes
        iterations = max_iterations if last_pass else 1
        every = 1 if last_pass else max(1, len(prob.chunks()) // FIRST_PASS_CHUNKS)
        for free, rotation_only in steps:
            y, report, last = levenberg_marquardt_dense(
                lambda yy, f=free, ro=rotation_only, e=every, w=weights: _eye_sums(
                    prob, w, yy, f, ro, delta, e
                ),
                y,
                free,
                iterations,
            )
        if not last_pass:  # the last step's residuals (all rows) are those at y
            en = Noise(*_sigmas(last.raw, eye_noise))
    cost_before = huber_cost((r_start * weights.eye).ravel(), delta)
    del r_start
    cov, lr, cost_after, n_res = eye_covariance(prob, weights, y, layout, delta, decoupled)
    return _Solve(
        y, cost_before, cost_after, hand_noise, en, weights, cov, lr, n_res, free_all.size, report
    )


def _eye_sums(
    prob: BatchProblem,
    weights: Weights,
    y: np.ndarray,
    free: np.ndarray,
    rotation_only: bool,
    delta: float,
    every: int,
) -> NormalSums:
    """The dense solver's normal sums over the eye pairs at y (every ``every``-th chunk),
    keeping the unweighted residuals of all six rows for the next noise estimate."""
    raw: list[np.ndarray] | None = None if rotation_only else []
    sums = normal_sums(
        weighted_eye_chunks(prob, weights, y, rotation_only, raw, every), free, delta
    )
    return sums if raw is None else replace(sums, raw=np.concatenate(raw))


def _solve_joint(
    prob: BatchProblem,
    layout: ParameterLayout,
    hn: Noise,
    hand_noise: tuple[float | None, float | None],
    eye_noise: tuple[float | None, float | None],
    delta: float,
    max_iterations: int,
    fix_time_offset: bool,
    decoupled: bool,
) -> _Solve:
    """Control poses, dt and T_HE together: the whole problem of eq. 15
    (:func:`.batch.solver.levenberg_marquardt_sparse`).

    ``decoupled`` as in :func:`_solve_offset_extrinsic`, with the control poses free in both
    steps: (control poses, dt, rotation of T_HE) on the MoCap rows and the eye's rotation rows,
    then (control poses, dt, translation) on all rows. Two passes when a noise is estimated.
    """
    ns, nh = prob.n_spline, 6 * prob.th.size
    free = np.ones(prob.n, bool)
    if fix_time_offset:
        free[ns] = False
    theta, trans = np.zeros(prob.n, bool), np.zeros(prob.n, bool)
    theta[ns + 1 : ns + 4], trans[ns + 4 :] = True, True
    m = nh + 6 * prob.ei.size
    all_rows = np.ones(m, bool)
    rot_rows = all_rows.copy()
    rot_rows[nh:] = np.tile([True] * 3 + [False] * 3, prob.ei.size)
    steps = (
        [(free & ~trans, rot_rows), (free & ~theta, all_rows)] if decoupled else [(free, all_rows)]
    )
    x = np.zeros(prob.n)
    en = Noise(*_sigmas(prob.eye_raw(np.zeros(prob.n_y)), eye_noise))
    passes = 2 if (en.estimated or hn.estimated) else 1
    for k in range(passes):
        weights = Weights(
            1.0 / hn.rotation, 1.0 / hn.translation, 1.0 / en.rotation, 1.0 / en.translation
        )
        # A first pass only has to get near enough to measure the noise again: plain least
        # squares does that in 2-3 steps, where Huber's switching between its quadratic and
        # linear parts over thousands of MoCap rows takes 20-40 steps (measured on 20 s);
        # the Huber pass then starts where its active set has settled.
        last = k + 1 == passes
        for cols, rows in steps:
            x, report = levenberg_marquardt_sparse(
                lambda xx, w=weights: prob.residuals(xx, w),
                lambda xx, w=weights: prob.jacobian(xx, w),
                x,
                cols,
                rows,
                delta if last else np.inf,
                max_iterations,
                LM_FTOL if last else LM_FTOL_FIRST_PASS,
            )
        if not last:
            r_h, r_e = prob.raw(x)
            hn, en = Noise(*_sigmas(r_h, hand_noise, prob.M)), Noise(*_sigmas(r_e, eye_noise))
    f = prob.residuals(x, weights)
    cov = joint_covariance(prob, weights, x, f, free, rot_rows, theta, trans, delta, decoupled)
    lr = joint_long_run(prob, weights, x, cov, layout, delta, decoupled)
    cost_before = huber_cost(prob.residuals(np.zeros(prob.n), weights), delta)
    return _Solve(
        x,
        cost_before,
        huber_cost(f, delta),
        hn,
        en,
        weights,
        cov,
        lr,
        f.size,
        int(free.sum()),
        report,
    )


def _robust_sigma(r: np.ndarray) -> float:
    """Per-axis standard deviation from the median absolute deviation (robust to outliers)."""
    return float(1.4826 * np.median(np.abs(r - np.median(r, axis=0))))


def _sigmas(
    r: np.ndarray, given: tuple[float | None, float | None], fitted: int = 0, n: int | None = None
) -> tuple[float, float, bool]:
    """Per-axis (rotation, translation) noise of residuals r (N, 6), unless given.

    ``fitted``: parameters per axis fitted to these same residuals (the spline's M control
    poses for the hand), which shrink them by sqrt((N - fitted) / N): undone here, up to a
    factor sqrt(2). A spline with about as many control poses as MoCap poses (a sparse MoCap)
    nearly interpolates it and its residuals say little about the noise; blowing them up
    then would only turn interpolation round-off into noise. ``n``: how many residuals the fit
    had, when r is a sample of them.
    """
    n = r.shape[0] if n is None else n
    inflate = float(np.sqrt(n / max(n - fitted, n / 2.0)))
    rot = (
        given[0] if given[0] is not None else max(inflate * _robust_sigma(r[:, :3]), MIN_SIGMA_ROT)
    )
    trans = (
        given[1]
        if given[1] is not None
        else max(inflate * _robust_sigma(r[:, 3:]), MIN_SIGMA_TRANS)
    )
    return rot, trans, given[0] is None or given[1] is None
