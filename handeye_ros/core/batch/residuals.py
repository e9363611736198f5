"""Stage 3's least-squares problem (Section III-C): the residual blocks of eq. 16 and their
Jacobians, for a cumulative B-spline T_GH(t) of the hand (:mod:`.batch.spline`, eq. 14) and the eye
predicted as ``T_WE(t) = T_WG T_GH(t - dt) T_HE`` (the model of Section III-C, stated with
eq. 15)::

    hand:  d(T_GH(t_h),  Z_h)
    eye:   d(T_HE^-1 T_GH(t_e - dt)^-1 T_GH(t_e+1 - dt) T_HE,  Y_e^-1 Y_e+1)

with ``d = (Log(R_pred R_obs^T), p_pred - p_obs)``, each part divided by its stream's noise
(:class:`Weights`). The loss and the solvers that minimise these are in :mod:`.batch.levenberg_marquardt`, the
covariance at the solution in :mod:`.batch.covariance`, the orchestration in :mod:`.batch.refine`.

Parameters: y = (dt, dtheta_X, dp_X, [drift], [scale]) are the updates of dt and T_HE (and the optional clock drift
and scale) from their start values (:class:`ParameterLayout`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..arrays import Floats, Indices, Mask
from ..errors import BatchError
from ..geometry import (
    Pose,
    log_so3,
    matrix_from_quat,
    relative,
    right_jacobian,
    skew,
)
from ..trajectory import Trajectory
from .spline import PoseSpline, fit_pieces

#: Central-difference steps in T_HE (rad, m) and dt (s) for Jacobians of the eye residuals.
FD_STEP = 1e-6
FD_STEP_S = 1e-7
#: ... and in the clock drift (s/s): 1e-9 moves an eye pose 100 s from the reference by 1e-7 s.
FD_STEP_DRIFT = 1e-9
#: dt may move this far (s) from its start during the solve: eye pairs nearer than this to
#: the spline's ends are left out, so that every eye pose keeps a spline segment.
DT_MARGIN_S = 0.05
#: MoCap poses the default solve's hand noise is measured on
#: (:meth:`BatchProblem.hand_noise_residuals`).
HAND_NOISE_SAMPLES = 200_000
#: Eye pose pairs evaluated at once (:meth:`BatchProblem.eye_chunk`): small enough that the
#: arrays of a chunk stay in cache and memory stays flat, large enough for numpy's per-call cost.
EYE_CHUNK_PAIRS = 1 << 15
#: Fewest eye residuals the stage accepts.
MIN_EYE_RESIDUALS = 20


@dataclass
class _ChunkPairs:
    """What a chunk's eye residuals and their Jacobian share (see ``eye_chunk``): the pairs'
    ends (a, b) in the chunk's eye times te [s]; Q = R_a^T R_b and R_a^T of the spline; T_HE
    (RX, pX); the rotation residuals; the scale s; the spline's body rates W and velocities V;
    and, with translations, u and the predicted relative translation p_rel."""

    a: Indices
    b: Indices
    te: Floats
    Q: Floats
    Ra_t: Floats
    RX: Floats
    pX: Floats
    r_rot: Floats
    s: float
    W: Floats
    V: Floats
    u: Floats | None
    p_rel: Floats | None


@dataclass(frozen=True)
class Weights:
    """1/sigma of each part of an eye relative pose's residual (1/rad, 1/m): its rotation and
    translation. The solver is handed them with the residuals they weight; the problem itself
    holds none."""

    eye_rotation: float = 1.0
    eye_translation: float = 1.0

    @property
    def eye(self) -> Floats:
        """(6,) per component of an eye residual."""
        return np.repeat([self.eye_rotation, self.eye_translation], 3)


def eye_pairs(traj: Trajectory) -> tuple[Indices, Indices]:
    """Consecutive pose indices not spanning a gap or a break (as stage 1)."""
    i = np.flatnonzero(traj.interval_ok())
    return i, i + 1


def _times(M: Floats, C: Floats) -> Floats:
    """``M C`` for a stack M (N, 3, 3) and a constant C (3, 3), as one matrix product."""
    return (M.reshape(-1, 3) @ C).reshape(M.shape)


def basis_ending_in(axis: Floats) -> Floats:
    """(3, 3) orthonormal, right-handed, its last column the unit ``axis``."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    e1 = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    out: Floats = np.stack((e1, np.cross(a, e1), a), axis=1)
    return out


