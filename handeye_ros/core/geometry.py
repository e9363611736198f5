"""Stacked rigid-body transforms and unit dual quaternions.

A pose stack is a pair ``(R, p)``: rotation matrices of shape (N, 3, 3) and translations of
shape (N, 3); a single pose is the same with N dropped. ``T_A_B = (R_AB, p_AB)`` maps B-coordinates
into A: ``x_A = R_AB x_B + p_AB``, and ``T_A_C = T_A_B * T_B_C`` reads right to left.
Quaternions are Hamilton, ``(x, y, z, w)``. Conversions go through ``scipy.spatial.transform``.

A unit dual quaternion is stored as two quaternions ``(q, qd)``, both (..., 4) in x y z w order:
``q`` the rotation, ``qd = 0.5 * (p, 0) (x) q`` the dual part (Daniilidis 1999).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from .arrays import Floats, Indices
from .chunked import chunked

Pose = tuple[Floats, Floats]
#: T_HE (or any pose kept as a quaternion): (x y z w, m).
Extrinsic = tuple[Floats, Floats]


def matrix_from_quat(q_xyzw: Floats) -> Floats:
    """Rotation matrices, shape (..., 3, 3), from quaternions (..., 4) in x y z w order."""
    q = np.asarray(q_xyzw, dtype=float)
    if not q.size:  # scipy 1.11 (Jazzy's) refuses an empty stack
        return np.zeros(q.shape[:-1] + (3, 3))
    out: Floats = Rotation.from_quat(q.reshape(-1, 4)).as_matrix().reshape(q.shape[:-1] + (3, 3))
    return out


def quat_from_matrix(R: Floats) -> Floats:
    """Quaternions (..., 4), x y z w with w >= 0, from rotation matrices (..., 3, 3)."""
    R = np.asarray(R, dtype=float)
    if not R.size:  # scipy 1.11 (Jazzy's) refuses an empty stack
        return np.zeros(R.shape[:-2] + (4,))
    q = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(R.shape[:-2] + (4,))
    return positive_w(q)


def row_sums(a: Floats) -> Floats:
    """``a.sum(axis=-1)`` for a few columns (k < 8), added column by column: the same numbers
    (numpy's reduction adds so few in order) at a tenth of its time on millions of short
    rows, where that reduction pays per row."""
    s = a[..., 0]
    for k in range(1, a.shape[-1]):
        s = s + a[..., k]
    return s


def row_norms(v: Floats) -> Floats:
    """Euclidean norms over the last axis of vectors (..., k): the same numbers as
    ``np.linalg.norm(v, axis=-1)`` (:func:`row_sums`; 3.6 million quaternions: 0.35 s against
    0.02 s)."""
    v = np.asarray(v, dtype=float)
    return np.sqrt(row_sums(v * v))


def positive_w(q: Floats) -> Floats:
    """The same rotations (..., 4), x y z w, with w >= 0: the one sign every output uses."""
    q = np.asarray(q, dtype=float)
    return np.where(q[..., 3:] < 0.0, -q, q)


def apply(R: Floats, v: Floats) -> Floats:
    """``R @ v`` for stacks: R (..., 3, 3), v (..., 3) -> (..., 3)."""
    out: Floats = np.matmul(R, v[..., None])[..., 0]
    return out


def compose(a: Pose, b: Pose) -> Pose:
    """``T_a * T_b`` for broadcastable stacks."""
    Ra, pa = a
    Rb, pb = b
    return np.matmul(Ra, Rb), apply(Ra, pb) + pa


def inverse(a: Pose) -> Pose:
    """``T_a^-1``."""
    R, p = a
    Rt = np.swapaxes(R, -1, -2)
    return Rt, -apply(Rt, p)


def relative(a: Pose, i: Indices, j: Indices) -> Pose:
    """Relative motions ``T_i^-1 T_j`` (the pose of frame j expressed in frame i), stacked."""
    R, p = a
    return compose(inverse((R[i], p[i])), (R[j], p[j]))


def rotation_angle(R: Floats) -> Floats:
    """Rotation angles in radians, [0, pi], of matrices (..., 3, 3), via the trace."""
    cos = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    out: Floats = np.arccos(np.clip(cos, -1.0, 1.0))
    return out


def quat_angle(a: Floats, b: Floats) -> Floats:
    """Angle in radians, [0, pi], of the rotation between unit x y z w quaternions a and b
    (either sign of each stands for the same rotation).

    Four times the angle between the two as unit vectors of R^4, by atan2 of the chord and
    its complement: exact at small angles, where arccos of the dot product loses half the
    digits."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    sign = np.where(np.einsum('...i,...i->...', a, b) < 0.0, -1.0, 1.0)
    d = a - b * sign[..., None]
    chord2 = np.einsum('...i,...i->...', d, d)
    out: Floats = 4.0 * np.arctan2(np.sqrt(chord2), np.sqrt(np.maximum(4.0 - chord2, 0.0)))
    return out


def quat_multiply(a: Floats, b: Floats) -> Floats:
    """Hamilton product ``a (x) b`` of x y z w quaternion stacks (broadcasting).

    Written out per component: twice as fast as through np.cross on long stacks (screening
    an hour of 1 kHz MoCap multiplies some 40 million quaternions)."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 1] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 2] = aw * bz + ax * by - ay * bx + az * bw
    out[..., 3] = aw * bw - ax * bx - ay * by - az * bz
    return out


def consecutive_rotvecs(q_xyzw: Floats, span: int = 1) -> Floats:
    """Rotation vectors (N-span, 3) of ``R_k^T R_k+span`` (body frame) for x y z w quaternions
    (N, 4), the shorter way, from ``q_k* (x) q_k+span`` with the angle by atan2 (exact at small
    angles; no rotation matrices for a stream of millions of poses)."""
    q = np.asarray(q_xyzw, dtype=float)
    return chunked(lambda s: _rotvecs_between(q[:-span][s], q[span:][s]), q.shape[0] - span)


def _rotvecs_between(a: Floats, b: Floats) -> Floats:
    d = quat_multiply(quat_conjugate(a), b)
    d *= np.where(d[:, 3:] < 0.0, -1.0, 1.0)
    s = row_norms(d[:, :3])
    # w contiguous: numpy 1.26 takes the SIMD arctan2 or libm's by where its output happens to
    # be allocated when an input is a strided view (docs/benchmarks.md, "the same result")
    w = np.ascontiguousarray(d[:, 3])
    angle = 2.0 * np.arctan2(s, w)
    small = s < 1e-12
    # near zero angle / s -> 2 / w, w ~ 1 for unit quaternions; the floor only keeps a
    # degenerate (near-zero) input from overflowing in the branch np.where discards
    scale = np.where(small, 2.0 / np.maximum(w, 1e-12), angle / np.where(small, 1.0, s))
    out: Floats = d[:, :3] * scale[:, None]
    return out


def quat_conjugate(q: Floats) -> Floats:
    """Conjugate (the inverse, for unit quaternions) of x y z w quaternions."""
    out: Floats = q * np.array([-1.0, -1.0, -1.0, 1.0])
    return out


def dual_quat_from_pose(q_xyzw: Floats, p_xyz: Floats) -> tuple[Floats, Floats]:
    """Unit dual quaternions ``(q, qd)`` of poses; ``qd = 0.5 * (p, 0) (x) q``."""
    p_quat = np.concatenate((p_xyz, np.zeros(p_xyz.shape[:-1] + (1,))), axis=-1)
    return q_xyzw, 0.5 * quat_multiply(p_quat, q_xyzw)


def pose_from_dual_quat(q: Floats, qd: Floats) -> tuple[Floats, Floats]:
    """Quaternion (x y z w, w >= 0) and translation of unit dual quaternions.

    The translation is ``p = 2 (qd (x) q*)_vec``; the dual quaternion is normalised first
    (|q| = 1 and q . qd = 0) so that slightly non-unit solver outputs still give a rigid pose.
    """
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    q = q / n
    qd = qd / n
    qd = qd - np.sum(q * qd, axis=-1, keepdims=True) * q
    p = 2.0 * quat_multiply(qd, quat_conjugate(q))[..., :3]
    sign = np.where(q[..., 3:] < 0.0, -1.0, 1.0)
    return q * sign, p


def skew(v: Floats) -> Floats:
    """Skew-symmetric (cross-product) matrices, (..., 3, 3), of vectors (..., 3)."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    o = np.zeros_like(x)
    return np.stack(
        (np.stack((o, -z, y), -1), np.stack((z, o, -x), -1), np.stack((-y, x, o), -1)), -2
    )


def exp_so3(v: Floats) -> Floats:
    """Rotation matrices Exp(v) of rotation vectors (N, 3), by Rodrigues' formula.

    The hot path of the batch stage's spline: several times faster than going through scipy's
    Rotation for the small angles of spline segments; exact to round-off at any angle.
    """
    theta2 = np.einsum('ij,ij->i', v, v)
    theta = np.sqrt(theta2)
    small = theta < 1e-4
    safe = np.where(small, 1.0, theta)
    # sin(t)/t and (1 - cos t)/t^2, with their Taylor series near 0
    a: Floats = np.where(small, 1.0 - theta2 / 6.0, np.sin(safe) / safe)
    b: Floats = np.where(small, 0.5 - theta2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    # I + a K + b K^2 with K^2 = v v^T - theta^2 I, written out (no 3x3 matmul)
    R = b[:, None, None] * (v[:, :, None] * v[:, None, :])
    diag = 1.0 - b * theta2
    av = a[:, None] * v
    R[:, 0, 0] += diag
    R[:, 1, 1] += diag
    R[:, 2, 2] += diag
    R[:, 0, 1] -= av[:, 2]
    R[:, 1, 0] += av[:, 2]
    R[:, 0, 2] += av[:, 1]
    R[:, 2, 0] -= av[:, 1]
    R[:, 1, 2] -= av[:, 0]
    R[:, 2, 1] += av[:, 0]
    return R


def log_so3(R: Floats) -> Floats:
    """Rotation vectors Log(R) of rotation matrices (N, 3, 3).

    From the skew part ``w = sin(theta) axis`` and ``theta = atan2(|w|, cos theta)``, which is
    accurate at small angles (unlike arccos of the trace); near pi, where the skew part
    vanishes, scipy's conversion takes over.
    """
    w = 0.5 * np.stack(
        (R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]), axis=1
    )
    s = row_norms(w)
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    theta = np.arctan2(s, c)
    small = s < 1e-8
    scale = np.where(small, 1.0 + theta * theta / 6.0, theta / np.where(small, 1.0, s))
    out: Floats = w * scale[:, None]
    near_pi = theta > 3.0
    if near_pi.any():
        from scipy.spatial.transform import Rotation

        out[near_pi] = Rotation.from_matrix(R[near_pi]).as_rotvec()
    return out


def right_jacobian(v: Floats, inverse: bool = False) -> Floats:
    """Right Jacobians Jr(v) of SO(3) (or their inverses), (N, 3, 3), for rotation vectors (N, 3).

    ``Exp(v + dv) = Exp(v) Exp(Jr(v) dv)`` to first order; the left Jacobian is ``Jr(-v)``.
    Closed forms with their Taylor series near 0 (Chirikjian 2011; Sola et al. 2018, eq. 143-146).
    """
    t2 = np.einsum('...i,...i->...', v, v)
    t = np.sqrt(t2)
    small = t < 1e-4
    s = np.where(small, 1.0, t)
    K = skew(v)
    K2 = v[..., :, None] * v[..., None, :]  # K^2 = v v^T - |v|^2 I (no stacked matmul)
    K2[..., [0, 1, 2], [0, 1, 2]] -= t2[..., None]
    a: Floats
    b: Floats
    if inverse:
        a = np.full(t.shape, 0.5)
        b = np.where(
            small,
            1.0 / 12.0 + t2 / 720.0,
            1.0 / (s * s) - (1.0 + np.cos(s)) / (2.0 * s * np.sin(s)),
        )
    else:
        a = -np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(s)) / (s * s))
        b = np.where(small, 1.0 / 6.0 - t2 / 120.0, (s - np.sin(s)) / (s * s * s))
    out: Floats = np.eye(3) + a[..., None, None] * K + b[..., None, None] * K2
    return out


