"""The joint solve's sparse Jacobian (eq. 15-16 with the control poses free): analytic in the
spline's control poses, central differences in (dt, T_HE).

Only the joint solve (``batch_joint``) needs it; the default solve holds the spline to the MoCap
and differentiates the eye residuals alone (:meth:`.batch.residuals.BatchProblem.eye_chunk`).
:func:`central_jacobian` takes the central differences, here and for the covariance's
Jacobians (:mod:`.covariance`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.sparse import csr_matrix

from ..arrays import Floats, Indices
from ..geometry import log_so3, right_jacobian, skew
from .residuals import FD_STEP, FD_STEP_S, BatchProblem, Weights
from .spline import PoseSpline


class _Triplets:
    """The (row, column, value) entries of a sparse Jacobian, gathered block by block."""

    def __init__(self, Jc: Floats) -> None:
        #: (M, 3, 3) right Jacobians of the control rotations' parameters
        self.Jc = Jc
        self.rows: list[Indices] = []
        self.cols: list[Indices] = []
        self.values: list[Floats] = []

    def add(self, row0: Indices, cp: Indices, col_off: int, block: Floats) -> None:
        """Blocks (N, k, 3, 3): rows row0 + 0..2, columns 6 cp + col_off + 0..2 (col_off 0:
        a control rotation, whose parameter enters through its right Jacobian)."""
        if col_off == 0:
            block = np.matmul(block, self.Jc[cp])
        rr = row0[:, None, None, None] + np.arange(3)[:, None]
        cc = 6 * cp[:, :, None, None] + col_off + np.arange(3)
        rr, cc = np.broadcast_arrays(rr, cc)
        self.rows.append(rr.ravel())
        self.cols.append(cc.ravel())
        self.values.append(block.ravel())


def joint_jacobian(prob: BatchProblem, x: Floats, weights: Weights) -> csr_matrix:
    """Sparse Jacobian of :meth:`BatchProblem.residuals`: analytic in the control poses (through
    :meth:`PoseSpline.poses_and_jacobian_at`), central differences in the 7 (dt, T_HE)
    columns, which only the eye rows depend on.

    With ``r = Log(R_pred R_obs^T)`` and R_pred moved to ``R_pred Exp(v)``, r moves by
    ``Jl^-1(r) R_pred v``. Hand row h: v is the spline's body perturbation. Eye pair (a, b)
    with ``Q = R_a^T R_b`` (spline rotations at t_a - dt, t_b - dt), ``T_HE = (R_X, p_X)``:
    the relative rotation ``R_X^T Q R_X`` has ``R_pred v = R_X^T (Q eps_b - eps_a)`` and the
    relative translation ``R_X^T (Q p_X + R_a^T (p_b - p_a) - p_X)`` moves by
    ``R_X^T ([u]x eps_a - Q [p_X]x eps_b + R_a^T (dp_b - dp_a))`` with
    ``u = Q p_X + R_a^T (p_b - p_a)``.
    """
    spline, y = prob.unpack(x)
    # the parameters are R_m = R0_m Exp(c_m): a change dc is Exp(Jr(c_m) dc) on R_m
    out = _Triplets(right_jacobian(x[: prob.n_spline].reshape(prob.M, 6)[:, :3]))
    _hand_blocks(prob, spline, weights, out)
    _eye_blocks(prob, spline, y, weights, out)
    # (dt, dtheta_X, dp_X): central differences of the eye rows
    w_eye = weights.eye

    def eye_rows(yy: Floats) -> Floats:
        return (prob.eye_raw_at(spline, yy) * w_eye).ravel()

    d = central_jacobian(eye_rows, y, np.arange(7))
    out.rows.append(np.repeat(6 * prob.th.size + np.arange(d.shape[0]), 7))
    out.cols.append(np.tile(prob.n_spline + np.arange(7), d.shape[0]))
    out.values.append(d.ravel())
    m = 6 * (prob.th.size + prob.ei.size)
    return csr_matrix(
        (np.concatenate(out.values), (np.concatenate(out.rows), np.concatenate(out.cols))),
        shape=(m, prob.n),
    )


def _hand_blocks(prob: BatchProblem, spline: PoseSpline, weights: Weights, out: _Triplets) -> None:
    """The hand rows: rotation by the control rotations, position by the control
    positions."""
    hb = prob.hand_basis
    R_s, _, JR, b = spline.poses_and_jacobian_at(hb)
    r_rot = log_so3(np.matmul(R_s, np.swapaxes(prob.hand_obs[0], -1, -2)))
    cp = hb[0][:, None] + np.arange(spline.order)
    row = 6 * np.arange(prob.th.size)
    lead = np.matmul(right_jacobian(-r_rot, inverse=True), R_s)  # Jl^-1(r) R_s
    out.add(row, cp, 0, weights.hand_rotation * np.matmul(lead[:, None], JR))
    out.add(row + 3, cp, 3, weights.hand_translation * b[..., None, None] * np.eye(3))


def _eye_blocks(
    prob: BatchProblem, spline: PoseSpline, y: Floats, weights: Weights, out: _Triplets
) -> None:
    """The eye rows' blocks in the control poses (see :func:`joint_jacobian`)."""
    RX, pX = prob.extrinsic(y)
    w_rot, w_trans = weights.eye_rotation, weights.eye_translation
    eb = prob.spline0.basis(prob.eye_times(y))
    R_e, p_e, JR_e, b_e = spline.poses_and_jacobian_at(eb)
    ia, ib = prob.ei, prob.ej
    Ra, Rb, pa, pb = R_e[ia], R_e[ib], p_e[ia], p_e[ib]
    Q = np.matmul(np.swapaxes(Ra, -1, -2), Rb)
    RXt = RX.T
    rel_R = np.matmul(np.matmul(RXt, Q), RX)
    r_eye = log_so3(np.matmul(rel_R, np.swapaxes(prob.eye_obs[0], -1, -2)))
    Jl_inv = right_jacobian(-r_eye, inverse=True)
    u = np.einsum('nij,j->ni', Q, pX) + np.einsum('nji,nj->ni', Ra, pb - pa)
    RXtRat = np.matmul(RXt, np.swapaxes(Ra, -1, -2))
    row = 6 * (prob.th.size + np.arange(ia.size))
    for idx, sign_rot, d_trans in (
        (ia, -1.0, np.matmul(RXt, skew(u))),
        (ib, 1.0, -np.matmul(np.matmul(RXt, Q), skew(pX))),
    ):
        cp = eb[0][idx][:, None] + np.arange(spline.order)
        JRi = JR_e[idx]
        # d r_rot / d eps: Jl^-1 R_X^T (-I for a, Q for b)
        d_rot = np.matmul(Jl_inv, RXt if sign_rot < 0 else np.matmul(RXt, Q)) * sign_rot
        out.add(row, cp, 0, w_rot * np.matmul(d_rot[:, None], JRi))
        out.add(row + 3, cp, 0, w_trans * np.matmul(d_trans[:, None], JRi))
        out.add(row + 3, cp, 3, w_trans * sign_rot * b_e[idx][..., None, None] * RXtRat[:, None])


def central_jacobian(
    fun: Callable[[Floats], Floats],
    y: Floats,
    cols: Indices,
    steps: Floats | None = None,
) -> Floats:
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
