"""Stage 3: continuous-time batch refinement of (dt, T_HE) with uncertainty (Section III-C).

The hand trajectory is a cumulative B-spline T_GH(t) (:mod:`.spline`); the eye is predicted as
``T_WE(t) = T_WG T_GH(t - dt) T_HE``. The eye residuals compare relative poses between
consecutive observations (eq. 16), so T_WG drops out; the hand residuals compare the spline
with each MoCap pose::

    hand:  d(T_GH(t_h),  Z_h)
    eye:   d(T_HE^-1 T_GH(t_e - dt)^-1 T_GH(t_e+1 - dt) T_HE,  Y_e^-1 Y_e+1)

with ``d = (Log(R_pred R_obs^T), p_pred - p_obs)`` (rotation and translation apart: the SE(3)
Log of eq. 16 differs from it only at second order), each part divided by its stream's noise,
and a Huber loss. Why the hand differs from eq. 15's relative form: the MoCap measures T_GH in
G directly, so there is no unknown world frame to remove, and its noise is white per pose,
which per-pose residuals model exactly; relative ones would be correlated between neighbours
and leave a rigid motion of the whole spline free. (The VIO's error is a drift, white in its
increments: there the relative form is the right one.)

By default the spline is fitted to the hand alone and (dt, T_HE) are solved on the eye
residuals with it by a Huber Levenberg-Marquardt with the analytic Jacobian
(:meth:`_Problem.eye_chunk`), the eye pairs taken in chunks and their normal equations summed
(an hour of 200 Hz VIO is 720 000 pairs), in two steps: (dt, rotation of T_HE) on the rotation
residuals, then (dt, translation) on all of them (:func:`_solve_offset_extrinsic` says why).
``joint`` solves the whole problem, control poses included (in the same two steps unless
``decoupled`` is off), by Levenberg-Marquardt with an analytic sparse Jacobian and a
sparse direct solve (:func:`_levenberg_marquardt` says why not scipy's solver); it is slower
and agrees with the default while the MoCap is much less noisy than the VIO.

The noise of each stream is estimated from its own residuals unless given. The covariance of
(dt, T_HE) is ``s^2 (J^T J)^-1`` at the solution; for the two-step solve it is that of the
two-step estimate (:func:`_two_step_from_normals`), for the joint one the 7x7 block by a Schur
complement over the spline, each stream's rows scaled by its own reduced chi^2.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import csc_matrix, csr_matrix, diags
from scipy.sparse.linalg import splu
from scipy.spatial.transform import Rotation

from .errors import BatchError
from .geometry import (
    Pose,
    hat,
    log_so3,
    matrix_from_quat,
    quat_from_matrix,
    relative,
    right_jacobian,
)
from .spline import PoseSpline, exp_so3, fit_spline
from .trajectory import Trajectory
from .uncertainty import (
    LongRunCovariance,
    huber_psi,
    huber_rho,
    influence,
    influence_from_sums,
    influence_sums,
    influence_two_step,
    long_run_covariance,
    two_step_from_sums,
)

#: Noise estimates never go below these (rad, m): a noise-free stream would get infinite weight.
MIN_SIGMA_ROT = 1e-6
MIN_SIGMA_TRANS = 1e-6
#: Central-difference steps in T_HE (rad, m) and dt (s) for Jacobians of the eye residuals.
FD_STEP = 1e-6
FD_STEP_S = 1e-7
#: ... and in the clock drift (s/s): 1e-9 moves an eye pose 100 s from the reference by 1e-7 s.
FD_STEP_DRIFT = 1e-9
#: dt may move this far (s) from its start during the solve: eye pairs nearer than this to
#: the spline's ends are left out, so that every eye pose keeps a spline segment.
DT_MARGIN_S = 0.05
#: MoCap poses the default solve's hand noise is measured on (:meth:`_Problem.hand_noise_residuals`).
HAND_NOISE_SAMPLES = 200_000
#: Eye pose pairs evaluated at once (:meth:`_Problem.eye_chunk`): small enough that the arrays
#: of a chunk stay in cache and memory stays flat, large enough for numpy's per-call cost.
EYE_CHUNK_PAIRS = 1 << 15
#: Chunks of eye pairs the first of the two noise passes uses on a long recording (spread
#: over it); the second pass and the covariance use every pair.
FIRST_PASS_CHUNKS = 4
#: Fewest eye residuals the stage accepts.
MIN_EYE_RESIDUALS = 20
#: Fewest MoCap poses per knot interval the joint solve accepts: with fewer, the control poses
#: outnumber what the MoCap determines and its normal matrix is singular.
MIN_HAND_POSES_PER_KNOT_JOINT = 2.0
#: Levenberg-Marquardt of the joint solve: start, floor and ceiling of the damping (relative to
#: the normal matrix's diagonal) and the relative cost change that ends it.
LM_LAMBDA0 = 1e-4
LM_LAMBDA_MIN = 1e-9
LM_LAMBDA_MAX = 1e8
LM_FTOL = 1e-10
LM_FTOL_FIRST_PASS = 1e-6


@dataclass(frozen=True)
class Noise:
    """Standard deviations per axis (rad, m) of one stream's residuals: of each pose for the
    hand, of the relative pose between consecutive poses for the eye."""

    rotation: float
    translation: float
    estimated: bool


@dataclass(frozen=True)
class SolverReport:
    """How a solve ended: success, why (message), its iterations (each one Newton model, the
    count ``batch_max_iterations`` bounds in both solvers), residual passes (nfev) and
    Jacobian evaluations (njev)."""

    success: bool
    message: str
    nfev: int
    njev: int
    iterations: int


@dataclass(frozen=True)
class BatchSolution:
    """Result of stage 3.

    time_offset_s, q_HE, p_HE: the refined dt and T_HE.
    covariance: (7, 7), order (dt [s], translation [m] x3, rotation [rad] x3); the rotation is
    the tangent of T_HE on the right, ``R_HE Exp(dtheta)`` (eye frame); then, when estimated,
    the clock drift [s/s] and the scale correction (a row and column each). It is the long-run
    covariance of :mod:`.uncertainty`, which holds for residuals correlated in time.
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

    @property
    def inflation(self) -> np.ndarray:
        """(7,) long-run over white standard deviation (1: the residuals look white)."""
        w = np.sqrt(np.clip(np.diag(self.covariance_white), 1e-300, None))
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None)) / w


