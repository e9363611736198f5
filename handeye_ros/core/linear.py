"""Stage 2: robust linear hand-eye calibration AX = XB with dual quaternions (Section III-B).

For each motion i -> j, ``A = T_GH_i^-1 T_GH_j`` (hand), ``B = T_WE_i^-1 T_WE_j`` (eye) and
``X = T_HE`` satisfy ``A X = X B`` (eq. 2-3). Written with unit dual quaternions this is linear
in the 8 entries of X's dual quaternion: a 6x8 block per motion (eq. 4), stacked into M (eq. 5),
whose two-dimensional null space holds X; the unit constraints ``|q| = 1, q . q' = 0`` pick it out
(Daniilidis 1999). Robustness comes from the screw-congruence kernel (eq. 7-12) and RANSAC on
2-motion subsets scored by ``sigma7 / sigma6`` (Algorithm 1).

One step beyond the paper, on by default (``decoupled_refit``): on the final consensus, the
extrinsic is re-estimated with rotation and translation apart. The rotation aligns the rotation
vectors of the inlier motions (``log R_A = R_X log R_B``, Park & Martin 1994); the translation
solves ``(R_A - I) t_X = R_X t_B - t_A`` by least squares weighted for a drifting eye.
Why: in the dual-quaternion system the rotation also has to satisfy the dual rows, which carry
the eye's translation error; a VIO's relative translations are far noisier than its relative
rotations, so that error leaks into the rotation. On the real flights of bench/real_cases.py
the rotation error drops from 0.4-1.7 deg to 0.03-0.5 deg, and on the paper's protocol at
level 10 from 0.9 to 0.5 deg (bench/ablation.py). The dual-quaternion solution is kept in the
result. The kernel and the inlier test are the paper's; two more departures are disclosed in
docs/method.md: the singular values come from the eigendecomposition of ``M^T M`` (batched 8x8
Gram matrices, never M itself), and a RANSAC refinement is eligible for the sigma7/sigma6
choice only when its consensus holds at least ``CONSENSUS_FRACTION`` of the largest one.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial.transform import Rotation

from .association import PosePairs
from .errors import DegenerateMotionError
from .geometry import (
    Pose,
    dual_quat_from_pose,
    matrix_from_quat,
    pose_from_dual_quat,
    quat_from_matrix,
    quat_multiply,
    relative,
    skew,
)
from .keyframes import segment_motion_indices
from .scale import dual_quaternion_scale, translation_and_scale

#: A RANSAC model is eligible only if its consensus holds at least this fraction of the largest
#: consensus found: sigma7/sigma6 of a tiny subset is small by chance, not by quality.
CONSENSUS_FRACTION = 0.5
#: Rotation axes of the inlier motions spread less than this (degrees): one rotation axis
#: (a ground robot, a turntable). The translation of T_HE along that axis is unobservable and
#: the rest is solved for apart (:func:`degenerate_refit`), the unobservable part named.
MIN_AXIS_SPREAD_DEG = 1.0
#: With one rotation axis, the rotation about it is taken as determined when its standard
#: deviation (from the translation equations) is below this, degrees.
MAX_PHI_STD_DEG = 2.0
#: Hypotheses scored at once by RANSAC (bounds its memory: a chunk's errors are this many
#: hypotheses times the motions).
RANSAC_CHUNK_ELEMENTS = 4_000_000
#: Below this spread the result is given, with a warning that it is weakly constrained.
WARN_AXIS_SPREAD_DEG = 10.0
#: Ratio of the 99 % quantile to the median of a chi distribution with 3 degrees of freedom
#: (3.368 / 1.538): the error norms of eq. 13 of inlier motions are roughly chi-3 distributed, so
#: this times their median is a threshold that keeps 99 % of the inliers at the measured noise.
CHI3_Q99_OVER_MEDIAN = 2.19


@dataclass(frozen=True)
class Motions:
    """Relative motions of hand (A) and eye (B) between pose pairs ``(i, j)``.

    Rotations (n, 3, 3) and translations (n, 3) in the frame of the earlier pose; the dual
    quaternions have their signs chosen so that both scalar parts are >= 0, as eq. 4 requires.
    """

    i: np.ndarray
    j: np.ndarray
    A: Pose
    B: Pose
    qa: np.ndarray
    qad: np.ndarray
    qb: np.ndarray
    qbd: np.ndarray
    duration_s: np.ndarray

    def __len__(self) -> int:
        return int(self.i.size)


@dataclass(frozen=True)
class LinearSolution:
    """Result of stage 2.

    Attributes
    ----------
    q_HE, p_HE : ndarray, shapes (4,), (3,)
        Extrinsic T_HE: the eye frame E in the hand frame H (x y z w quaternion, metres).
    q_HE_dq, p_HE_dq : ndarray, shapes (4,), (3,)
        The paper's dual-quaternion solution on the same consensus (equal to q_HE, p_HE
        without the decoupled refit).
    sigma_ratio : float
        sigma7 / sigma6 of the final robustified system (smaller is better, 0 without noise).
    singular_values : ndarray, shape (8,)
        Of the final system, descending.
    n_motions, n_inliers : int
    inliers : ndarray of bool, shape (n_motions,)
    axis_spread_deg : float
        How far apart the rotation axes of the inlier motions are (for two axes, their angle).
    rotation_residual_deg, translation_residual_m : float
        RMS of the inlier criteria (eq. 14) over the inliers at the solution.
    inlier_rotation_deg, inlier_translation_m : float
        Inlier thresholds of the final consensus (the configured ones, or wider when adapted to
        the measured noise).
    warnings : tuple of str
    unobservable : tuple of str
        Components of T_HE the motion cannot determine (one rotation axis), in words, with the
        value they were given; empty when the motion determines all of them.
    scale, scale_std, scale_dq : float
        With ``estimate_scale``: the factor s that makes the eye's translations metric (on top
        of any the eye already had), its least-squares standard deviation, and the
        dual-quaternion path's s (:mod:`.scale`); 1, NaN, 1 otherwise.
    motions : Motions or None
        The motions the solution was found on (eye made metric by ``scale``), in the order of
        ``inliers``: for plots and diagnostics.
    """

    q_HE: np.ndarray
    p_HE: np.ndarray
    q_HE_dq: np.ndarray
    p_HE_dq: np.ndarray
    sigma_ratio: float
    singular_values: np.ndarray
    n_motions: int
    n_inliers: int
    inliers: np.ndarray
    axis_spread_deg: float
    rotation_residual_deg: float
    translation_residual_m: float
    inlier_rotation_deg: float
    inlier_translation_m: float
    warnings: tuple[str, ...] = ()
    unobservable: tuple[str, ...] = ()
    scale: float = 1.0
    scale_std: float = float('nan')
    scale_dq: float = 1.0
    motions: Motions | None = field(default=None, repr=False, compare=False)


def build_motions(
    pairs: PosePairs, strategy: str = 'rotation', eta_rad: float = np.deg2rad(5.0)
) -> Motions:
    """Relative motions A (hand) and B (eye) from matched pose pairs.

    Keyframes are chosen on the hand rotations (the MoCap side is the less noisy one), within
    each eye segment: a motion across a break would compare the hand with a jump of the VIO
    world.
    """
    i, j = segment_motion_indices(pairs.R_GH, pairs.segment, strategy, eta_rad)
    A = relative((pairs.R_GH, pairs.p_GH), i, j)
    B = relative((pairs.R_WE, pairs.p_WE), i, j)
    qa, qad = dual_quat_from_pose(quat_from_matrix(A[0]), A[1])
    qb, qbd = dual_quat_from_pose(quat_from_matrix(B[0]), B[1])
    return Motions(i, j, A, B, qa, qad, qb, qbd, pairs.t_eye_s[j] - pairs.t_eye_s[i])


def constraint_gram(m: Motions) -> np.ndarray:
    """Gram matrices ``S_i^T S_i``, (n, 8, 8), of the 6x8 blocks of eq. 4.

    With r, r' (s, s') the vector parts of the hand (eye) dual quaternion, and our column order
    ``(q_v, q_w, q'_v, q'_w)``::

        S = [[ (r + s)^,   r - s,   0,         0     ],
             [ (r' + s')^, r' - s', (r + s)^,  r - s ]]
    """
    r, rd, s, sd = m.qa[:, :3], m.qad[:, :3], m.qb[:, :3], m.qbd[:, :3]
    n = r.shape[0]
    S = np.zeros((n, 6, 8))
    S[:, :3, :3] = skew(r + s)
    S[:, :3, 3] = r - s
    S[:, 3:, :3] = skew(rd + sd)
    S[:, 3:, 3] = rd - sd
    S[:, 3:, 4:7] = skew(r + s)
    S[:, 3:, 7] = r - s
    return np.matmul(np.swapaxes(S, -1, -2), S)


def screw_log_weights(m: Motions, mu: float) -> np.ndarray:
    """``log W_i = mu (1 - E_i^2)`` of the screw-congruence kernel (eq. 10-11).

    E_i (eq. 10) compares the scalar parts of the hand and eye dual quaternions, which are equal
    without noise (eq. 9; eq. 8 gives their forms): ``w = cos(theta/2)`` (rotation angle) and
    ``w' = -d/2 sin(theta/2)`` (d: translation along the screw axis). E_i = 1 when they agree.
    Logs are returned so that large E cannot underflow the weights to zero before normalising.
    """

    def ratio(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        a, b = np.abs(a), np.abs(b)
        return np.maximum(a, b) / np.maximum(np.minimum(a, b), 1e-15)

    e = 0.5 * (ratio(m.qa[:, 3], m.qb[:, 3]) + ratio(m.qad[:, 3], m.qbd[:, 3]))
    return mu * (1.0 - e * e)


def solve_gram(G: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit dual quaternion in the 2-D null space of stacked systems with Gram matrices G.

    Parameters
    ----------
    G : ndarray, shape (..., 8, 8)

    Returns
    -------
    q, qd : ndarray, shape (..., 4)
        Rotation and dual part (x y z w), |q| = 1 and q . qd = 0. When no combination of the
        two smallest singular vectors satisfies q . qd = 0 (the quadratic in their weights has
        no real root, which noise far beyond a rank-6 system can cause), the combination
        nearest to it is returned and :func:`pose_from_dual_quat` projects qd.
    sigma : ndarray, shape (..., 8)
        Singular values of the stacked system, descending (sigma[..., 6] is the paper's sigma7):
        the square roots of G's eigenvalues, since G = M^T M.
    """
    lam, V = np.linalg.eigh(G)
    sigma = np.sqrt(np.clip(lam[..., ::-1], 0.0, None))
    v1, v2 = V[..., :, 0], V[..., :, 1]
    u1, u1d, u2, u2d = v1[..., :4], v1[..., 4:], v2[..., :4], v2[..., 4:]

    def dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.sum(a * b, axis=-1)

    # x = l1 v1 + l2 v2 with q . qd = 0: a homogeneous quadratic in (l1, l2). In the eigenbasis
    # of its 2x2 matrix Q it reads e1 m1^2 + e2 m2^2 = 0, solved by m = (sqrt(e2), +-sqrt(-e1)).
    b = 0.5 * (dot(u1, u2d) + dot(u2, u1d))
    Q = np.stack((np.stack((dot(u1, u1d), b), -1), np.stack((b, dot(u2, u2d)), -1)), -2)
    e, P = np.linalg.eigh(Q)
    mixed = (e[..., 0] <= 0.0) & (e[..., 1] >= 0.0)
    m1 = np.where(
        mixed,
        np.sqrt(np.abs(e[..., 1])),
        np.where(np.abs(e[..., 0]) < np.abs(e[..., 1]), 1.0, 0.0),
    )
    m2 = np.where(mixed, np.sqrt(np.abs(e[..., 0])), 1.0 - m1)
    best_q = best_qd = None
    best_norm = None
    for sign in (1.0, -1.0):
        mu_vec = np.stack((m1, sign * m2), -1)
        lam_vec = np.matmul(P, mu_vec[..., None])[..., 0]
        q = lam_vec[..., :1] * u1 + lam_vec[..., 1:] * u2
        qd = lam_vec[..., :1] * u1d + lam_vec[..., 1:] * u2d
        # Of the two roots, the one with the larger real part is X; the other tends to (0, q).
        norm = np.linalg.norm(q, axis=-1)
        if best_norm is None:
            best_q, best_qd, best_norm = q, qd, norm
        else:
            take = (norm > best_norm)[..., None]
            best_q = np.where(take, q, best_q)
            best_qd = np.where(take, qd, best_qd)
            best_norm = np.maximum(norm, best_norm)
    scale = 1.0 / np.maximum(best_norm, 1e-300)[..., None]
    return best_q * scale, best_qd * scale, sigma


