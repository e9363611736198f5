"""Stage 3: continuous-time batch refinement of (dt, T_HE) with uncertainty (Section III-C).

The hand trajectory is a cumulative B-spline T_GH(t) (:mod:`.spline`); the eye is predicted as
``T_WE(t) = T_WG T_GH(t - dt) T_HE``. Residuals compare relative poses between consecutive
observations of each stream (eq. 20), so T_WG drops out::

    hand:  d(T_GH(t_h)^-1 T_GH(t_h+1),            Z_h^-1 Z_h+1)
    eye:   d(T_HE^-1 T_GH(t_e - dt)^-1 T_GH(t_e+1 - dt) T_HE,  Y_e^-1 Y_e+1)

with ``d = (Log(dR_pred dR_obs^T), dp_pred - dp_obs)`` (rotation and translation apart: the
SE(3) Log of eq. 20 differs from it only at second order), each part divided by its stream's
noise, a Huber loss, and a trust-region Levenberg-Marquardt (scipy's ``trf``, which takes the
sparse Jacobian: a dense one does not scale) over the spline's control poses, dt and T_HE.

By default the spline is fitted to the hand alone and (dt, T_HE) are solved on the eye
residuals with it, in two steps: (dt, rotation of T_HE) on the rotation residuals, then
(dt, translation) on all of them (:func:`_solve_offset_extrinsic` says why). ``joint`` frees
the control poses as well (the whole problem above, sparse Jacobian); it is far slower.

Relative residuals leave the spline's absolute pose free (a rigid motion of the whole spline
changes no residual); a weak prior on the first control pose fixes that gauge. The noise of
each stream is estimated from its own residuals unless given. The covariance of (dt, T_HE) is
``s^2 (J^T J)^-1`` at the solution; for the two-step solve it is that of the two-step estimate
(:func:`_two_step_covariance`), for the joint one the 7x7 block by a Schur complement over the
spline.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import coo_matrix, csc_matrix
from scipy.sparse.linalg import splu
from scipy.spatial.transform import Rotation

from .errors import BatchError
from .geometry import Pose, compose, log_so3, matrix_from_quat, quat_from_matrix, relative
from .spline import PoseSpline, fit_spline
from .time_align import GAP_FACTOR
from .trajectory import Trajectory
#: Noise estimates never go below these (rad, m): a noise-free stream would get infinite weight.
MIN_SIGMA_ROT = 1e-6
MIN_SIGMA_TRANS = 1e-6
#: Weak prior (rad, m) on the first control pose, fixing the gauge of relative residuals.
GAUGE_SIGMA = 1.0
#: dt may move this far (s) from its start during the solve (sets the Jacobian pattern).
DT_MARGIN_S = 0.05
#: Fewest eye residuals the stage accepts.
MIN_EYE_RESIDUALS = 20


@dataclass(frozen=True)
class Noise:
    """Standard deviations of one stream's relative-pose residuals per axis (rad, m)."""

    rotation: float
    translation: float
    estimated: bool


@dataclass(frozen=True)
class BatchSolution:
    """Result of stage 3.

    time_offset_s, q_HE, p_HE: the refined dt and T_HE.
    covariance: (7, 7), order (dt [s], translation [m] x3, rotation [rad] x3); the rotation is
    the tangent of T_HE on the right, ``R_HE Exp(dtheta)`` (eye frame).
    std: sqrt of its diagonal.
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


def _pairs(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Consecutive sample indices not spanning a gap (GAP_FACTOR median periods, as stage 1)."""
    step = np.diff(t)
    ok = step <= GAP_FACTOR * np.median(step)
    i = np.flatnonzero(ok)
    return i, i + 1


def _residual_parts(pred: Pose, obs: Pose) -> np.ndarray:
    """(N, 6): rotation (rad) and translation (m) differences of relative poses."""
    dR = np.matmul(pred[0], np.swapaxes(obs[0], -1, -2))
    return np.concatenate((log_so3(dR), pred[1] - obs[1]), axis=1)


def _robust_sigma(r: np.ndarray) -> float:
    """Per-axis standard deviation from the median absolute deviation (robust to outliers)."""
    return float(1.4826 * np.median(np.abs(r - np.median(r, axis=0))))


