"""Closed-form estimates of T_HE on a consensus of motions, beside the dual-quaternion one.

The rotation aligns the rotation vectors of the motions (``log R_A = R_X log R_B``, Park &
Martin 1994; :func:`refit_rotation`); the translation solves ``(R_A - I) t_X = R_X t_B - t_A``
by least squares weighted for a drifting eye (:func:`refit_translation_gls`). With every motion
about one axis, :func:`degenerate_refit` solves what the motion determines and names the rest.
Stage 2 (:mod:`.linear.robust`) uses them after its RANSAC; :mod:`.checks.orientations` to test
a candidate reading of the orientations on the same motions.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.spatial.transform import Rotation

from ..arrays import Floats, Mask
from ..geometry import Extrinsic
from .axxb import Motions

#: With one rotation axis, the rotation about it is taken as determined when its standard
#: deviation (from the translation equations) is below this, degrees.
MAX_PHI_STD_DEG = 2.0
#: Rotation axes of the inlier motions spread less than this (degrees): one rotation axis
#: (a ground robot, a turntable). The translation of T_HE along that axis is unobservable and
#: the rest is solved for apart (:func:`degenerate_refit`), the unobservable part named.
MIN_AXIS_SPREAD_DEG = 1.0
#: Below this spread the result is given, with a warning that it is weakly constrained.
WARN_AXIS_SPREAD_DEG = 10.0


def refit_rotation(m: Motions, mask: Mask) -> Floats:
    """Rotation of T_HE from the rotation parts alone of the selected motions, x y z w.

    ``R_A = R_X R_B R_X^T`` makes the rotation vectors satisfy ``log R_A = R_X log R_B``; the
    least-squares R_X over the motions is an orthogonal Procrustes problem (Park & Martin
    1994), solved by ``Rotation.align_vectors``. Longer rotations, whose axes are better
    defined, weigh more by their length.
    """
    out: Floats = rotation_from_motions(m.A[0][mask], m.B[0][mask])[0].as_quat()
    return out


def rotation_from_motions(R_A: Floats, R_B: Floats) -> tuple[Rotation, Floats, Floats]:
    """The least-squares R_X of ``log R_A = R_X log R_B`` over motions (n, 3, 3), and the two
    rotation-vector stacks (n, 3) it aligns (for residuals)."""
    a = Rotation.from_matrix(R_A).as_rotvec()
    b = Rotation.from_matrix(R_B).as_rotvec()
    return Rotation.align_vectors(a, b)[0], a, b


def translation_from_motions(
    R_A: Floats, t_A: Floats, t_B: Floats, R_X: Floats, w: Floats | None = None
) -> tuple[Floats, Floats]:
    """The least-squares t_X of ``(R_A - I) t_X = R_X t_B - t_A`` over motions, each motion's
    three rows weighted by w (n,) when given; returns t_X and the (n, 3) residuals (weighted
    as solved)."""
    w = np.ones(R_A.shape[0]) if w is None else w
    lhs = ((R_A - np.eye(3)) * w[:, None, None]).reshape(-1, 3)
    rhs = ((t_B @ R_X.T - t_A) * w[:, None]).reshape(-1)
    t_X = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    return t_X, (lhs @ t_X - rhs).reshape(-1, 3)


def drift_weights(m: Motions, mask: Mask) -> Floats:
    """``1 / sqrt(duration)`` of the selected motions: a drifting eye's error variance grows
    with the motion's length (see :func:`refit_translation_gls`)."""
    out: Floats = 1.0 / np.sqrt(np.maximum(m.duration_s[mask], 1e-6))
    return out


def refit_translation_gls(m: Motions, mask: Mask, R_HE: Floats) -> Floats:
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


def axis_spread_deg(m: Motions, mask: Mask) -> float:
    """Spread of the hand rotation axes of the selected motions, degrees.

    From the eigenvalues l1 >= l2 of the axes' scatter matrix: ``2 atan(sqrt(l2 / l1))``, which
    for two axes equals the angle between them and is 0 when all axes are parallel.
    """
    return float(axis_spreads_deg(rotation_axes(m), np.asarray(mask, dtype=float)[None])[0])