def _pairs(traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """Consecutive pose indices not spanning a gap or a break (as stage 1)."""
    i = np.flatnonzero(traj.interval_ok())
    return i, i + 1


def _times(M: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``M C`` for a stack M (N, 3, 3) and a constant C (3, 3), as one matrix product."""
    return (M.reshape(-1, 3) @ C).reshape(M.shape)


def _conjugate(C: np.ndarray, M: np.ndarray, right: bool = True) -> np.ndarray:
    """``C M C^T`` (or ``C M`` with ``right`` False) for a constant C (3, 3) and a stack M
    (N, 3, 3), as plain matrix products over the stack (numpy's stacked 3x3 matmul is several
    times slower)."""
    n = M.shape[0]
    CM = (C @ np.swapaxes(M, 0, 1).reshape(3, 3 * n)).reshape(3, n, 3).swapaxes(0, 1)
    if not right:
        return CM
    return (CM.reshape(3 * n, 3) @ C.T).reshape(n, 3, 3)


def _residual_parts(pred: Pose, obs: Pose) -> np.ndarray:
    """(N, 6): rotation (rad) and translation (m) differences of predicted and observed poses
    (the spline's and the MoCap's, or relative ones of the eye)."""
    dR = np.matmul(pred[0], np.swapaxes(obs[0], -1, -2))
    return np.concatenate((log_so3(dR), pred[1] - obs[1]), axis=1)


def _robust_sigma(r: np.ndarray) -> float:
    """Per-axis standard deviation from the median absolute deviation (robust to outliers)."""
    return float(1.4826 * np.median(np.abs(r - np.median(r, axis=0))))


class _Problem:
    """The least-squares problem of the module docstring, with its Jacobian."""

    def __init__(
        self,
        hand: Trajectory,
        eye: Trajectory,
        dt0: float,
        q0: np.ndarray,
        p0: np.ndarray,
        knot_spacing: float,
        order: int,
        drift_stamp_ns: int | None = None,
        scale: bool = False,
    ):
        self.origin = int(hand.t_ns[0])
        self.th = hand.seconds(self.origin)
        te = eye.seconds(self.origin)
        # the MoCap's rotations stay quaternions: an hour at 1 kHz as matrices is 260 MB, and
        # only the joint solve needs them all (:attr:`hand_obs`)
        qh, ph = hand.q_xyzw, hand.p_xyz
        Re, pe = matrix_from_quat(eye.q_xyzw), eye.p_xyz
        self.spline0 = fit_spline(self.th, qh, ph, knot_spacing, order)
        self.M = self.spline0.R.shape[0]
        self.hand_q, self.hand_p = qh, ph
        # eye pairs whose both ends stay inside the spline for any dt within the margin
        ei, ej = _pairs(eye)
        lo, hi = self.spline0.t0 + DT_MARGIN_S, self.spline0.t_end - DT_MARGIN_S
        inside = (te[ei] - dt0 >= lo) & (te[ej] - dt0 <= hi)
        self.ei, self.ej = ei[inside], ej[inside]
        if self.ei.size < MIN_EYE_RESIDUALS:
            raise BatchError(
                f'only {self.ei.size} consecutive eye pose pairs fall inside the '
                f'hand spline (need {MIN_EYE_RESIDUALS}): the streams overlap too '
                'little for the batch stage'
            )
        self.te = te
        self.eye_obs = relative((Re, pe), self.ei, self.ej)
        self.dt0, self.RX0, self.pX0 = dt0, matrix_from_quat(q0), np.asarray(p0, float)
        self.n_spline = 6 * self.M
        self.n = self.n_spline + 7
        self.w = np.ones(4)  # 1/sigma: hand rot, hand trans, eye rot, eye trans
        # optional entries of y after (dt, dtheta_X, dp_X): the clock drift about the reference
        # stamp t_ref (eye clock) and the eye's scale correction (1 + y_s)
        self.i_drift = 7 if drift_stamp_ns is not None else None
        self.i_scale = 7 + int(drift_stamp_ns is not None) if scale else None
        self.n_y = 7 + int(drift_stamp_ns is not None) + int(scale)
        self.t_ref = (
            0.0
            if drift_stamp_ns is None
            else (np.int64(drift_stamp_ns) - np.int64(self.origin)) * 1e-9
        )

    @property
    def hand_obs(self) -> Pose:
        """The MoCap poses as (R (N, 3, 3), p (N, 3)): made once, when the joint solve asks."""
        obs = self.__dict__.get('_hand_obs')
        if obs is None:
            obs = self.__dict__['_hand_obs'] = (matrix_from_quat(self.hand_q), self.hand_p)
        return obs

    @property
    def hand_basis(self) -> tuple[np.ndarray, np.ndarray]:
        """Spline basis at every MoCap stamp (the knots never move; the times neither): made
        once, when the joint solve first asks."""
        basis = self.__dict__.get('_hand_basis')
        if basis is None:
            basis = self.__dict__['_hand_basis'] = self.spline0.basis(self.th)
        return basis

    def hand_noise_residuals(self) -> np.ndarray:
        """Hand residuals of the spline fit (n, 6) at up to HAND_NOISE_SAMPLES MoCap poses evenly
        spread: what the default solve needs of the hand is its noise level, which a robust
        sigma of 2e5 residuals gives to 0.3 %; an hour of 1 kHz MoCap would take 10 s more."""
        pick = np.unique(
            np.linspace(0, self.th.size - 1, min(self.th.size, HAND_NOISE_SAMPLES)).astype(int)
        )
        obs = (matrix_from_quat(self.hand_q[pick]), self.hand_p[pick])
        return _residual_parts(self.spline0.evaluate(self.th[pick]), obs)

    def extrinsic(self, y: np.ndarray) -> Pose:
        """T_HE of the updates y = (ddt, dtheta_X, dp_X, ...) to the start values."""
        return self.RX0 @ Rotation.from_rotvec(y[1:4]).as_matrix(), self.pX0 + y[4:7]

    def clock(self, y: np.ndarray) -> tuple[float, float]:
        """(dt at t_ref, clock drift) of y."""
        return self.dt0 + y[0], (0.0 if self.i_drift is None else float(y[self.i_drift]))

    def scale(self, y: np.ndarray) -> float:
        """The factor on the eye's translations (1 without a scale parameter)."""
        return 1.0 if self.i_scale is None else 1.0 + float(y[self.i_scale])

    def eye_times(self, y: np.ndarray, first: int = 0, stop: int | None = None) -> np.ndarray:
        """The hand-clock times of the eye stamps first..stop-1: ``t - dt - drift (t - t_ref)``
        (the linear clock of :mod:`.clock`)."""
        dt, drift = self.clock(y)
        te = self.te[first:stop]
        return te - dt - drift * (te - self.t_ref)

    # parameters: per control point (dphi, dp); then dt, dtheta_X, dp_X
    def unpack(self, x: np.ndarray) -> tuple[PoseSpline, np.ndarray]:
        """(spline, y) of the full parameter vector (joint solve)."""
        c = x[: self.n_spline].reshape(self.M, 6)
        s0 = self.spline0
        R = np.matmul(s0.R, exp_so3(c[:, :3]))
        spline = PoseSpline(s0.t0, s0.dt, s0.order, R, s0.p + c[:, 3:])
        return spline, x[self.n_spline :]

    def hand_raw(self, spline: PoseSpline) -> np.ndarray:
        """Unweighted hand residuals (Nh, 6): spline against each MoCap pose."""
        return _residual_parts(spline.evaluate(self.th, self.hand_basis), self.hand_obs)

    def eye_raw_at(self, spline: PoseSpline, y: np.ndarray) -> np.ndarray:
        """Unweighted eye residuals (Ne, 6): the eye predicted from the spline and y (the clock
        and X; with a scale s, the predicted relative translations divided by it), a chunk
        of pairs at a time (:meth:`eye_chunk`)."""
        return np.concatenate(
            [
                self.eye_chunk(
                    y, k, min(k + EYE_CHUNK_PAIRS, self.ei.size), jacobian=False, spline=spline
                )[0]
                for k in self.chunks()
            ]
        )

    def eye_chunk(
        self,
        y: np.ndarray,
        k0: int,
        k1: int,
        jacobian: bool = True,
        rotation_only: bool = False,
        spline: PoseSpline | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Unweighted eye residuals of the pairs k0..k1-1 ((n, 6), or (n, 3) rotation only)
        predicted from ``spline`` (default: the hand's fit) and y, and with ``jacobian`` their
        Jacobian (n, 6 or 3, n_y) in y, analytic (the spline held fixed). The pairs are taken a
        chunk at a time so that no array holds more than a chunk (an hour at 200 Hz is 720 000
        pairs).

        With a scale s the metric prediction is brought to the eye's units (divided by s)
        rather than the eye's noisy translations scaled: a scale on noisy observations shrinks
        towards zero by their noise-to-motion ratio (attenuation; -1 % at 1.5 mm per 25 mm
        frame step).

        With ``Q = R_a^T R_b`` of the spline at the pair's hand times, ``u = Q p_X + R_a^T (p_b -
        p_a)``, the predicted relative pose ``(R_X^T Q R_X, p = R_X^T (u - p_X))`` and r =
        ``Log(R_rel R_obs^T) = R_X^T Log(Q R_X R_obs^T R_X^T)`` (left Jacobian J_l):

        - X's rotation, ``R_X Exp(d)``: r by ``J_l^-1 (R_rel - I) d``, p by ``[p]x d``;
        - X's position: p by ``R_X^T (Q - I) dp_X``;
        - a hand time moving by dtau (dt: -1, drift: -(t - t_ref)) moves the spline by its body
          rate w and velocity v: r by ``J_l^-1 R_X^T (Q w_b dtau_b - w_a dtau_a)``, p by
          ``R_X^T ([u]x w_a dtau_a - Q [p_X]x w_b dtau_b + R_a^T (v_b dtau_b - v_a dtau_a))``;
        - the scale s: the predicted translation p / s by ``-p / s^2``.
        """
        lo, hi = int(self.ei[k0]), int(self.ej[k1 - 1]) + 1
        a, b = self.ei[k0:k1] - lo, self.ej[k0:k1] - lo
        te = self.te[lo:hi]
        times = self.eye_times(y, lo, hi)
        sp = self.spline0 if spline is None else spline
        basis = sp.basis(times)
        if jacobian:
            R, P, W, V = sp.evaluate_with_velocity(basis, sp.basis_derivative(times))
        else:
            R, P = sp.evaluate(times, basis)
        RX, pX = self.extrinsic(y)
        Ra_t = np.swapaxes(R[a], -1, -2)
        Q = np.matmul(Ra_t, R[b])
        # R_X^T Log(Q M) R_X-wise: M = R_X R_obs^T R_X^T needs only products with the constant
        # R_X, which are one matrix product over all pairs at once
        Robs_t = np.swapaxes(self.eye_obs[0][k0:k1], -1, -2)
        M = _conjugate(RX, Robs_t)
        r_rot = log_so3(np.matmul(Q, M)) @ RX  # (R_X^T v) row-wise
        n = a.size
        rows = 3 if rotation_only else 6
        r = np.empty((n, rows))
        r[:, :3] = r_rot
        s = self.scale(y)
        if not rotation_only:
            u = Q @ pX + np.einsum('nij,nj->ni', Ra_t, P[b] - P[a])
            p_rel = (u - pX) @ RX  # R_X^T (u - p_X), row-wise
            r[:, 3:] = p_rel / s - self.eye_obs[1][k0:k1]
        if not jacobian:
            return r, None
        J = np.zeros((n, rows, self.n_y))
        Jl_inv = right_jacobian(-r_rot, inverse=True)
        Jr_theta = right_jacobian(y[None, 1:4])[0]
        rel_R = _conjugate(RX.T, Q)
        J[:, :3, 1:4] = _times(np.matmul(Jl_inv, rel_R - np.eye(3)), Jr_theta)
        time_cols = [(0, -1.0, -1.0)]
        if self.i_drift is not None:
            time_cols.append(
                (self.i_drift, -(te[a] - self.t_ref)[:, None], -(te[b] - self.t_ref)[:, None])
            )
        Wa, Wb = W[a], W[b]
        QWb = np.einsum('nij,nj->ni', Q, Wb)
        for col, fa, fb in time_cols:
            J[:, :3, col] = np.einsum('nij,nj->ni', Jl_inv, (QWb * fb - Wa * fa) @ RX)
        if rotation_only:
            return r, J
        J[:, 3:, 1:4] = _times(hat(p_rel), Jr_theta / s)
        J[:, 3:, 4:7] = _conjugate(RX.T, Q - np.eye(3), right=False) / s
        if self.i_scale is not None:
            J[:, 3:, self.i_scale] = -p_rel / s**2
        dp_a = np.cross(u, Wa) - np.einsum('nij,nj->ni', Ra_t, V[a])
        dp_b = np.einsum('nij,nj->ni', Ra_t, V[b]) - np.einsum('nij,nj->ni', Q, np.cross(pX, Wb))
        for col, fa, fb in time_cols:
            J[:, 3:, col] = (dp_a * fa + dp_b * fb) @ RX / s
        return r, J

    def chunks(self) -> range:
        """Start indices of the eye pair chunks of :meth:`eye_chunk`."""
        return range(0, self.ei.size, EYE_CHUNK_PAIRS)

    def raw(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Unweighted hand (Nh, 6) and eye (Ne, 6) residuals."""
        spline, y = self.unpack(x)
        return self.hand_raw(spline), self.eye_raw_at(spline, y)

    def eye_raw(self, y: np.ndarray) -> np.ndarray:
        """Unweighted eye residuals (Ne, 6) for y = (dt, dtheta_X, dp_X, ...), the spline
        fixed to the hand."""
        return self.eye_raw_at(self.spline0, y)

    def residuals(self, x: np.ndarray) -> np.ndarray:
        r_h, r_e = self.raw(x)
        w = self.w
        return np.concatenate(
            ((r_h * np.repeat(w[:2], 3)).ravel(), (r_e * np.repeat(w[2:], 3)).ravel())
        )

    def jacobian(self, x: np.ndarray) -> csr_matrix:
        """Sparse Jacobian of :meth:`residuals`: analytic in the control poses (through
        :meth:`PoseSpline.evaluate_with_jacobian`), central differences in the 7 (dt, T_HE)
        columns, which only the eye rows depend on.

        With ``r = Log(R_pred R_obs^T)`` and R_pred moved to ``R_pred Exp(v)``, r moves by
        ``Jl^-1(r) R_pred v``. Hand row h: v is the spline's body perturbation. Eye pair (a, b)
        with ``Q = R_a^T R_b`` (spline rotations at t_a - dt, t_b - dt), ``T_HE = (R_X, p_X)``:
        the relative rotation ``R_X^T Q R_X`` has ``R_pred v = R_X^T (Q eps_b - eps_a)`` and the
        relative translation ``R_X^T (Q p_X + R_a^T (p_b - p_a) - p_X)`` moves by
        ``R_X^T ([u]x eps_a - Q [p_X]x eps_b + R_a^T (dp_b - dp_a))`` with
        ``u = Q p_X + R_a^T (p_b - p_a)``.
        """
        spline, y = self.unpack(x)
        RX, pX = self.extrinsic(y)
        k = spline.order
        w = self.w
        ent_r, ent_c, ent_v = [], [], []

        # the parameters are R_m = R0_m Exp(c_m): a change dc is Exp(Jr(c_m) dc) on R_m
        Jc = right_jacobian(x[: self.n_spline].reshape(self.M, 6)[:, :3])

        def add(row0: np.ndarray, cp: np.ndarray, col_off: int, block: np.ndarray) -> None:
            """Blocks (N, k, 3, 3): rows row0 + 0..2, columns 6 cp + col_off + 0..2."""
            if col_off == 0:
                block = np.matmul(block, Jc[cp])
            rr = row0[:, None, None, None] + np.arange(3)[:, None]
            cc = 6 * cp[:, :, None, None] + col_off + np.arange(3)
            rr, cc = np.broadcast_arrays(rr, cc)
            ent_r.append(rr.ravel())
            ent_c.append(cc.ravel())
            ent_v.append(block.ravel())

        # hand rows: rotation by the control rotations, position by the control positions
        hb = self.hand_basis
        R_s, _, JR, b = spline.evaluate_with_jacobian(hb)
        r_rot = log_so3(np.matmul(R_s, np.swapaxes(self.hand_obs[0], -1, -2)))
        cp = hb[0][:, None] + np.arange(k)
        row = 6 * np.arange(self.th.size)
        lead = np.matmul(right_jacobian(-r_rot, inverse=True), R_s)  # Jl^-1(r) R_s
        add(row, cp, 0, w[0] * np.matmul(lead[:, None], JR))
        add(row + 3, cp, 3, w[1] * b[..., None, None] * np.eye(3))
        # eye rows
        eb = self.spline0.basis(self.eye_times(y))
        R_e, p_e, JR_e, b_e = spline.evaluate_with_jacobian(eb)
        ia, ib = self.ei, self.ej
        Ra, Rb, pa, pb = R_e[ia], R_e[ib], p_e[ia], p_e[ib]
        Q = np.matmul(np.swapaxes(Ra, -1, -2), Rb)
        RXt = RX.T
        rel_R = np.matmul(np.matmul(RXt, Q), RX)
        r_eye = log_so3(np.matmul(rel_R, np.swapaxes(self.eye_obs[0], -1, -2)))
        Jl_inv = right_jacobian(-r_eye, inverse=True)
        u = np.einsum('nij,j->ni', Q, pX) + np.einsum('nji,nj->ni', Ra, pb - pa)
        RXtRat = np.matmul(RXt, np.swapaxes(Ra, -1, -2))
        row = 6 * (self.th.size + np.arange(ia.size))
        for idx, sign_rot, d_trans in (
            (ia, -1.0, np.matmul(RXt, hat(u))),
            (ib, 1.0, -np.matmul(np.matmul(RXt, Q), hat(pX))),
        ):
            cp = eb[0][idx][:, None] + np.arange(k)
            JRi = JR_e[idx]
            # d r_rot / d eps: Jl^-1 R_X^T (-I for a, Q for b)
            d_rot = np.matmul(Jl_inv, RXt if sign_rot < 0 else np.matmul(RXt, Q)) * sign_rot
            add(row, cp, 0, w[2] * np.matmul(d_rot[:, None], JRi))
            add(row + 3, cp, 0, w[3] * np.matmul(d_trans[:, None], JRi))
            add(row + 3, cp, 3, w[3] * sign_rot * b_e[idx][..., None, None] * RXtRat[:, None])
        # (dt, dtheta_X, dp_X): central differences of the eye rows
        w_eye = np.repeat(w[2:], 3)

        def eye_rows(yy: np.ndarray) -> np.ndarray:
            return (self.eye_raw_at(spline, yy) * w_eye).ravel()

        d = _jacobian(eye_rows, y, np.arange(7))
        ent_r.append(np.repeat(6 * self.th.size + np.arange(d.shape[0]), 7))
        ent_c.append(np.tile(self.n_spline + np.arange(7), d.shape[0]))
        ent_v.append(d.ravel())
        m = 6 * (self.th.size + ia.size)
        return csr_matrix(
            (np.concatenate(ent_v), (np.concatenate(ent_r), np.concatenate(ent_c))),
            shape=(m, self.n),
        )


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
    with t the eye's stamps (:mod:`.clock`); ``scale``: also a factor on the eye's
    translations. Both are corrections to what the eye already has (0 and 1 to start), and
    only the default (not the joint) solve estimates them.

    Raises
    ------
    BatchError
        When the input cannot support the stage (overlap too short, gaps in the hand stream).
    """
    t_start = time.perf_counter()
    if joint and (drift_stamp_ns is not None or scale):
        raise BatchError(
            'the joint solve (batch_joint) does not estimate a clock drift or a '
            'scale; leave batch_joint off to estimate them'
        )
    hand, piece_note = _continuous_piece(hand, eye, time_offset_s, knot_spacing, order)
    _check_hand_stream(hand, knot_spacing, order, joint)
    prob = _Problem(
        hand, eye, time_offset_s, q_HE, p_HE, knot_spacing, order, drift_stamp_ns, scale
    )
    layout = _Layout.of(prob, fix_time_offset)
    # the hand's noise, from the spline fit's own residuals (per pose, as in the joint cost)
    hn = Noise(
        *_sigmas(
            prob.hand_raw(prob.spline0) if joint else prob.hand_noise_residuals(),
            hand_noise,
            prob.M,
            prob.th.size,
        )
    )
    if joint:
        x, cost_before, cost_after, hn, en, cov, n_res, n_free, sol = _solve_joint(
            prob,
            hn,
            hand_noise,
            eye_noise,
            huber_delta,
            max_iterations,
            fix_time_offset,
            decoupled,
        )
        spline, y = prob.unpack(x)
        w_eye = np.repeat(prob.w[2:], 3)

        def eye_rows(yy: np.ndarray, rotation_only: bool = False) -> np.ndarray:
            r = prob.eye_raw_at(spline, yy) * w_eye
            return (r[:, :3] if rotation_only else r).ravel()

        # the eye's long-run correlation, added to the Schur covariance (which has the spline's
        # share): the eye rows' long-run minus their white sandwich, at the joint solution
        lr = _eye_long_run(
            eye_rows(y),
            _eye_jacobians(eye_rows, y, layout, decoupled),
            layout,
            huber_delta,
            decoupled,
        )
        extra = lr.covariance - lr.white
        lam, V = np.linalg.eigh(0.5 * (cov + extra + (cov + extra).T))
        cov_lr = (V * np.clip(lam, 0.0, None)) @ V.T
        lr = LongRunCovariance(cov_lr, cov, lr.bandwidth, lr.samples)
    else:
        y, cost_before, cost_after, en, cov, n_res, n_free, sol, lr = _solve_offset_extrinsic(
            prob, layout, eye_noise, huber_delta, max_iterations, decoupled
        )
    dof = max(n_res - n_free, 1)
    chi2 = 2.0 * cost_after / dof
    # parameter order (dt, dtheta, dp, ...) -> reported order (dt, translation, rotation, ...)
    perm = np.array([0, 4, 5, 6, 1, 2, 3, *range(7, prob.n_y)])
    cov_white = cov[np.ix_(perm, perm)]
    cov = lr.covariance[np.ix_(perm, perm)]
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
        cost_before=cost_before,
        cost_after=cost_after,
        iterations=sol.iterations,
        evaluations=int(sol.nfev),
        termination=str(sol.message),
        success=bool(sol.success),
        hand_noise=hn,
        eye_noise=en,
        n_hand_residuals=int(prob.th.size),
        n_eye_residuals=int(prob.ei.size),
        n_control_points=prob.M,
        seconds=time.perf_counter() - t_start,
        reduced_chi2=chi2,
        decoupled=decoupled,
        warnings=tuple(warnings),
        covariance_white=cov_white,
        bandwidth=lr.bandwidth,
        clock_drift=None if prob.i_drift is None else drift,
        time_offset_stamp_ns=drift_stamp_ns,
        scale=None if prob.i_scale is None else prob.scale(y),
    )


@dataclass(frozen=True)
class _Layout:
    """Which entries of y = (dt, dtheta_X (3), dp_X (3), [drift], [scale]) each step frees.

    time: dt (unless fixed) and the drift, free in both steps of the decoupled solve; scale:
    with the translation (step B). Every covariance is in the order of :attr:`all`.
    """

    time: tuple[int, ...]
    scale: tuple[int, ...]
    size: int

    @classmethod
    def of(cls, prob: _Problem, fix_time_offset: bool) -> _Layout:
        time_idx = (() if fix_time_offset else (0,)) + (
            () if prob.i_drift is None else (prob.i_drift,)
        )
        return cls(time_idx, () if prob.i_scale is None else (prob.i_scale,), prob.n_y)

    @property
    def a(self) -> np.ndarray:
        return np.array((*self.time, 1, 2, 3))

    @property
    def b(self) -> np.ndarray:
        return np.array((*self.time, 4, 5, 6, *self.scale))

    @property
    def all(self) -> np.ndarray:
        return np.array((*self.time, 1, 2, 3, 4, 5, 6, *self.scale))

    @property
    def steps(self) -> np.ndarray:
        """Central-difference steps for the entries of y."""
        h = np.full(self.size, FD_STEP)
        h[0] = FD_STEP_S
        if self.size > 7 and len(self.time) and self.time[-1] >= 7:
            h[self.time[-1]] = FD_STEP_DRIFT
        return h


def _solve_offset_extrinsic(
    prob: _Problem, layout: _Layout, eye_noise, delta: float, max_iterations: int, decoupled: bool
):
    """(dt, T_HE) by Huber Levenberg-Marquardt on the eye residuals, the spline fixed to the
    hand, with the analytic Jacobian of :meth:`_Problem.eye_chunk`
    (:func:`_levenberg_marquardt_small`). Parameters y = (dt, dtheta_X, dp_X, ...) from the
    start values.

    ``decoupled``: first (dt, dtheta_X) on the rotation residuals alone, then (dt, dp_X) on
    all residuals with the rotation fixed. Why: as in the linear stage's decoupled refit, a
    VIO's relative translations carry errors that are not white (scale, drift), and in a
    joint solve they pull the extrinsic's rotation; on the real flights of bench/real_cases.py
    the joint solve left 0.25-0.80 deg of rotation error where this leaves 0.03-0.31 deg, and on
    the paper protocol it is as good for dt and better for the rotation.

    Two passes: the eye noise is estimated from the residuals at the linear result, then again
    at the first solution (the linear result's residuals include its own error).
    Returns (y, cost before, cost after, noise, covariance in the order of y, number of
    residuals, number of free parameters, the last solver report, the long-run covariance).
    """
    y = np.zeros(layout.size)
    free_all = layout.all
    r_start = prob.eye_raw(y)  # kept: the cost before, at the final weights
    en = Noise(*_sigmas(r_start, eye_noise))
    passes = 2 if en.estimated else 1
    sols = []
    for k in range(passes):
        prob.w[2:] = 1.0 / np.array([en.rotation, en.translation])
        steps = [(layout.a, True), (layout.b, False)] if decoupled else [(free_all, False)]
        # the first pass only has to get near enough to measure the noise again: from the
        # linear result one Gauss-Newton step does (the second pass starts within a fraction
        # of a sigma and converges in one or two)
        # (and on a long recording from every few chunks of pairs only: FIRST_PASS_CHUNKS
        # chunks spread over the recording hold some 130 000 pairs, enough for both)
        last_pass = k + 1 == passes
        iterations = max_iterations if last_pass else 1
        every = 1 if last_pass else max(1, len(prob.chunks()) // FIRST_PASS_CHUNKS)
        for free, rotation_only in steps:
            y, sol, last = _levenberg_marquardt_small(
                lambda yy, f=free, ro=rotation_only, e=every: _eye_sums(prob, yy, f, ro, delta, e),
                y,
                free,
                iterations,
            )
            sols.append(sol)
        if k + 1 < passes:  # the last step's residuals (all rows) are those at y
            en = Noise(*_sigmas(last.raw, eye_noise))
    w = np.repeat(prob.w[2:], 3)
    cost_before = _huber_cost((r_start * w).ravel(), delta)
    del r_start
    cov, lr, cost_after, n_res = _eye_covariance(prob, y, layout, delta, decoupled)
    return y, cost_before, cost_after, en, cov, n_res, free_all.size, sols[-1], lr


@dataclass(frozen=True)
class _EyeSums:
    """One evaluation of the weighted eye residuals over the free columns of y, summed over
    the pairs: the Huber cost, ``A = J^T psi' J``, ``g = J^T psi`` and the column sums of J^2
    (the damping's scale)."""

    cost: float
    A: np.ndarray
    g: np.ndarray
    D: np.ndarray
    raw: np.ndarray | None = None


def _weighted_chunks(
    prob: _Problem,
    y: np.ndarray,
    rotation_only: bool = False,
    raw: list[np.ndarray] | None = None,
    every: int = 1,
):
    """(r (n, rows), J (n, rows, n_y)) of each chunk of eye pairs (of every ``every``-th
    chunk), weighted by 1/sigma; the unweighted residuals of each chunk are appended to
    ``raw`` when given."""
    rows = 3 if rotation_only else 6
    w = np.repeat(prob.w[2:], 3)[:rows]
    for k in prob.chunks()[::every]:
        r, J = prob.eye_chunk(y, k, min(k + EYE_CHUNK_PAIRS, prob.ei.size), True, rotation_only)
        if raw is not None:
            raw.append(r)
        yield r * w, J * w[None, :, None]


def _eye_sums(
    prob: _Problem,
    y: np.ndarray,
    free: np.ndarray,
    rotation_only: bool,
    delta: float,
    every: int = 1,
) -> _EyeSums:
    p = free.size
    cost, A, g, D = 0.0, np.zeros((p, p)), np.zeros(p), np.zeros(p)
    raw: list[np.ndarray] | None = None if rotation_only else []
    for r, J in _weighted_chunks(prob, y, rotation_only, raw, every):
        r = r.ravel()
        Jf = J[:, :, free].reshape(r.size, p)
        psi, dpsi = huber_psi(r, delta)
        cost += _huber_cost(r, delta)
        A += Jf.T @ (Jf * dpsi[:, None])
        g += Jf.T @ psi
        D += np.einsum('ij,ij->j', Jf, Jf)
    return _EyeSums(cost, A, g, D, None if raw is None else np.concatenate(raw))


def _eye_covariance(
    prob: _Problem, y: np.ndarray, layout: _Layout, delta: float, decoupled: bool
) -> tuple[np.ndarray, LongRunCovariance, float, int]:
    """(white covariance, long-run covariance (:mod:`.uncertainty`), Huber cost, number of
    residuals) of the default solve at y, in the order of y (zero rows for a fixed dt), from
    one pass over the eye pairs with their analytic Jacobian.

    The white covariance is ``s^2 (J^T J)^-1`` (for the two-step solve that of the two-step
    estimate, :func:`_two_step_from_normals`); the long-run one comes from the per-pair
    influences, whose sums are gathered a chunk at a time."""
    free_all = layout.all
    k = len(layout.time)
    cost, n_res = 0.0, 0
    g_parts: dict[str, list[np.ndarray]] = {'a': [], 'b': [], 'all': []}
    sums: dict[str, np.ndarray] = {}

    def add(name: str, value: np.ndarray) -> None:
        sums[name] = sums[name] + value if name in sums else value

    for r, J in _weighted_chunks(prob, y):
        cost += _huber_cost(r, delta)
        n_res += r.size
        if decoupled:
            J_a, J_b, J_t = J[:, :3][:, :, layout.a], J[:, :, layout.b], J[:, :, 1:4]
            g_a, H_a = influence_sums(r[:, :3], J_a, delta)
            g_b, H_b, C = influence_sums(r, J_b, delta, J_t)
            g_parts['a'].append(g_a)
            g_parts['b'].append(g_b)
            for name, value in (('H_a', H_a), ('H_b', H_b), ('C', C)):
                add(name, value)
            fa, fb, ft = (x.reshape(-1, x.shape[-1]) for x in (J_a, J_b, J_t))
            add('N_a', fa.T @ fa)
            add('N_b', fb.T @ fb)
            add('N_bt', fb.T @ ft)
        else:
            J_f = J[:, :, free_all]
            g, H = influence_sums(r, J_f, delta)
            g_parts['all'].append(g)
            add('H', H)
            f = J_f.reshape(-1, J_f.shape[-1])
            add('N', f.T @ f)
    s2 = max(2.0 * cost / max(n_res - free_all.size, 1), 1e-12)
    cov = np.zeros((layout.size, layout.size))
    if decoupled:
        cov[np.ix_(free_all, free_all)] = _two_step_from_normals(
            sums['N_a'], sums['N_b'], sums['N_bt'], s2, k
        )
        psi = _two_step_influences(
            *two_step_from_sums(
                np.concatenate(g_parts['a']),
                sums['H_a'],
                np.concatenate(g_parts['b']),
                sums['H_b'],
                sums['C'],
                np.arange(k, k + 3),
            ),
            k,
        )
    else:
        cov[np.ix_(free_all, free_all)] = s2 * np.linalg.inv(sums['N'])
        psi, _ = influence_from_sums(np.concatenate(g_parts['all']), sums['H'])
    return cov, _long_run_in_y(psi, layout), cost, n_res


def _two_step_influences(psi_theta: np.ndarray, psi_b: np.ndarray, k: int) -> np.ndarray:
    """The two-step estimate's influences (T, free) in the order of :attr:`_Layout.all`:
    step B's k time parameters, step A's dtheta, then step B's others."""
    return np.concatenate((psi_b[:, :k], psi_theta, psi_b[:, k:]), axis=1)


def _long_run_in_y(psi: np.ndarray, layout: _Layout) -> LongRunCovariance:
    """Long-run covariance (:mod:`.uncertainty`) of influences psi (T, free), as matrices in
    the order of y (zero rows and columns for the entries held fixed)."""
    lr = long_run_covariance(psi)
    full, white = np.zeros((layout.size,) * 2), np.zeros((layout.size,) * 2)
    idx = np.ix_(layout.all, layout.all)
    full[idx], white[idx] = lr.covariance, lr.white
    return LongRunCovariance(full, white, lr.bandwidth, lr.samples)


#: The small solve ends when a step moves no parameter by more than this fraction of its
#: standard deviation (from the Gauss-Newton normal matrix), or lowers the cost by less than
#: LM_FTOL relative. A hundredth of a sigma is far below anything the result's precision can
#: show (for dt at 0.4 ms, 4 us), and each tighter step is a pass over every eye pair.
STEP_TOL_SIGMA = 1e-2


def _levenberg_marquardt_small(
    sums_at, y: np.ndarray, free: np.ndarray, max_iterations: int
) -> tuple[np.ndarray, SolverReport, _EyeSums]:
    """Huber-robust Levenberg-Marquardt on a few parameters (``free`` entries of y) with the
    analytic Jacobian: the Newton model of :func:`_levenberg_marquardt` (rows beyond delta
    add a clipped gradient and no curvature) solved densely. ``sums_at(y) -> _EyeSums``.

    Why not scipy's least_squares: with a finite-difference Jacobian each of its iterations
    re-evaluated the spline at every eye pose once per parameter (on an hour of 200 Hz VIO,
    10 minutes of the stage), and it needs the whole Jacobian in memory. Here an iteration is
    one pass over the eye pairs with their Jacobian, summed as it goes, and the step from the
    linear result converges in 2-4 of them. Returns (y, report, the sums at y).
    """
    y = y.copy()
    cur = sums_at(y)
    lam, nu, nfev = LM_LAMBDA0, 2.0, 1
    message, success = 'maximum number of iterations reached', False
    iterations = 0
    for _ in range(max_iterations):
        iterations += 1
        sigma = np.sqrt(np.clip(np.diag(np.linalg.pinv(cur.A)), 1e-300, None))
        D = np.diag(np.maximum(cur.D, 1e-12))
        if np.all(np.abs(np.linalg.solve(cur.A, -cur.g)) <= STEP_TOL_SIGMA * sigma):
            # the Gauss-Newton step from here is below tolerance: y is the solution, and
            # the step is not worth a pass over the eye (it would change y by < 1e-2 sigma)
            message, success = "Gauss-Newton step below 1e-2 of every parameter's sigma", True
            break
        while True:
            step = np.linalg.solve(cur.A + lam * D, -cur.g)
            y_new = y.copy()
            y_new[free] += step
            new = sums_at(y_new)
            nfev += 1
            predicted = -(cur.g @ step + 0.5 * step @ (cur.A @ step))
            if new.cost <= cur.cost or lam > LM_LAMBDA_MAX:
                break
            lam *= nu
            nu *= 2.0
        if new.cost > cur.cost:
            message, success = 'no step lowers the cost any further', True
            break
        decrease = cur.cost - new.cost
        rho = decrease / predicted if predicted > 0 else 0.0
        lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), LM_LAMBDA_MIN)
        nu = 2.0
        y, cur = y_new, new
        if np.all(np.abs(step) <= STEP_TOL_SIGMA * sigma):
            message, success = "step below 1e-2 of every parameter's sigma", True
            break
        if decrease <= LM_FTOL * cur.cost:
            message, success = 'relative cost change below tolerance', True
            break
    report = SolverReport(success, message, nfev=nfev, njev=nfev, iterations=iterations)
    return y, report, cur


def _eye_jacobians(
    residuals, y: np.ndarray, layout: _Layout, decoupled: bool
) -> dict[str, np.ndarray]:
    """Central-difference Jacobians of the eye residuals at y (the joint solve's, where the
    spline moves): for the two-step solve 'a' (rotation rows; dt if free, dtheta), 'b' (all
    rows; dt if free, dp) and 'theta' (all rows; dtheta); otherwise 'all' (all rows; every
    free parameter)."""
    h = layout.steps
    if not decoupled:
        return {'all': _jacobian(residuals, y, layout.all, h)}
    return {
        'a': _jacobian(lambda yy: residuals(yy, rotation_only=True), y, layout.a, h),
        'b': _jacobian(residuals, y, layout.b, h),
        'theta': _jacobian(residuals, y, np.array([1, 2, 3]), h),
    }


def _eye_long_run(
    r: np.ndarray, jac: dict[str, np.ndarray], layout: _Layout, delta: float, decoupled: bool
) -> LongRunCovariance:
    """Long-run covariance (:mod:`.uncertainty`) of (dt, dtheta_X, dp_X, ...) from the eye
    residuals at the solution, as matrices in the order of y (zero rows for a fixed dt).

    ``r``: the weighted eye residuals, 6 rows per eye pose pair in time order; ``jac``: their
    Jacobians as :func:`_eye_jacobians` names them.
    """
    k = len(layout.time)
    if decoupled:
        psi = _two_step_influences(
            *influence_two_step(
                r.reshape(-1, 6)[:, :3].ravel(),
                jac['a'],
                r,
                jac['b'],
                jac['theta'],
                delta,
                3,
                6,
                np.arange(k, k + 3),
            ),
            k,
        )
    else:
        psi, _ = influence(r, jac['all'], delta, 6)
    return _long_run_in_y(psi, layout)


def _jacobian(fun, y: np.ndarray, cols: np.ndarray, steps: np.ndarray | None = None) -> np.ndarray:
    """Central-difference Jacobian of fun(y) wrt the entries ``cols`` of y = (dt, dtheta_X,
    dp_X, ...), with ``steps`` per entry (default: FD_STEP_S for dt, FD_STEP otherwise)."""
    out = []
    for idx in cols:
        h = steps[idx] if steps is not None else (FD_STEP_S if idx == 0 else FD_STEP)
        yp, ym = y.copy(), y.copy()
        yp[idx] += h
        ym[idx] -= h
        out.append((fun(yp) - fun(ym)) / (2 * h))
    return np.stack(out, axis=1)


def _two_step_from_normals(
    N_A: np.ndarray, N_B: np.ndarray, N_Bt: np.ndarray, s2: float, k: int
) -> np.ndarray:
    """Covariance of the decoupled estimate under white residuals, in the order (dt if free,
    dtheta, dp); k is 1 when dt is free.

    Step A gives dtheta (with dt) from the rotation residuals: Sigma_A = s2 (J_A^T J_A)^-1.
    Step B gives (dt, dp) from all residuals with dtheta fixed; its own noise gives
    Sigma_B = s2 (J_B^T J_B)^-1, and dtheta's error moves it by S = -(J_B^T J_B)^-1 J_B^T J_t
    (J_t: all residuals wrt dtheta). The final dt is step B's. N_A, N_B, N_Bt: J_A^T J_A,
    J_B^T J_B and J_B^T J_t, summed over the eye pairs.
    """
    cov_a = s2 * np.linalg.inv(N_A)
    cov_tt = cov_a[k:, k:]
    N_B_inv = np.linalg.inv(N_B)
    S = -N_B_inv @ N_Bt
    return _assemble_two_step(cov_tt, s2 * N_B_inv, S, k)


def _assemble_two_step(cov_tt: np.ndarray, cov_b: np.ndarray, S: np.ndarray, k: int) -> np.ndarray:
    """The two-step estimate's covariance in the order (time parameters, dtheta, dp, scale?).

    cov_tt: dtheta from step A; cov_b: step B's (time, dp, scale?) from its own noise; S: how
    dtheta's error moves step B's parameters; k: how many time parameters (dt, drift) are free.
    """
    cov_b = cov_b + S @ cov_tt @ S.T
    n = cov_tt.shape[0] + cov_b.shape[0]
    out = np.zeros((n, n))
    pos_t = np.arange(k, k + 3)
    idx_b = np.array(list(range(k)) + list(range(k + 3, n)))  # where B's parameters go
    out[np.ix_(pos_t, pos_t)] = cov_tt
    out[np.ix_(idx_b, idx_b)] = cov_b
    cross = S @ cov_tt  # Cov(B's parameters, dtheta)
    out[np.ix_(idx_b, pos_t)] = cross
    out[np.ix_(pos_t, idx_b)] = cross.T
    return out


def _solve_joint(
    prob: _Problem,
    hn: Noise,
    hand_noise,
    eye_noise,
    delta: float,
    max_iterations: int,
    fix_time_offset: bool,
    decoupled: bool,
):
    """Control poses, dt and T_HE together: the whole problem of eq. 15.

    ``decoupled`` as in :func:`_solve_offset_extrinsic`, with the control poses free in both
    steps: (control poses, dt, rotation of T_HE) on the MoCap rows and the eye's rotation rows,
    then (control poses, dt, translation) on all rows. Two passes when a noise is estimated.
    Returns (x, cost before, cost after, hand noise, eye noise, 7x7 covariance in the order of
    y = (dt, dtheta_X, dp_X), number of residuals, number of free parameters, solver report).
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
        prob.w = 1.0 / np.array([hn.rotation, hn.translation, en.rotation, en.translation])
        # A first pass only has to get near enough to measure the noise again: plain least
        # squares does that in 2-3 steps, where Huber's switching between its quadratic and
        # linear parts over thousands of MoCap rows takes 20-40 steps (measured on 20 s);
        # the Huber pass then starts where its active set has settled.
        last = k + 1 == passes
        for cols, rows in steps:
            x, report = _levenberg_marquardt(
                prob,
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
    f = prob.residuals(x)
    # The Gauss-Newton Jacobian of the Huber cost (scipy's convention), each stream's rows
    # scaled by its own reduced chi^2: its noise is estimated apart; the hand rows also pay
    # for the control poses, the eye rows for dt and T_HE.
    s2_h = 2.0 * _huber_cost(f[:nh], delta) / max(nh - ns, 1)
    s2_e = 2.0 * _huber_cost(f[nh:], delta) / max(f.size - nh - 7, 1)
    scale = np.where(
        np.arange(f.size) < nh, 1.0 / np.sqrt(max(s2_h, 1e-12)), 1.0 / np.sqrt(max(s2_e, 1e-12))
    )
    scale *= np.sqrt(np.minimum(1.0, delta / np.maximum(np.abs(f), 1e-300)))
    J = diags(scale) @ prob.jacobian(x)
    cov = np.zeros((7, 7))
    glob = np.flatnonzero(free[ns:])  # y's free entries
    if not decoupled:
        cov[np.ix_(glob, glob)] = _marginal_covariance(J[:, free], ns)
    else:
        # as _two_step_from_normals, with the control poses marginalised in each step
        J_A = J[rot_rows][:, free & ~trans]
        cov_tt = _marginal_covariance(J_A, J_A.shape[1] - 3)
        J_B = csc_matrix(J[:, free & ~theta])
        rhs = np.asarray((J_B.T @ J[:, theta]).todense())
        S = -splu(csc_matrix(J_B.T @ J_B)).solve(rhs)[ns:]
        k_dt = int(free[ns])
        cov[np.ix_(glob, glob)] = _assemble_two_step(
            cov_tt, _marginal_covariance(J_B, ns), S, k_dt
        )
    cost_before = _huber_cost(prob.residuals(np.zeros(prob.n)), delta)
    return (x, cost_before, _huber_cost(f, delta), hn, en, cov, f.size, int(free.sum()), report)


def _levenberg_marquardt(
    prob: _Problem,
    x: np.ndarray,
    free: np.ndarray,
    rows: np.ndarray,
    delta: float,
    max_iterations: int,
    ftol: float,
) -> tuple[np.ndarray, SolverReport]:
    """Huber-robust Levenberg-Marquardt with a sparse direct solve of the normal equations.

    Why not scipy's least_squares here: its sparse trust-region solver is lsmr, an iterative
    solver, and the joint problem (stiff MoCap rows, weak VIO rows, a 6-wide band per control
    pose plus 7 dense columns) is too ill-conditioned for it: on 8 s of data it crept from cost
    1.98e4 to 1.85e4 in 50 evaluations, and its dense solver is no faster per step and does not
    scale. A Gauss-Newton step solved exactly by sparse LU (the normal matrix is banded with a
    7-wide border) converges in 3-5 steps. The Huber loss enters as its own Newton model: rows
    within delta as in least squares, rows beyond it with their gradient clipped to +-delta and
    no curvature; the damping follows the gain ratio (Nielsen), so a step the model mispredicts
    is retried shorter.
    ``free``: the parameters it moves; ``rows``: the residual rows it minimises.
    Returns (x, report).
    """
    f = prob.residuals(x)[rows]
    cost = _huber_cost(f, delta)
    lam, nu, nfev, njev = LM_LAMBDA0, 2.0, 1, 0
    message, success = 'maximum number of iterations reached', False
    for _ in range(max_iterations):
        J = prob.jacobian(x)[rows][:, free]
        njev += 1
        # Newton on the Huber cost: rows beyond delta add no curvature, only a clipped gradient
        inner = (np.abs(f) <= delta).astype(float)
        A = (J.T @ diags(inner) @ J).tocsc()
        g = J.T @ np.clip(f, -delta, delta)
        D = diags(np.maximum(np.asarray(J.multiply(J).sum(axis=0)).ravel(), 1e-12))
        while True:
            # the parameters are in time order with (dt, T_HE) last: the normal matrix is
            # banded with a 7-wide border, which factors without fill outside them as it is
            step = splu((A + lam * D).tocsc(), permc_spec='NATURAL', diag_pivot_thresh=0.0).solve(
                -g
            )
            x_new = x.copy()
            x_new[free] += step
            f_new = prob.residuals(x_new)[rows]
            nfev += 1
            cost_new = _huber_cost(f_new, delta)
            predicted = -(g @ step + 0.5 * step @ (A @ step))
            if cost_new <= cost or lam > LM_LAMBDA_MAX:
                break
            lam *= nu
            nu *= 2.0
        if cost_new > cost:  # no step lowers the cost: at the optimum to the Jacobian's accuracy
            message, success = 'no step lowers the cost any further', True
            break
        # Nielsen's damping update from the gain ratio (actual over predicted decrease)
        decrease = cost - cost_new
        rho = decrease / predicted if predicted > 0 else 0.0
        lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), LM_LAMBDA_MIN)
        nu = 2.0
        x, f, cost = x_new, f_new, cost_new
        if decrease <= ftol * cost:
            message, success = 'relative cost change below tolerance', True
            break
    return x, SolverReport(success, message, nfev=nfev, njev=njev, iterations=njev)


def _huber_cost(r: np.ndarray, delta: float) -> float:
    return float(np.sum(huber_rho(r, delta)))


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


def _marginal_covariance(J, n_nuisance: int) -> np.ndarray:
    """(J^T J)^-1 block of the parameters after the first ``n_nuisance`` (the control poses,
    and dt where it is marginalised too), by the Schur complement over those."""
    J = csc_matrix(J)
    Js, Jc = J[:, :n_nuisance], J[:, n_nuisance:].toarray()
    A = csc_matrix(Js.T @ Js)
    B = np.asarray(Js.T @ Jc)
    C = Jc.T @ Jc
    lu = splu(A)
    S = C - B.T @ lu.solve(B)
    return np.linalg.inv(S)


#: The longest gap-free part of the MoCap is used when it covers at least this fraction of the
#: eye poses the whole MoCap covers.
MIN_PIECE_COVERAGE = 0.5


def _bridged_s(hand: Trajectory, knot_spacing: float, order: int) -> float:
    """Longest hand interval [s] the spline bridges: a gap of the stream's own
    (:meth:`Trajectory.gap_limit_s`) or the span of one spline segment's support."""
    return max(knot_spacing * (order - 1), hand.gap_limit_s())


def _continuous_piece(
    hand: Trajectory, eye: Trajectory, time_offset_s: float, knot_spacing: float, order: int
) -> tuple[Trajectory, str]:
    """The hand itself when it has no gap the spline cannot bridge; otherwise its gap-free part
    that covers the most eye poses, with a note, when that part covers at least
    MIN_PIECE_COVERAGE of them (a spline cannot bridge a gap, and eye residuals near one would
    compare the VIO with an invented motion). Raises BatchError otherwise."""
    step = np.diff(hand.t_ns) * 1e-9
    cuts = np.flatnonzero(step > _bridged_s(hand, knot_spacing, order))
    if not cuts.size:
        return hand, ''
    starts = np.concatenate(([0], cuts + 1))
    ends = np.concatenate((cuts + 1, [len(hand)]))
    te = eye.t_ns - np.int64(round(time_offset_s * 1e9))
    covered = [
        int(np.sum((te >= hand.t_ns[a]) & (te <= hand.t_ns[b - 1])))
        for a, b in zip(starts, ends, strict=True)
    ]
    total = int(np.sum((te >= hand.t_ns[0]) & (te <= hand.t_ns[-1])))
    best = int(np.argmax(covered))
    k = int(cuts[np.argmax(step[cuts])])
    if covered[best] < MIN_PIECE_COVERAGE * max(total, 1):
        raise BatchError(
            f'{hand.name} has a gap of {step[k]:.3f} s (after pose {k}) and no '
            'part without one covers half of the eye: the spline (knots every '
            f'{knot_spacing:g} s) cannot bridge a gap; the batch stage needs a '
            'continuous hand stream (or a larger knot_spacing)'
        )
    a, b = int(starts[best]), int(ends[best])
    origin = int(hand.t_ns[0])
    first, last = (hand.t_ns[a] - origin) * 1e-9, (hand.t_ns[b - 1] - origin) * 1e-9
    note = (
        f'{hand.name} has {cuts.size} gap(s) the spline cannot bridge (the longest '
        f'{step[k]:.3f} s); the batch stage used its part from {first:.1f} to {last:.1f} s, '
        f'which covers {covered[best]} of the {total} eye poses'
    )
    return hand.select(slice(a, b)), note


def _check_hand_stream(hand: Trajectory, knot_spacing: float, order: int, joint: bool) -> None:
    """Refuse a MoCap stream the spline cannot be fitted to: a gap longer than the spline
    bridges, or (joint solve) fewer MoCap poses per knot interval than it needs."""
    step = np.diff(hand.t_ns) * 1e-9
    period = float(np.median(step))
    if joint and knot_spacing < MIN_HAND_POSES_PER_KNOT_JOINT * period:
        raise BatchError(
            f'the joint solve needs at least {MIN_HAND_POSES_PER_KNOT_JOINT:g} '
            f'MoCap poses per knot interval; {hand.name} at '
            f'{1.0 / period:.3g} Hz gives {knot_spacing / period:.2g} with knots '
            f'every {knot_spacing:g} s: leave batch_joint off (the default solve '
            f'holds the spline to the MoCap) or set knot_spacing >= '
            f'{MIN_HAND_POSES_PER_KNOT_JOINT * period:.3g} s'
        )
    longest = float(step.max())
    if longest > _bridged_s(hand, knot_spacing, order):
        k = int(np.argmax(step))
        raise BatchError(
            f'{hand.name} has a gap of {longest:.3f} s (after pose {k}): the '
            f'spline (knots every {knot_spacing:g} s) would have control points '
            'without MoCap data there; the batch stage needs a continuous hand '
            'stream (or a larger knot_spacing)'
        )