def quat_slerp(q0: Floats, q1: Floats, f: Floats) -> Floats:
    """Spherical interpolation ``q0 (q0^-1 q1)^f`` of unit x y z w quaternion stacks (..., 4)
    at fractions f (...,): f in [0, 1] interpolates, outside extrapolates along the same
    geodesic. The shorter way is taken (q1's sign is matched to q0's first).

    On the great circle of R^4 through q0 and q1 (the same curve as the product form, without
    its quaternion products): ``(sin((1 - f) W) q0 + sin(f W) q1) / sin W`` with W the angle
    between them. Consecutive poses of a stream are close (W < 0.05 rad), and there the
    weights come from their series in W^2 (to W^8, round-off exact), W^2 from the chord: no
    trigonometry on millions of MoCap poses. Only the pairs asked for are computed (scipy's
    Slerp prepares every interval of the trajectory).
    """
    q0 = np.asarray(q0, dtype=float)
    q1 = np.asarray(q1, dtype=float)
    f = np.asarray(f, dtype=float)
    sign = np.where(np.einsum('...i,...i->...', q0, q1) < 0.0, -1.0, 1.0)
    q1 = q1 * sign[..., None]
    d = q0 - q1
    c2 = np.einsum('...i,...i->...', d, d)  # chord^2 = (2 sin(W / 2))^2
    w0, w1 = _slerp_weights_series(c2, f)
    far = c2 > SLERP_SERIES_CHORD**2
    if np.any(far):
        W = 2.0 * np.arctan2(np.sqrt(c2[far]), np.sqrt(np.maximum(4.0 - c2[far], 0.0)))
        ff = np.broadcast_to(f, c2.shape)[far]
        w0[far] = np.sin((1.0 - ff) * W) / np.sin(W)
        w1[far] = np.sin(ff * W) / np.sin(W)
    out = q0 * w0[..., None]
    out += q1 * w1[..., None]
    out /= np.sqrt(np.einsum('...i,...i->...', out, out))[..., None]
    return out


