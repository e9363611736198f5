"""AX = XB with dual quaternions (Section III-B, eq. 2-13): the algebra stage 2 is built on.

For each motion i -> j, ``A = T_GH_i^-1 T_GH_j`` (hand), ``B = T_WE_i^-1 T_WE_j`` (eye) and
``X = T_HE`` satisfy ``A X = X B`` (eq. 2-3). Written with unit dual quaternions this is linear
in the 8 entries of X's dual quaternion: a 6x8 block per motion (eq. 4, :func:`constraint_gram`),
stacked into M (eq. 5), whose two-dimensional null space holds X; the unit constraints
``|q| = 1, q . q' = 0`` pick it out (Daniilidis 1999; :func:`solve_gram`). The screw-congruence
kernel (eq. 7-11, :func:`screw_log_weights`) and the inlier criteria (eq. 13,
:func:`motion_errors`) are what the robust estimation of :mod:`.linear.robust` uses.

The singular values come from the eigendecomposition of ``M^T M`` (batched 8x8 Gram matrices,
never M itself): docs/method.md lists it among the departures from the paper.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..arrays import Floats, Indices
from ..association import PosePairs
from ..geometry import (
    Pose,
    dual_quat_from_pose,
    matrix_from_quat,
    quat_from_matrix,
    quat_multiply,
    relative,
    skew,
)
from .keyframes import segment_motion_indices


@dataclass(frozen=True)
class Motions:
    """Relative motions of hand (A) and eye (B) between pose pairs ``(i, j)``.

    Rotations (n, 3, 3) and translations (n, 3) in the frame of the earlier pose; the dual
    quaternions have their signs chosen so that both scalar parts are >= 0, as eq. 4 requires.
    """

    i: Indices
    j: Indices
    A: Pose
    B: Pose
    qa: Floats
    qad: Floats
    qb: Floats
    qbd: Floats
    duration_s: Floats

    def __len__(self) -> int:
        return int(self.i.size)


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


def scaled_motions(m: Motions, s: float) -> Motions:
    """The motions with the eye's translations (and dual parts) times s."""
    return replace(m, B=(m.B[0], m.B[1] * s), qbd=m.qbd * s)


def constraint_gram(m: Motions) -> Floats:
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
    out: Floats = np.matmul(np.swapaxes(S, -1, -2), S)
    return out


def screw_log_weights(m: Motions, mu: float, dual: bool = True) -> Floats:
    """``log W_i = mu (1 - E_i^2)`` of the screw-congruence kernel (eq. 10-11).

    E_i (eq. 10) compares the scalar parts of the hand and eye dual quaternions, which are equal
    without noise (eq. 9; eq. 8 gives their forms): ``w = cos(theta/2)`` (rotation angle) and
    ``w' = -d/2 sin(theta/2)`` (d: translation along the screw axis). E_i = 1 when they agree.
    Logs are returned so that large E cannot underflow the weights to zero before normalising.
    Without ``dual`` E_i compares the rotation angles alone: motions about one axis that move
    only across it (a ground robot, a turntable) have d = 0, and the ratio of their two w' is
    one of noise over noise, which no congruence is measured by.
    """

    def ratio(a: Floats, b: Floats) -> Floats:
        a, b = np.abs(a), np.abs(b)
        out: Floats = np.maximum(a, b) / np.maximum(np.minimum(a, b), 1e-15)
        return out

    rotation = ratio(m.qa[:, 3], m.qb[:, 3])
    e = 0.5 * (rotation + ratio(m.qad[:, 3], m.qbd[:, 3])) if dual else rotation
    return mu * (1.0 - e * e)


def solve_gram(G: Floats) -> tuple[Floats, Floats, Floats]:
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

    def dot(a: Floats, b: Floats) -> Floats:
        out: Floats = np.sum(a * b, axis=-1)
        return out

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
    roots = []
    for sign in (1.0, -1.0):
        mu_vec = np.stack((m1, sign * m2), -1)
        lam_vec = np.matmul(P, mu_vec[..., None])[..., 0]
        q = lam_vec[..., :1] * u1 + lam_vec[..., 1:] * u2
        qd = lam_vec[..., :1] * u1d + lam_vec[..., 1:] * u2d
        roots.append((q, qd, np.linalg.norm(q, axis=-1)))
    # Of the two roots, the one with the larger real part is X; the other tends to (0, q).
    (q_a, qd_a, norm_a), (q_b, qd_b, norm_b) = roots
    take = (norm_b > norm_a)[..., None]
    best_q, best_qd = np.where(take, q_b, q_a), np.where(take, qd_b, qd_a)
    best_norm = np.maximum(norm_b, norm_a)
    scale = 1.0 / np.maximum(best_norm, 1e-300)[..., None]
    return best_q * scale, best_qd * scale, sigma


def sigma_ratio(sigma: Floats) -> Floats:
    """Algorithm 1's score sigma7 / sigma6 of singular values (..., 8), descending.

    When sigma6 too is zero to round-off (exact motions about one axis: the null space has more
    than the two dimensions the unit constraints resolve) the ratio means nothing: it is 1,
    the worst score, so that any well-posed consensus wins and an all-degenerate one still goes
    on to :func:`degenerate_refit` (0 / 0 here had made it depend on the last bit of rounding
    whether RANSAC found anything). NaN for an empty system."""
    s6, s7, s1 = sigma[..., 5], sigma[..., 6], sigma[..., 0]
    with np.errstate(divide='ignore', invalid='ignore'):
        return np.where(s6 > 1e-12 * s1, s7 / s6, np.where(s1 > 0.0, 1.0, np.nan))


def motion_errors(
    m: Motions, q_HE: Floats, p_HE: Floats, chunk: int = 4_000_000
) -> tuple[Floats, Floats]:
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