def _conjugate(C: Floats, M: Floats, right: bool = True) -> Floats:
    """``C M C^T`` (or ``C M`` with ``right`` False) for a constant C (3, 3) and a stack M
    (N, 3, 3), as plain matrix products over the stack (numpy's stacked 3x3 matmul is several
    times slower)."""
    n = M.shape[0]
    CM = (C @ np.swapaxes(M, 0, 1).reshape(3, 3 * n)).reshape(3, n, 3).swapaxes(0, 1)
    if not right:
        return CM
    return (CM.reshape(3 * n, 3) @ C.T).reshape(n, 3, 3)


def residual_parts(pred: Pose, obs: Pose) -> Floats:
    """(N, 6): rotation (rad) and translation (m) differences of predicted and observed poses
    (the spline's and the MoCap's, or relative ones of the eye)."""
    dR = np.matmul(pred[0], np.swapaxes(obs[0], -1, -2))
    return np.concatenate((log_so3(dR), pred[1] - obs[1]), axis=1)


class BatchProblem:
    """The least-squares problem of the module docstring, with its Jacobian."""

    def __init__(
        self,
        hand: Trajectory,
        eye: Trajectory,
        dt0: float,
        q0: Floats,
        p0: Floats,
        knot_spacing: float,
        order: int,
        drift_stamp_ns: int | None = None,
        scale: bool = False,
        pieces: list[tuple[int, int]] | None = None,
        spline0: PoseSpline | None = None,
        held_axis: Floats | None = None,
        held_rotation: bool = False,
    ):
        """``pieces``: index ranges of the hand's gap-free parts, one spline each (default: one
        spline through the whole hand); ``spline0``: the spline already fitted to this hand
        with these knots and pieces; ``held_*``: the directions held (:meth:`_bases`)."""
        self.origin = int(hand.t_ns[0])
        self.th = hand.seconds(self.origin)
        te = eye.seconds(self.origin)
        # the MoCap's rotations stay quaternions: an hour at 1 kHz as matrices is 260 MB
        qh, ph = hand.q_xyzw, hand.p_xyz
        Re, pe = matrix_from_quat(eye.q_xyzw), eye.p_xyz
        pieces = pieces or [(0, len(hand))]
        self.pieces = pieces
        if spline0 is None:
            spline0 = fit_pieces(self.th, qh, ph, knot_spacing, order, pieces)
        self.spline0 = spline0
        self.M = self.spline0.R.shape[0]
        self.hand_q, self.hand_p = qh, ph
        # eye pairs whose two ends each stay inside a piece of the spline for any dt within the
        # margin: eq. 16 reads the hand at the two ends only, so a keyframe pair may span a
        # MoCap gap, but no end may fall in one (the spline would invent the motion there)
        ei, ej = eye_pairs(eye)
        inside = self._inside(te[ei] - dt0) & self._inside(te[ej] - dt0)
        self.ei, self.ej = ei[inside], ej[inside]
        if self.ei.size < MIN_EYE_RESIDUALS:
            raise BatchError(
                f'only {self.ei.size} consecutive eye pose pairs fall inside the '
                f'hand spline{"s" if self.spline0.pieces is not None else ""} (need {MIN_EYE_RESIDUALS}): '
                'the streams overlap too little for the batch stage'
            )
        self.te = te
        self.eye_obs = relative((Re, pe), self.ei, self.ej)
        self.dt0, self.RX0 = dt0, matrix_from_quat(q0)
        self.pX0: Floats = np.asarray(p0, dtype=np.float64)
        self.translation_basis, self.rotation_basis = self._bases(held_axis, held_rotation)
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

    def _bases(self, held_axis: Floats | None, held_rotation: bool) -> tuple[Floats, Floats]:
        """The bases of dp_X (hand frame) and dtheta_X (eye frame): the identity, or with a
        unit ``held_axis`` (hand frame; the only rotation axis of a ground robot) one whose last
        vector is it, so that holding T_HE's translation along it is holding y[6]; with
        ``held_rotation`` (the rotation about it held too) dtheta_X's is the axis in the eye
        frame, y[3] held (:func:`basis_ending_in`)."""
        eye3: Floats = np.eye(3)
        if held_axis is None:
            return eye3, eye3
        rotation = basis_ending_in(self.RX0.T @ held_axis) if held_rotation else eye3
        return basis_ending_in(held_axis), rotation

    def _inside(self, t: Floats) -> Mask:
        """Hand times (s) at least DT_MARGIN_S inside a piece of the spline."""
        spans = np.array(self.spline0.spans())
        k = np.clip(np.searchsorted(spans[:, 0], t, side='right') - 1, 0, None)
        out: Mask = (t >= spans[k, 0] + DT_MARGIN_S) & (t <= spans[k, 1] - DT_MARGIN_S)
        return out

    def hand_noise_residuals(self) -> Floats:
        """Hand residuals of the spline fit (n, 6) at up to HAND_NOISE_SAMPLES MoCap poses evenly
        spread: what the default solve needs of the hand is its noise level, which a robust
        sigma of 2e5 residuals gives to 0.3 %; an hour of 1 kHz MoCap would take 10 s more."""
        pick = np.unique(
            np.linspace(0, self.th.size - 1, min(self.th.size, HAND_NOISE_SAMPLES)).astype(int)
        )
        obs = (matrix_from_quat(self.hand_q[pick]), self.hand_p[pick])
        return residual_parts(self.spline0.poses_at(self.th[pick]), obs)

    def extrinsic(self, y: Floats) -> Pose:
        """T_HE of the updates y = (ddt, dtheta_X, dp_X, ...) to the start values."""
        R = self.RX0 @ Rotation.from_rotvec(self.rotation_basis @ y[1:4]).as_matrix()
        return R, self.pX0 + self.translation_basis @ y[4:7]

    def clock(self, y: Floats) -> tuple[float, float]:
        """(dt at t_ref, clock drift) of y."""
        return self.dt0 + y[0], (0.0 if self.i_drift is None else float(y[self.i_drift]))

    def scale(self, y: Floats) -> float:
        """The factor on the eye's translations (1 without a scale parameter)."""
        return 1.0 if self.i_scale is None else 1.0 + float(y[self.i_scale])

    def eye_times(self, y: Floats, first: int = 0, stop: int | None = None) -> Floats:
        """The hand-clock times of the eye stamps first..stop-1: ``t - dt - drift (t - t_ref)``
        (the linear clock of :mod:`.time.clock`)."""
        dt, drift = self.clock(y)
        te = self.te[first:stop]
        return te - dt - drift * (te - self.t_ref)

    def eye_raw_at(self, spline: PoseSpline, y: Floats) -> Floats:
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
        y: Floats,
        k0: int,
        k1: int,
        jacobian: bool = True,
        rotation_only: bool = False,
        spline: PoseSpline | None = None,
    ) -> tuple[Floats, Floats | None]:
        """Unweighted eye residuals of the pairs k0..k1-1 ((n, 6), or (n, 3) rotation only)
        predicted from ``spline`` (default: the hand's fit) and y, and with ``jacobian`` their
        Jacobian (n, 6 or 3, n_y) in y, analytic (the spline held fixed). The pairs are taken a
        chunk at a time so that no array holds more than a chunk (an hour at 200 Hz is 720 000
        pairs).

        With a scale s the metric prediction is brought to the eye's units (divided by s)
        rather than the eye's noisy translations scaled: a scale on noisy observations shrinks
        towards zero by their noise-to-motion ratio (attenuation; -1 % at 1.5 mm per 25 mm
        frame step). The Jacobian's derivation is :meth:`_eye_chunk_jacobian`'s.
        """
        lo, hi = int(self.ei[k0]), int(self.ej[k1 - 1]) + 1
        a, b = self.ei[k0:k1] - lo, self.ej[k0:k1] - lo
        te = self.te[lo:hi]
        times = self.eye_times(y, lo, hi)
        sp = self.spline0 if spline is None else spline
        basis = sp.basis(times)
        if jacobian:
            R, P, W, V = sp.poses_and_rates_at(basis, sp.basis_derivative(times))
        else:
            R, P = sp.poses_at(times, basis)
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
        translations = (None, None) if rotation_only else (u, p_rel)
        pairs = _ChunkPairs(a, b, te, Q, Ra_t, RX, pX, r_rot, s, W, V, *translations)
        return r, self._eye_chunk_jacobian(pairs, y, rows)

    def _eye_chunk_jacobian(self, p: _ChunkPairs, y: Floats, rows: int) -> Floats:
        """The Jacobian (n, rows, n_y) of :meth:`eye_chunk`'s residuals in y, analytic (the
        spline held fixed).

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
        a, b, te, Q, RX, pX, s = p.a, p.b, p.te, p.Q, p.RX, p.pX, p.s
        J = np.zeros((a.size, rows, self.n_y))
        Jl_inv = right_jacobian(-p.r_rot, inverse=True)
        # the tangent on the right in the rotation basis: R_X0 Exp(B y[1:4])
        Jr_theta = right_jacobian((self.rotation_basis @ y[1:4])[None])[0] @ self.rotation_basis
        rel_R = _conjugate(RX.T, Q)
        J[:, :3, 1:4] = _times(np.matmul(Jl_inv, rel_R - np.eye(3)), Jr_theta)
        time_cols: list[tuple[int, float | Floats, float | Floats]] = [(0, -1.0, -1.0)]
        if self.i_drift is not None:
            time_cols.append(
                (self.i_drift, -(te[a] - self.t_ref)[:, None], -(te[b] - self.t_ref)[:, None])
            )
        Wa, Wb = p.W[a], p.W[b]
        QWb = np.einsum('nij,nj->ni', Q, Wb)
        for col, fa, fb in time_cols:
            J[:, :3, col] = np.einsum('nij,nj->ni', Jl_inv, (QWb * fb - Wa * fa) @ RX)
        if rows == 3:
            return J
        assert p.p_rel is not None and p.u is not None, 'translations were predicted'
        J[:, 3:, 1:4] = _times(skew(p.p_rel), Jr_theta / s)
        J[:, 3:, 4:7] = _conjugate(RX.T, Q - np.eye(3), right=False) @ self.translation_basis / s
        if self.i_scale is not None:
            J[:, 3:, self.i_scale] = -p.p_rel / s**2
        dp_a = np.cross(p.u, Wa) - np.einsum('nij,nj->ni', p.Ra_t, p.V[a])
        dp_b = np.einsum('nij,nj->ni', p.Ra_t, p.V[b]) - np.einsum(
            'nij,nj->ni', Q, np.cross(pX, Wb)
        )
        for col, fa, fb in time_cols:
            J[:, 3:, col] = (dp_a * fa + dp_b * fb) @ RX / s
        return J

    def chunks(self) -> range:
        """Start indices of the eye pair chunks of :meth:`eye_chunk`."""
        return range(0, self.ei.size, EYE_CHUNK_PAIRS)

    def eye_raw(self, y: Floats) -> Floats:
        """Unweighted eye residuals (Ne, 6) for y = (dt, dtheta_X, dp_X, ...), the spline
        fixed to the hand."""
        return self.eye_raw_at(self.spline0, y)