#: Chord (|q0 - q1|, about the angle W in R^4) below which :func:`quat_slerp` takes the
#: weights from their series: at 0.05 the first term left out is below 1e-16.
SLERP_SERIES_CHORD = 0.05


def _slerp_weights_series(c2: Floats, f: Floats) -> tuple[Floats, Floats]:
    """sin((1 - f) W) / sin W and sin(f W) / sin W for small W, from the chord^2 c2."""
    # W^2 = (2 asin(c / 2))^2 = c^2 + c^4 / 12 + c^6 / 90 + c^8 / 560 + ...
    W2 = c2 * (1.0 + c2 * (1.0 / 12.0 + c2 * (1.0 / 90.0 + c2 / 560.0)))

    def sin_over(x: Floats) -> Floats:  # sin(x W) / (x W) in x^2 W^2
        z = x * x * W2
        return 1.0 - z / 6.0 * (1.0 - z / 20.0 * (1.0 - z / 42.0 * (1.0 - z / 72.0)))

    den = sin_over(np.ones_like(W2))
    g = 1.0 - f
    return g * sin_over(g) / den, f * sin_over(f) / den


def difference(q_a: Floats, p_a: Floats, q_b: Floats, p_b: Floats) -> Floats:
    """a [-] b of two poses (x y z w, m): (p_a - p_b, Log(R_b^T R_a)), translation [m] then
    rotation [rad] in the tangent on the right (the batch stage's order for T_HE)."""
    R_a, R_b = matrix_from_quat(q_a), matrix_from_quat(q_b)
    return np.concatenate([np.asarray(p_a) - np.asarray(p_b), log_so3((R_b.T @ R_a)[None])[0]])