def motion_errors(
    m: Motions, q_HE: np.ndarray, p_HE: np.ndarray, chunk: int = 4_000_000
) -> tuple[np.ndarray, np.ndarray]:
    """Inlier criteria of eq. 13 for K hypotheses against n motions.

    ``E = X B X^-1 A^-1``; e1 = rotation angle of E (rad), e2 = norm of its translation (m).

    Both are evaluated as matrix products over (hypothesis, motion), never as K*n pose
    compositions (this is the hot loop of RANSAC):

    - ``cos(e1 / 2) = |<q_X q_B, q_A q_X>| = |q_X^T Rq(q_B)^T Lq(q_A) q_X|``, a quadratic form
      in q_X: the flattened outer products ``q_X q_X^T`` (K, 16) times the flattened 4x4
      matrices of the motions (16, n).
    - ``|t_E| = |R_X^T t_E| = |t_B + (I - R_B) u - R_B R_X^T R_A^T t_A|`` with
      ``u = R_X^T t_X``: each term is linear in u or in the entries of R_X.

    Parameters
    ----------
    q_HE, p_HE : ndarray, shapes (K, 4), (K, 3)

    Returns
    -------
    e_rot, e_trans : ndarray, shape (K, n)
    """
    q_HE = np.asarray(q_HE, dtype=float)
    RX = matrix_from_quat(q_HE)
    K, n = RX.shape[0], len(m)
    basis = np.eye(4)
    # Lq(a) b = a (x) b and Rq(b) a = a (x) b as 4x4 matrices (columns: products with the basis)
    Lq = np.stack([quat_multiply(m.qa, e) for e in basis], axis=-1)
    Rq = np.stack([quat_multiply(e, m.qb) for e in basis], axis=-1)
    forms = np.matmul(np.swapaxes(Rq, -1, -2), Lq).reshape(n, 16)
    R_B, t_B = m.B
    a = np.einsum('nba,nb->na', m.A[0], m.A[1])  # R_A^T t_A
    P = (R_B[:, :, :, None] * a[:, None, None, :]).reshape(n * 3, 9)  # R_B[a,b] * a[c]
    e_rot = np.empty((K, n))
    e_trans = np.empty((K, n))
    step = max(1, chunk // max(3 * n, 1))
    for k0 in range(0, K, step):
        q = q_HE[k0 : k0 + step]
        R = RX[k0 : k0 + step]
        cos_half = np.abs((q[:, :, None] * q[:, None, :]).reshape(-1, 16) @ forms.T)
        e_rot[k0 : k0 + step] = 2.0 * np.arccos(np.minimum(cos_half, 1.0))
        u = np.einsum('kba,kb->ka', R, p_HE[k0 : k0 + step])  # R_X^T t_X, (k, 3)
        RB_u = (R_B.reshape(n * 3, 3) @ u.T).reshape(n, 3, -1)
        # sum_bc R_B[a,b] R_X[c,b] a[c]: the entries of R_X ordered (b, c), i.e. R_X^T flattened
        RB_RXt_a = (P @ np.swapaxes(R, -1, -2).reshape(-1, 9).T).reshape(n, 3, -1)
        t = t_B[:, :, None] + u.T[None] - RB_u - RB_RXt_a
        e_trans[k0 : k0 + step] = np.linalg.norm(t, axis=1).T
    return e_rot, e_trans


def refit_rotation(m: Motions, mask: np.ndarray) -> np.ndarray:
    """Rotation of T_HE from the rotation parts alone of the selected motions, x y z w.

    ``R_A = R_X R_B R_X^T`` makes the rotation vectors satisfy ``log R_A = R_X log R_B``; the
    least-squares R_X over the motions is an orthogonal Procrustes problem (Park & Martin
    1994), solved by ``Rotation.align_vectors``. Longer rotations, whose axes are better
    defined, weigh more by their length.
    """
    return rotation_from_motions(m.A[0][mask], m.B[0][mask])[0].as_quat()


def rotation_from_motions(
    R_A: np.ndarray, R_B: np.ndarray
) -> tuple[Rotation, np.ndarray, np.ndarray]:
    """The least-squares R_X of ``log R_A = R_X log R_B`` over motions (n, 3, 3), and the two
    rotation-vector stacks (n, 3) it aligns (for residuals)."""
    a = Rotation.from_matrix(R_A).as_rotvec()
    b = Rotation.from_matrix(R_B).as_rotvec()
    return Rotation.align_vectors(a, b)[0], a, b


def translation_from_motions(
    R_A: np.ndarray, t_A: np.ndarray, t_B: np.ndarray, R_X: np.ndarray, w: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The least-squares t_X of ``(R_A - I) t_X = R_X t_B - t_A`` over motions, each motion's
    three rows weighted by w (n,) when given; returns t_X and the (n, 3) residuals (weighted
    as solved)."""
    w = np.ones(R_A.shape[0]) if w is None else w
    lhs = ((R_A - np.eye(3)) * w[:, None, None]).reshape(-1, 3)
    rhs = ((t_B @ R_X.T - t_A) * w[:, None]).reshape(-1)
    t_X = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    return t_X, (lhs @ t_X - rhs).reshape(-1, 3)


def drift_weights(m: Motions, mask: np.ndarray) -> np.ndarray:
    """``1 / sqrt(duration)`` of the selected motions: a drifting eye's error variance grows
    with the motion's length (see :func:`refit_translation_gls`)."""
    return 1.0 / np.sqrt(np.maximum(m.duration_s[mask], 1e-6))


def refit_translation_gls(m: Motions, mask: np.ndarray, R_HE: np.ndarray) -> np.ndarray:
    """Translation of T_HE given its rotation, from the translation part of AX = XB (eq. 2).

    ``(R_A - I) t_X = R_X t_B - t_A`` for every selected motion, solved by least squares with
    each motion's three rows weighted by ``1 / sqrt(duration)``: the eye's error accumulates
    frame by frame, so the variance of ``t_B`` grows with the motion's length, and these are
    the generalised-least-squares weights for independent keyframe motions. The hand (MoCap)
    side is taken as exact.

    Parameters
    ----------
    m : Motions
    mask : ndarray of bool, shape (n,)
        Motions to use (the inliers).
    R_HE : ndarray, shape (3, 3)

    Returns
    -------
    ndarray, shape (3,)
        t_HE, metres.
    """
    return translation_from_motions(
        m.A[0][mask], m.A[1][mask], m.B[1][mask], R_HE, drift_weights(m, mask)
    )[0]


def axis_spread_deg(m: Motions, mask: np.ndarray) -> float:
    """Spread of the hand rotation axes of the selected motions, degrees.

    From the eigenvalues l1 >= l2 of the axes' scatter matrix: ``2 atan(sqrt(l2 / l1))``, which
    for two axes equals the angle between them and is 0 when all axes are parallel.
    """
    v = m.qa[mask, :3]
    norms = np.linalg.norm(v, axis=1)
    a = v[norms > 1e-12] / norms[norms > 1e-12, None]
    if a.shape[0] < 2:
        return 0.0
    lam = np.linalg.eigvalsh(a.T @ a)[::-1]
    return float(np.degrees(2.0 * np.arctan(np.sqrt(max(lam[1], 0.0) / lam[0]))))


def common_axis(v: np.ndarray) -> np.ndarray:
    """Unit principal direction of vectors (n, 3) (the eigenvector of their scatter matrix with
    the largest eigenvalue), signed to agree with the first long vector."""
    _, V = np.linalg.eigh(v.T @ v)
    a = V[:, -1]
    k = int(np.argmax(np.linalg.norm(v, axis=1)))
    return a if float(v[k] @ a) >= 0.0 else -a


def degenerate_refit(
    m: Motions, mask: np.ndarray
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """T_HE when every motion rotates about one axis (a ground robot, a turntable).

    The rotation axes fix R_X up to a rotation phi about the common axis a (hand frame):
    ``R_X = R_phi R_0`` with R_0 the smallest rotation taking the eye's axis onto a. The
    translation part of AX = XB, ``(R_A - I) t_X = R_phi R_0 t_B - t_A``, is linear in
    ``(cos phi, sin phi, t_X)``: with ``u = R_0 t_B``, ``R_phi u = cos phi u_perp + sin phi
    (a x u) + (a . u) a``. Solved by least squares with the drift weights of
    :func:`refit_translation_gls`. The translation along a is never determined
    ((R_A - I) a = 0); phi is determined when the motion translates across the axis (a ground
    robot driving) and not when the rig only turns in place (any phi has its own t_X then):
    it is taken when its standard deviation from the least squares is below MAX_PHI_STD_DEG.
    Undetermined parts are given their smallest value (no translation along a; phi = 0).

    Returns (q_HE x y z w, p_HE, the undetermined components in words).
    """
    a_h = Rotation.from_matrix(m.A[0][mask]).as_rotvec()
    a_e = Rotation.from_matrix(m.B[0][mask]).as_rotvec()
    a = common_axis(a_h)
    e = common_axis(a_e)
    if float(np.sum((a_h @ a) * (a_e @ e))) < 0.0:  # the same turns, the same sense
        e = -e
    with warnings.catch_warnings():  # one pair of vectors: the smallest rotation, as wanted
        warnings.simplefilter('ignore', UserWarning)
        R0 = Rotation.align_vectors(a[None], e[None])[0]
    R_A, t_A = m.A[0][mask], m.A[1][mask]
    u = R0.apply(m.B[1][mask])
    w = drift_weights(m, mask)[:, None, None]
    # basis (e1, e2, a) of the hand frame; unknowns z = (cos phi, sin phi, t_e1, t_e2, t_a)
    e1 = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    basis = np.stack((e1, e2, a), axis=1)
    u_perp = u - (u @ a)[:, None] * a
    cols = (
        np.concatenate(
            (-u_perp[:, :, None], -np.cross(a, u)[:, :, None], np.matmul(R_A - np.eye(3), basis)),
            axis=2,
        )
        * w
    )
    rhs = (((u @ a)[:, None] * a - t_A)[:, :, None] * w).reshape(-1)
    lhs = cols.reshape(-1, 5)[:, :4]  # the t_a column is zero: (R_A - I) a = 0
    unobservable = [
        (
            'translation along the rotation axis '
            f'[{a[0]:+.3f} {a[1]:+.3f} {a[2]:+.3f}] (hand frame), set to 0'
        )
    ]
    phi = 0.0
    z, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
    # phi is determined when its own standard deviation is small and (cos, sin) came out a
    # unit vector; noise alone lifts the singular values of a degenerate system, so their
    # ratio cannot tell
    dof = max(rhs.size - 4, 1)
    s2 = float(np.sum((lhs @ z - rhs) ** 2)) / dof
    cov = s2 * np.linalg.pinv(lhs.T @ lhs)
    norm_cs = float(np.hypot(z[0], z[1]))
    sd_phi = float(np.sqrt(max(cov[0, 0] + cov[1, 1], 0.0))) / max(norm_cs, 1e-12)
    if sd_phi < np.deg2rad(MAX_PHI_STD_DEG) and abs(norm_cs - 1.0) < 0.3:
        phi = float(np.arctan2(z[1], z[0]))
    else:
        unobservable.append(
            'rotation about that axis (and with it the translation across '
            'it), set to the smallest rotation that aligns the axes'
        )
    R_X = Rotation.from_rotvec(phi * a) * R0
    # with phi fixed, the translation across the axis (along the axis stays 0)
    lhs_t = (np.matmul(R_A - np.eye(3), basis[:, :2]) * w).reshape(-1, 2)
    rhs_t = ((R_X.apply(m.B[1][mask]) - t_A)[:, :, None] * w).reshape(-1)
    t2 = np.linalg.lstsq(lhs_t, rhs_t, rcond=None)[0]
    q = R_X.as_quat()
    return q * (1.0 if q[3] >= 0.0 else -1.0), basis[:, :2] @ t2, tuple(unobservable)


def sigma_ratio(sigma: np.ndarray) -> np.ndarray:
    """Algorithm 1's score sigma7 / sigma6 of singular values (..., 8), descending.

    When sigma6 too is zero to round-off (exact motions about one axis: the null space has more
    than the two dimensions the unit constraints resolve) the ratio means nothing: it is 1,
    the worst score, so that any well-posed consensus wins and an all-degenerate one still goes
    on to :func:`degenerate_refit` (0 / 0 here had made it depend on the last bit of rounding
    whether RANSAC found anything). NaN for an empty system."""
    s6, s7, s1 = sigma[..., 5], sigma[..., 6], sigma[..., 0]
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(s6 > 1e-12 * s1, s7 / s6, np.where(s1 > 0.0, 1.0, np.nan))


def _ransac(
    m: Motions,
    gram: np.ndarray,
    w2: np.ndarray,
    iterations: int,
    inlier_rotation_rad: float,
    inlier_translation_m: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Algorithm 1's loop: per 2-motion hypothesis, its consensus size, the robust re-solve on
    that consensus (q, qd, sigma7/sigma6), evaluated in chunks so that memory does not grow
    with the number of hypotheses. Returns (counts, q1, qd1, ratio, hypotheses' (q0, p0))."""
    n = len(m)
    first = rng.integers(0, n, iterations)
    second = (first + rng.integers(1, n, iterations)) % n
    counts = np.empty(iterations, dtype=int)
    q1 = np.empty((iterations, 4))
    qd1 = np.empty((iterations, 4))
    ratio = np.empty(iterations)
    q0_all = np.empty((iterations, 4))
    p0_all = np.empty((iterations, 3))
    chunk = max(1, RANSAC_CHUNK_ELEMENTS // max(n, 1))
    for a in range(0, iterations, chunk):
        b = min(a + chunk, iterations)
        G2 = (gram[first[a:b]] + gram[second[a:b]]).reshape(-1, 8, 8)
        q0, qd0, _ = solve_gram(G2)
        q0, p0 = pose_from_dual_quat(q0, qd0)
        e_rot, e_trans = motion_errors(m, q0, p0)
        masks = (e_rot < inlier_rotation_rad) & (e_trans < inlier_translation_m)
        counts[a:b] = masks.sum(axis=1)
        qa, qda, sigma = solve_gram(((masks * w2) @ gram).reshape(-1, 8, 8))
        q1[a:b], qd1[a:b] = qa, qda
        ratio[a:b] = sigma_ratio(sigma)
        q0_all[a:b], p0_all[a:b] = q0, p0
    return counts, q1, qd1, ratio, (q0_all, p0_all)


def calibrate_linear(
    m: Motions,
    *,
    robust_kernel: bool = True,
    mu: float = 5.0,
    ransac_iterations: int = 200,
    inlier_rotation_rad: float = np.deg2rad(0.5),
    inlier_translation_m: float = 0.02,
    min_motions: int = 10,
    adaptive_inliers: bool = True,
    decoupled_refit: bool = True,
    estimate_scale: bool = False,
    rng: np.random.Generator | None = None,
) -> LinearSolution:
    """Algorithm 1: RANSAC over 2-motion subsets, robust refinement, best sigma7/sigma6.

    Each iteration solves the 12x8 system of two random motions, collects the motions that agree
    with it within the inlier thresholds (eq. 13), re-solves on them with the robust kernel
    weights (eq. 12), and scores that refinement by sigma7/sigma6; the best-scoring refinement
    wins. With ``ransac_iterations=0`` a single robust solve on all motions is returned.

    With ``adaptive_inliers`` the consensus of the winner is taken once more with thresholds no
    tighter than the configured ones but wide enough for the noise measured from the winner's
    own residuals (``CHI3_Q99_OVER_MEDIAN`` times their median), and the system re-solved on it.
    Why: the paper's 0.5 deg / 2 cm suit a good VIO over a 5 deg keyframe motion; a noisier eye
    pushes most clean motions over them, and a solution from the few left is far noisier than
    one from all clean motions. The median keeps true outliers (a minority) out.

    With ``decoupled_refit`` the extrinsic is finally re-estimated on the consensus with
    rotation (:func:`refit_rotation`) and translation (:func:`refit_translation_gls`) apart;
    otherwise the dual-quaternion solution is the result. Either way the dual-quaternion
    solution is kept in ``q_HE_dq, p_HE_dq``.

    When the rotation axes of the consensus are all parallel (one rotation axis), the
    determined part of T_HE comes from :func:`degenerate_refit` and ``unobservable`` names the
    rest.

    ``estimate_scale``: the eye's translations are metric only up to a factor s (a monocular
    eye, :mod:`.scale`); both refits then solve for it: the translation refit in (t_X, s), the
    dual-quaternion one in (q', s) with its rotation fixed. RANSAC's thresholds in metres need
    the eye near metric already (the pipeline scales it by :func:`.scale.scale_prior` first).

    Raises
    ------
    DegenerateMotionError
        With fewer than ``min_motions`` motions, or when no hypothesis gathers a consensus.
    """
    n = len(m)
    if n < max(min_motions, 2):
        msg = (
            f'only {n} relative motions could be built (need {max(min_motions, 2)}): the '
            'recording rotates too little for the keyframe rule. Rotate the rig more (about '
            'several axes), or lower eta'
        )
        raise DegenerateMotionError(msg)
    rng = rng if rng is not None else np.random.default_rng(0)
    gram = constraint_gram(m).reshape(n, 64)
    if robust_kernel:
        log_w = screw_log_weights(m, mu)
        w2 = np.exp(2.0 * (log_w - log_w.max()))
    else:
        w2 = np.ones(n)

    if ransac_iterations > 0:
        counts, q1, qd1, ratio, (q0, p0) = _ransac(
            m, gram, w2, ransac_iterations, inlier_rotation_rad, inlier_translation_m, rng
        )
    else:
        counts = np.array([n])
        q1, qd1, sigma = solve_gram((w2 @ gram).reshape(1, 8, 8))
        ratio = sigma_ratio(sigma)
    eligible = (counts >= 2) & (counts >= CONSENSUS_FRACTION * counts.max()) & np.isfinite(ratio)
    if not eligible.any():
        msg = (
            f'RANSAC found no model that 2 or more of the {n} motions agree with within '
            f'{np.degrees(inlier_rotation_rad):.2f} deg / {inlier_translation_m:.3f} m: the '
            'eye poses are too noisy for these thresholds, or the time offset is wrong'
        )
        raise DegenerateMotionError(msg)
    best = int(np.argmin(np.where(eligible, ratio, np.inf)))
    q_HE, p_HE = pose_from_dual_quat(q1[best], qd1[best])
    if ransac_iterations > 0:
        e_rot, e_trans = motion_errors(m, q0[best][None], p0[best][None])
        inliers = (e_rot[0] < inlier_rotation_rad) & (e_trans[0] < inlier_translation_m)
    else:
        inliers = np.ones(n, dtype=bool)
    sigma_best = solve_gram(((inliers * w2) @ gram).reshape(8, 8))[2]
    ratio_best = float(ratio[best])
    thr_rot, thr_trans = inlier_rotation_rad, inlier_translation_m
    if adaptive_inliers:
        e_rot, e_trans = motion_errors(m, q_HE[None], p_HE[None])
        thr_rot = max(thr_rot, CHI3_Q99_OVER_MEDIAN * float(np.median(e_rot[0])))
        thr_trans = max(thr_trans, CHI3_Q99_OVER_MEDIAN * float(np.median(e_trans[0])))
        wider = (e_rot[0] < thr_rot) & (e_trans[0] < thr_trans)
        if wider.sum() > inliers.sum():
            q2, qd2, s2 = solve_gram(((wider * w2) @ gram).reshape(8, 8))
            q_HE, p_HE = pose_from_dual_quat(q2, qd2)
            inliers, sigma_best, ratio_best = wider, s2, float(s2[6] / s2[5])

    spread = axis_spread_deg(m, inliers)
    q_dq, p_dq = q_HE, p_HE
    unobservable: tuple[str, ...] = ()
    warnings = []
    scale = scale_dq = 1.0
    scale_std = float('nan')
    if estimate_scale and spread >= MIN_AXIS_SPREAD_DEG:
        # the paper's baseline with a scale: the rotation of the dual-quaternion solution,
        # then its dual part and s from the lower rows of eq. 4
        p_dq, scale_dq = dual_quaternion_scale(
            m.qa[inliers],
            m.qad[inliers],
            m.qb[inliers],
            m.qbd[inliers],
            q_dq,
            drift_weights(m, inliers),
        )
        if not (np.isfinite(scale_dq) and scale_dq > 0.0):
            p_dq, scale_dq = p_HE, 1.0
        if not decoupled_refit:
            p_HE, scale = p_dq, scale_dq
    if spread < MIN_AXIS_SPREAD_DEG:
        # one rotation axis: the dual-quaternion system has a 3-D null space and picks an
        # arbitrary point of it; the determined part is solved apart and the rest named
        q_HE, p_HE, unobservable = degenerate_refit(m, inliers)
        warnings.append(
            f'the rotation axes of the {inliers.sum()} inlier motions are within '
            f'{spread:.2f} deg of one direction, so part of the extrinsic cannot be '
            'observed: ' + '; '.join(unobservable) + '. Rotate the rig about at '
            'least two different axes to determine it'
        )
    elif decoupled_refit:
        q_HE = refit_rotation(m, inliers)
        q_HE *= 1.0 if float(np.dot(q_HE, q_dq)) >= 0.0 else -1.0  # same hemisphere as before
        fit = (
            translation_and_scale(
                m.A[0][inliers],
                m.A[1][inliers],
                m.B[1][inliers],
                matrix_from_quat(q_HE),
                drift_weights(m, inliers),
            )
            if estimate_scale
            else None
        )
        if fit is not None:
            scale_std = fit.scale_std
        if fit is not None and fit.observable:
            p_HE, scale = fit.p_HE, fit.scale
        else:  # no scale, or an unobservable one (the pipeline's verdict names it)
            p_HE = refit_translation_gls(m, inliers, matrix_from_quat(q_HE))
    if MIN_AXIS_SPREAD_DEG <= spread < WARN_AXIS_SPREAD_DEG:
        warnings.append(
            f'rotation axes spread only {spread:.1f} deg: the extrinsic is weakly '
            'constrained; rotate about more different axes'
        )
    if scale != 1.0:  # the inlier criteria of eq. 13 with the eye made metric
        m = scaled_motions(m, scale)
    e_rot, e_trans = motion_errors(m, q_HE[None], p_HE[None])
    return LinearSolution(
        q_HE=q_HE,
        p_HE=p_HE,
        q_HE_dq=q_dq,
        p_HE_dq=p_dq,
        sigma_ratio=ratio_best,
        singular_values=sigma_best,
        n_motions=n,
        n_inliers=int(inliers.sum()),
        inliers=inliers,
        axis_spread_deg=spread,
        rotation_residual_deg=float(np.degrees(np.sqrt(np.mean(e_rot[0, inliers] ** 2)))),
        translation_residual_m=float(np.sqrt(np.mean(e_trans[0, inliers] ** 2))),
        inlier_rotation_deg=float(np.degrees(thr_rot)),
        inlier_translation_m=float(thr_trans),
        warnings=tuple(warnings),
        unobservable=unobservable,
        scale=scale,
        scale_std=scale_std,
        scale_dq=scale_dq,
        motions=m,
    )


def scaled_motions(m: Motions, s: float) -> Motions:
    """The motions with the eye's translations (and dual parts) times s."""
    return replace(m, B=(m.B[0], m.B[1] * s), qbd=m.qbd * s)