def rotation_axes(m: Motions) -> Floats:
    """(n, 3) unit hand rotation axes of the motions (zero rows for no rotation)."""
    return unit_axes(m.qa[:, :3])


def unit_axes(v: Floats) -> Floats:
    """(n, 3) vectors along the rotation axes (a quaternion's vector part, a rotation vector)
    scaled to unit length; zero rows for no rotation."""
    norms = np.linalg.norm(v, axis=1)
    out: Floats = np.where(norms[:, None] > 1e-12, v / np.maximum(norms, 1e-300)[:, None], 0.0)
    return out


def axis_spreads_deg(axes: Floats, masks: Mask) -> Floats:
    """:func:`axis_spread_deg` of many selections at once: ``axes`` from
    :func:`rotation_axes`, ``masks`` (k, n) -> (k,) degrees."""
    scatter = (masks @ (axes[:, :, None] * axes[:, None, :]).reshape(-1, 9)).reshape(-1, 3, 3)
    lam = np.linalg.eigvalsh(scatter)  # ascending
    with np.errstate(divide='ignore', invalid='ignore'):
        r = np.where(lam[:, 2] > 0.0, np.maximum(lam[:, 1], 0.0) / lam[:, 2], 0.0)
    out: Floats = np.degrees(2.0 * np.arctan(np.sqrt(r)))
    return out


def common_axis(v: Floats) -> Floats:
    """Unit principal direction of vectors (n, 3) (the eigenvector of their scatter matrix with
    the largest eigenvalue), signed to agree with the first long vector."""
    _, V = np.linalg.eigh(v.T @ v)
    a = V[:, -1]
    k = int(np.argmax(np.linalg.norm(v, axis=1)))
    return a if float(v[k] @ a) >= 0.0 else -a


def degenerate_refit(
    m: Motions, mask: Mask
) -> tuple[Floats, Floats, tuple[str, ...], Floats, bool]:
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

    Returns (q_HE x y z w, p_HE, the undetermined components in words, the axis a, and
    whether phi is undetermined too).
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
    q = q * (1.0 if q[3] >= 0.0 else -1.0)
    return q, basis[:, :2] @ t2, tuple(unobservable), a, len(unobservable) > 1


def held_alike(
    m: Motions, mask: Mask, axis: Floats, extrinsic: Extrinsic, like: Extrinsic
) -> Extrinsic:
    """``extrinsic`` (T_HE as x y z w, m) moved along what a turntable's motions leave open, to
    where it is nearest ``like``: screwed about the hand's rotation axis line (direction
    ``axis`` through the point the hand motions ``mask`` all turn about; every ``Z T_HE``
    with Z such a screw fits AX = XB alike, since Z commutes with every A) by the twist of
    ``like``'s rotation over its own about the axis, and along the axis to ``like``'s
    translation. Two answers that hold the rotation about the axis by a rule (the smallest
    one that aligns the axes, :func:`degenerate_refit`) may land far apart on that screw
    when the axes of the two frames are near opposite; moved alike they differ by what the
    motions determine."""
    R_A, t_A = m.A[0][mask], m.A[1][mask]
    # the point of the axis line nearest H's origin: (R_A - I) c = -t_A for every motion
    c = np.linalg.lstsq((R_A - np.eye(3)).reshape(-1, 3), -t_A.reshape(-1), rcond=None)[0]
    q, p = extrinsic
    q_like, p_like = like
    between = (Rotation.from_quat(q_like) * Rotation.from_quat(q).inv()).as_quat()
    twist = Rotation.from_rotvec(2.0 * np.arctan2(between[:3] @ axis, between[3]) * axis)
    moved = twist.apply(np.asarray(p, dtype=float) - c) + c
    moved = moved + float((np.asarray(p_like) - moved) @ axis) * axis
    return (twist * Rotation.from_quat(q)).as_quat(), moved