class _Problem:
    """The least-squares problem of the module docstring, with its Jacobian pattern."""

    def __init__(self, hand: Trajectory, eye: Trajectory, dt0: float, q0: np.ndarray,
                 p0: np.ndarray, knot_spacing: float, order: int):
        self.origin = int(hand.t_ns[0])
        self.th = hand.seconds(self.origin)
        te = eye.seconds(self.origin)
        Rh, ph = matrix_from_quat(hand.q_xyzw), hand.p_xyz
        Re, pe = matrix_from_quat(eye.q_xyzw), eye.p_xyz
        self.spline0 = fit_spline(self.th, Rh, ph, knot_spacing, order)
        self.M = self.spline0.R.shape[0]
        self.hi, self.hj = _pairs(self.th)
        self.hand_obs = relative((Rh, ph), self.hi, self.hj)
        # eye pairs whose both ends stay inside the spline for any dt within the margin
        ei, ej = _pairs(te)
        lo, hi = self.spline0.t0 + DT_MARGIN_S, self.spline0.t_end - DT_MARGIN_S
        inside = (te[ei] - dt0 >= lo) & (te[ej] - dt0 <= hi)
        self.ei, self.ej = ei[inside], ej[inside]
        if self.ei.size < MIN_EYE_RESIDUALS:
            raise BatchError(f'only {self.ei.size} consecutive eye pose pairs fall inside the '
                             f'hand spline (need {MIN_EYE_RESIDUALS}): the streams overlap too '
                             'little for the batch stage')
        self.te = te
        self.eye_obs = relative((Re, pe), self.ei, self.ej)
        self.dt0, self.RX0, self.pX0 = dt0, matrix_from_quat(q0), np.asarray(p0, float)
        self.n_spline = 6 * self.M
        self.n = self.n_spline + 7
        self.w = np.ones(4)  # 1/sigma: hand rot, hand trans, eye rot, eye trans

    def offset_extrinsic(self, y: np.ndarray) -> tuple[float, Pose]:
        """(dt, T_HE) of the updates y = (ddt, dtheta_X, dp_X) to the start values."""
        return (self.dt0 + y[0],
                (self.RX0 @ Rotation.from_rotvec(y[1:4]).as_matrix(), self.pX0 + y[4:7]))

    # parameters: per control point (dphi, dp); then dt, dtheta_X, dp_X
    def unpack(self, x: np.ndarray) -> tuple[PoseSpline, float, Pose]:
        c = x[:self.n_spline].reshape(self.M, 6)
        s0 = self.spline0
        R = np.matmul(s0.R, Rotation.from_rotvec(c[:, :3]).as_matrix())
        spline = PoseSpline(s0.t0, s0.dt, s0.order, R, s0.p + c[:, 3:])
        return (spline, *self.offset_extrinsic(x[self.n_spline:]))

    def hand_raw(self, spline: PoseSpline) -> np.ndarray:
        """Unweighted hand residuals (Nh, 6) against a spline."""
        return _residual_parts(relative(spline.evaluate(self.th), self.hi, self.hj),
                               self.hand_obs)

    def eye_raw_at(self, spline: PoseSpline, dt: float, X: Pose) -> np.ndarray:
        """Unweighted eye residuals (Ne, 6): the eye predicted from the spline, dt and X."""
        pred = compose(spline.evaluate(self.te - dt), X)
        return _residual_parts(relative(pred, self.ei, self.ej), self.eye_obs)

    def raw(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unweighted hand (Nh, 6) and eye (Ne, 6) residuals and the gauge prior (6,)."""
        spline, dt, X = self.unpack(x)
        return self.hand_raw(spline), self.eye_raw_at(spline, dt, X), x[:6] / GAUGE_SIGMA

    def eye_raw(self, y: np.ndarray) -> np.ndarray:
        """Unweighted eye residuals (Ne, 6) for (dt, dtheta_X, dp_X) with the spline fixed."""
        return self.eye_raw_at(self.spline0, *self.offset_extrinsic(y))

    def residuals(self, x: np.ndarray) -> np.ndarray:
        r_h, r_e, gauge = self.raw(x)
        w = self.w
        return np.concatenate(((r_h * np.repeat(w[:2], 3)).ravel(),
                               (r_e * np.repeat(w[2:], 3)).ravel(), gauge))

    def sparsity(self) -> csc_matrix:
        """Which parameters each residual row depends on."""
        k = self.spline0.order
        rows, cols = [], []

        def spline_block(row0: np.ndarray, seg_a: np.ndarray, seg_b: np.ndarray) -> None:
            first = np.minimum(seg_a, seg_b)
            last = np.minimum(np.maximum(seg_a, seg_b) + k - 1, self.M - 1)
            width = int((last - first).max()) + 1
            cp = first[:, None] + np.arange(width)
            cp_ok = cp <= last[:, None]
            for a in range(6):  # residual component
                r = (row0 + a)[:, None].repeat(width, axis=1)[cp_ok]
                c = cp[cp_ok]
                for b in range(6):  # control point component
                    rows.append(r)
                    cols.append(6 * c + b)

        seg_h = self.spline0.segments(self.th)[0]
        spline_block(6 * np.arange(self.hi.size), seg_h[self.hi], seg_h[self.hj])
        base = 6 * self.hi.size
        lo_a = self.spline0.segments(self.te[self.ei] - self.dt0 - DT_MARGIN_S)[0]
        hi_b = self.spline0.segments(self.te[self.ej] - self.dt0 + DT_MARGIN_S)[0]
        spline_block(base + 6 * np.arange(self.ei.size), lo_a, hi_b)
        eye_rows = base + np.arange(6 * self.ei.size)
        for c in range(7):
            rows.append(eye_rows)
            cols.append(np.full(eye_rows.size, self.n_spline + c))
        g0 = base + 6 * self.ei.size
        rows.append(g0 + np.arange(6))
        cols.append(np.arange(6))
        r, c = np.concatenate(rows), np.concatenate(cols)
        m = g0 + 6
        return csc_matrix(coo_matrix((np.ones(r.size), (r, c)), shape=(m, self.n)))


def refine(hand: Trajectory, eye: Trajectory, time_offset_s: float, q_HE: np.ndarray,
           p_HE: np.ndarray, *, knot_spacing: float = 0.05, order: int = 4,
           hand_noise: tuple[float | None, float | None] = (None, None),
           eye_noise: tuple[float | None, float | None] = (None, None),
           huber_delta: float = 1.345, max_iterations: int = 50,
           joint: bool = False, fix_time_offset: bool = False,
           decoupled: bool = True) -> BatchSolution:
    """Refine dt and T_HE from the linear result (see the module docstring).

    By default the spline is fitted to the hand and (dt, T_HE) are then solved on the eye
    residuals; ``joint`` also frees the spline's control poses (the full problem of eq. 19,
    with a sparse Jacobian; far slower, and the same answer while the MoCap is much less noisy
    than the VIO).

    ``hand_noise`` / ``eye_noise``: (rotation rad, translation m) per axis of the relative-pose
    residuals; None estimates it from the data's own residuals.

    Raises
    ------
    BatchError
        When the input cannot support the stage (overlap too short, gaps in the hand stream).
    """
    t_start = time.perf_counter()
    _check_hand_gaps(hand, knot_spacing, order)
    prob = _Problem(hand, eye, time_offset_s, q_HE, p_HE, knot_spacing, order)
    # the hand's noise, from the spline fit's own residuals (relative form, as in the joint cost)
    hn = Noise(*_sigmas(prob.hand_raw(prob.spline0), hand_noise))
    huber = _huber(huber_delta)
    if joint:
        sol, cost_before, cost_after, en = _solve_joint(prob, hn, eye_noise, huber,
                                                        max_iterations)
        y = sol.x[prob.n_spline:]
        cov_raw = _marginal_covariance(sol.jac, prob.n_spline)
        n_free, n_res = sol.x.size, sol.fun.size
    else:
        y, cost_before, cost_after, en, cov, n_res, n_free, sol = _solve_offset_extrinsic(
            prob, eye_noise, huber, max_iterations, fix_time_offset, decoupled)
    dof = max(n_res - n_free, 1)
    chi2 = 2.0 * cost_after / dof
    if joint:
        cov = cov_raw * max(chi2, 1e-12)
    # parameter order (dt, dtheta, dp) -> reported order (dt, translation, rotation)
    perm = np.array([0, 4, 5, 6, 1, 2, 3])
    cov = cov[np.ix_(perm, perm)]
    dt, X = prob.offset_extrinsic(y)
    warnings = []
    if not sol.success:
        warnings.append(f'batch solver stopped without converging: {sol.message}')
    return BatchSolution(
        time_offset_s=float(dt), q_HE=quat_from_matrix(X[0]), p_HE=X[1], covariance=cov,
        std=np.sqrt(np.clip(np.diag(cov), 0.0, None)), cost_before=cost_before,
        cost_after=cost_after, iterations=int(sol.njev or 0), evaluations=int(sol.nfev),
        termination=str(sol.message), success=bool(sol.success), hand_noise=hn, eye_noise=en,
        n_hand_residuals=int(prob.hi.size), n_eye_residuals=int(prob.ei.size),
        n_control_points=prob.M, seconds=time.perf_counter() - t_start, reduced_chi2=chi2,
        decoupled=decoupled and not joint, warnings=tuple(warnings))


def _huber(delta: float):
    def cost(r: np.ndarray) -> float:
        a = np.abs(r)
        return float(np.sum(np.where(a <= delta, 0.5 * r * r, delta * (a - 0.5 * delta))))
    cost.delta = delta  # type: ignore[attr-defined]
    return cost


def _solve_offset_extrinsic(prob: _Problem, eye_noise, huber, max_iterations: int,
                            fix_time_offset: bool, decoupled: bool):
    """(dt, T_HE) by trust-region Levenberg-Marquardt on the eye residuals, the spline fixed to
    the hand. Parameters y = (dt, dtheta_X, dp_X) from the start values.

    ``decoupled``: first (dt, dtheta_X) on the rotation residuals alone, then (dt, dp_X) on
    all residuals with the rotation fixed. Why: as in the linear stage's decoupled refit, a
    VIO's relative translations carry errors that are not white (scale, drift), and in a
    joint solve they pull the extrinsic's rotation; on the real flights of bench/real_cases.py
    the joint solve left 0.25-0.80 deg of rotation error where this leaves 0.03-0.31 deg, and on
    the paper protocol it is as good for dt and better for the rotation.

    Two passes: the eye noise is estimated from the residuals at the linear result, then again
    at the first solution (the linear result's residuals include its own error).
    Returns (y, cost before, cost after, noise, 7x7 covariance in the order of y, number of
    residuals, number of free parameters, the last solver result).
    """
    y = np.zeros(7)
    dt_idx = [] if fix_time_offset else [0]
    free_all = np.array(dt_idx + [1, 2, 3, 4, 5, 6])

    def residuals(yy: np.ndarray, rotation_only: bool = False) -> np.ndarray:
        r = prob.eye_raw(yy) * np.repeat(prob.w[2:], 3)
        return (r[:, :3] if rotation_only else r).ravel()

    def solve(free: np.ndarray, rotation_only: bool):
        def fun(z: np.ndarray) -> np.ndarray:
            yy = y.copy()
            yy[free] = z
            return residuals(yy, rotation_only)
        # tolerances: 1e-10 relative is ~1e-10 s in dt and sub-micrometre in T_HE
        sol = least_squares(fun, y[free], method='trf', loss='huber', f_scale=huber.delta,
                            x_scale='jac', max_nfev=max_iterations, xtol=1e-10, ftol=1e-10,
                            gtol=1e-10)
        y[free] = sol.x
        return sol

    en = Noise(*_sigmas(prob.eye_raw(y), eye_noise))
    passes = 2 if en.estimated else 1
    sols = []
    for k in range(passes):
        prob.w[2:] = 1.0 / np.array([en.rotation, en.translation])
        if decoupled:
            sols.append(solve(np.array(dt_idx + [1, 2, 3]), True))
            sols.append(solve(np.array(dt_idx + [4, 5, 6]), False))
        else:
            sols.append(solve(free_all, False))
        if k + 1 < passes:
            en = Noise(*_sigmas(prob.eye_raw(y), eye_noise))
    cost_before = huber(residuals(np.zeros(7)))
    r0 = residuals(y)
    cost_after = huber(r0)
    dof = max(r0.size - free_all.size, 1)
    s2 = max(2.0 * cost_after / dof, 1e-12)
    cov = np.zeros((7, 7))
    if not decoupled:
        J = _jacobian(residuals, y, free_all)
        cov[np.ix_(free_all, free_all)] = s2 * np.linalg.inv(J.T @ J)
    else:
        cov[np.ix_(free_all, free_all)] = _two_step_covariance(
            residuals, y, np.array(dt_idx + [1, 2, 3]), np.array(dt_idx + [4, 5, 6]), s2)
    return y, cost_before, cost_after, en, cov, r0.size, free_all.size, sols[-1]


def _jacobian(fun, y: np.ndarray, cols: np.ndarray, rotation_only: bool = False) -> np.ndarray:
    """Central-difference Jacobian of fun(y) wrt the entries ``cols`` of y."""
    out = []
    for idx in cols:
        h = 1e-7 if idx == 0 else 1e-6
        yp, ym = y.copy(), y.copy()
        yp[idx] += h
        ym[idx] -= h
        out.append((fun(yp, rotation_only) - fun(ym, rotation_only)) / (2 * h))
    return np.stack(out, axis=1)


def _two_step_covariance(fun, y: np.ndarray, free_a: np.ndarray, free_b: np.ndarray,
                         s2: float) -> np.ndarray:
    """Covariance of the decoupled estimate, in the order (dt if free, dtheta, dp).

    Step A gives dtheta (with dt) from the rotation residuals: Sigma_A = s2 (J_A^T J_A)^-1.
    Step B gives (dt, dp) from all residuals with dtheta fixed; its own noise gives
    Sigma_B = s2 (J_B^T J_B)^-1, and dtheta's error moves it by S = -(J_B^T J_B)^-1 J_B^T J_t
    (J_t: all residuals wrt dtheta). The final dt is step B's.
    """
    theta = np.array([1, 2, 3])
    J_A = _jacobian(fun, y, free_a, rotation_only=True)
    cov_a = s2 * np.linalg.inv(J_A.T @ J_A)
    k = free_a.size - 3  # 1 when dt is free
    cov_tt = cov_a[k:, k:]
    J_B = _jacobian(fun, y, free_b)
    J_t = _jacobian(fun, y, theta)
    N_B = np.linalg.inv(J_B.T @ J_B)
    S = -N_B @ (J_B.T @ J_t)
    cov_b = s2 * N_B + S @ cov_tt @ S.T
    # assemble in the order (dt?, dtheta, dp)
    n = free_b.size + 3
    out = np.zeros((n, n))
    b_dt = list(range(k))  # dt position in B (0) if free
    pos_t = np.arange(k, k + 3)
    pos_p = np.arange(k + 3, n)
    out[np.ix_(pos_t, pos_t)] = cov_tt
    idx_b = np.array(b_dt + list(pos_p))  # where B's parameters go
    out[np.ix_(idx_b, idx_b)] = cov_b
    cross = S @ cov_tt  # Cov(B params, dtheta)
    out[np.ix_(idx_b, pos_t)] = cross
    out[np.ix_(pos_t, idx_b)] = cross.T
    return out


def _solve_joint(prob: _Problem, hn: Noise, eye_noise, huber, max_iterations: int):
    """Spline control poses, dt and T_HE together (sparse Jacobian; slower)."""
    x0 = np.zeros(prob.n)
    _, r_e, _ = prob.raw(x0)
    en = Noise(*_sigmas(r_e, eye_noise))
    prob.w = 1.0 / np.array([hn.rotation, hn.translation, en.rotation, en.translation])
    cost_before = huber(prob.residuals(x0))
    sol = least_squares(prob.residuals, x0, jac_sparsity=prob.sparsity(), method='trf',
                        loss='huber', f_scale=huber.delta, x_scale='jac', tr_solver='lsmr',
                        max_nfev=max_iterations, xtol=1e-10, ftol=1e-10, gtol=1e-10)
    return sol, cost_before, huber(sol.fun), en


def _sigmas(r: np.ndarray, given: tuple[float | None, float | None]) -> tuple[float, float,
                                                                                bool]:
    rot = given[0] if given[0] is not None else max(_robust_sigma(r[:, :3]), MIN_SIGMA_ROT)
    trans = given[1] if given[1] is not None else max(_robust_sigma(r[:, 3:]), MIN_SIGMA_TRANS)
    return rot, trans, given[0] is None or given[1] is None


def _marginal_covariance(J, n_spline: int) -> np.ndarray:
    """(J^T J)^-1 block of the last 7 parameters, by the Schur complement over the spline."""
    J = csc_matrix(J)
    Js, Jc = J[:, :n_spline], J[:, n_spline:].toarray()
    A = csc_matrix(Js.T @ Js)
    B = np.asarray(Js.T @ Jc)
    C = Jc.T @ Jc
    lu = splu(A)
    S = C - B.T @ lu.solve(B)
    return np.linalg.inv(S)


def _check_hand_gaps(hand: Trajectory, knot_spacing: float, order: int) -> None:
    step = np.diff(hand.t_ns) * 1e-9
    longest = float(step.max())
    limit = max(knot_spacing * (order - 1), GAP_FACTOR * float(np.median(step)))
    if longest > limit:
        k = int(np.argmax(step))
        raise BatchError(f'{hand.name} has a gap of {longest:.3f} s (after pose {k}): the '
                         f'spline (knots every {knot_spacing:g} s) would have control points '
                         'without MoCap data there; the batch stage needs a continuous hand '
                         'stream (or a larger knot_spacing)')
