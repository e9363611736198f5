"""Pose pairs at common instants, given the time offset.

For each sample of the sparser stream, the denser stream is interpolated at the same instant
(positions linearly, orientations by SLERP), so no pair mixes two instants and the sparser
stream, usually the noisier VIO, is never interpolated. Instants that fall outside the other
stream or inside one of its gaps are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .arrays import Floats, Indices, Mask, Stamps
from .chunked import chunked
from .errors import NoOverlapError
from .geometry import (
    Pose,
    compose,
    inverse,
    matrix_from_quat,
    quat_slerp,
    relative,
    rotation_angle,
    row_norms,
)
from .trajectory import Trajectory

#: Fewer matched pairs than this cannot support keyframes, RANSAC and a world alignment.
MIN_PAIRS = 20


@dataclass(frozen=True)
class PosePairs:
    """Hand and eye poses at the same physical instants.

    Attributes
    ----------
    t_eye_s : ndarray, shape (N,)
        Instants on the eye clock, seconds from the eye origin ``origin_ns``.
    R_GH, p_GH : ndarray, shapes (N, 3, 3), (N, 3)
        Hand (marker) poses in the MoCap world G, at ``t_eye - dt`` on the hand clock.
    R_WE, p_WE : ndarray, shapes (N, 3, 3), (N, 3)
        Eye (body) poses in the VIO world W.
    segment : ndarray of int, shape (N,)
        The eye segment (between breaks) each pair belongs to: no relative pose may join two
        segments, whose VIO worlds differ.
    """

    t_eye_s: Floats
    R_GH: Floats
    p_GH: Floats
    R_WE: Floats
    p_WE: Floats
    segment: Indices


def interpolate(traj: Trajectory, t_ns: Stamps) -> tuple[Floats, Floats, Mask]:
    """Poses of ``traj`` at stamps ``t_ns`` (int64 ns, any order).

    Returns rotation matrices (M, 3, 3), positions (M, 3) and a mask (M,) that is False outside
    the trajectory's span or inside one of its gaps or breaks (:meth:`Trajectory.interval_ok`).
    """
    origin = int(traj.t_ns[0])
    ts = traj.seconds(origin)
    tq = (np.asarray(t_ns, dtype=np.int64) - np.int64(origin)).astype(float) * 1e-9
    k = np.searchsorted(ts, tq, side='right')
    inside = (tq >= ts[0]) & (tq <= ts[-1])
    kc = np.clip(k, 1, ts.size - 1)
    ok = inside & traj.interval_ok()[kc - 1]
    a = kc[ok] - 1
    f = (tq[ok] - ts[a]) / (ts[a + 1] - ts[a])
    R = np.tile(np.eye(3), (tq.size, 1, 1))
    p = np.zeros((tq.size, 3))
    q = traj.q_xyzw
    R[ok] = chunked(lambda s: matrix_from_quat(quat_slerp(q[a[s]], q[a[s] + 1], f[s])), a.size)
    p[ok] = traj.p_xyz[a] + f[:, None] * (traj.p_xyz[a + 1] - traj.p_xyz[a])
    return R, p, ok


def associate(hand: Trajectory, eye: Trajectory, time_offset_s: float) -> PosePairs:
    """Pairs ``(T_GH(t - dt), T_WE(t))`` at the stamps of the sparser stream.

    Raises :class:`TimeAlignmentError` when fewer than MIN_PAIRS instants are covered by both.
    """
    if eye.rate_hz <= hand.rate_hz:
        pairs, _ = pairs_at_eye(hand, eye, time_offset_s)
        _check_overlap(pairs.t_eye_s.size, hand, eye, time_offset_s)
        return pairs
    # the eye is the denser stream: interpolated at the hand's stamps
    dt_ns = np.int64(round(time_offset_s * 1e9))
    R_WE, p_WE, ok = interpolate(eye, hand.t_ns + dt_ns)
    R_GH, p_GH = matrix_from_quat(hand.q_xyzw[ok]), hand.p_xyz[ok]
    R_WE, p_WE, t_eye_ns = R_WE[ok], p_WE[ok], hand.t_ns[ok] + dt_ns
    # the segment of the eye pose before each instant (no instant lies inside a break)
    seg = eye.segment_ids()[
        np.clip(np.searchsorted(eye.t_ns, t_eye_ns, side='right') - 1, 0, len(eye) - 1)
    ]
    _check_overlap(t_eye_ns.size, hand, eye, time_offset_s)
    return PosePairs(_seconds(t_eye_ns), R_GH, p_GH, R_WE, p_WE, seg)


def pairs_at_eye(
    hand: Trajectory, eye: Trajectory, time_offset_s: float
) -> tuple[PosePairs, Mask]:
    """Pairs ``(T_GH(t - dt), T_WE(t))`` at every eye stamp the hand covers, and the mask (N,)
    of those eye poses (no check of how many there are)."""
    dt_ns = np.int64(round(time_offset_s * 1e9))
    R_GH, p_GH, ok = interpolate(hand, eye.t_ns - dt_ns)
    pairs = PosePairs(
        _seconds(eye.t_ns[ok]),
        R_GH[ok],
        p_GH[ok],
        matrix_from_quat(eye.q_xyzw[ok]),
        eye.p_xyz[ok],
        eye.segment_ids()[ok],
    )
    return pairs, ok


def _seconds(t_ns: Stamps) -> Floats:
    return (t_ns - t_ns[0]).astype(float) * 1e-9 if t_ns.size else np.zeros(0)


def _check_overlap(n: int, hand: Trajectory, eye: Trajectory, time_offset_s: float) -> None:
    if n < MIN_PAIRS:
        msg = (
            f'after applying the time offset {time_offset_s:+.4f} s only {n} '
            f'instants of {eye.name} fall inside {hand.name} (need {MIN_PAIRS}): the streams '
            'overlap too little in time'
        )
        raise NoOverlapError(msg)


def eye_motion_residuals(
    hand: Trajectory,
    eye: Trajectory,
    i: Indices,
    j: Indices,
    time_offset_s: float,
    T_HE: Pose,
) -> tuple[Floats, Floats, Mask]:
    """``(T_HE^-1 A T_HE)^-1 B`` for each eye motion ``B = T_WE_i^-1 T_WE_j``, with
    ``A = T_GH(t_i - dt)^-1 T_GH(t_j - dt)`` the hand's motion over the same instants
    (AX = XB, eq. 2), in the eye frame.

    Parameters
    ----------
    i, j : ndarray of int, shape (M,)
        Eye pose indices of the motions.
    time_offset_s : float
        dt (s): the eye's instant t is the hand's t - dt.
    T_HE : (R_HE (3, 3), p_HE (3,) m)
        The extrinsic X.

    Returns
    -------
    err_R, err_p : ndarray, shapes (M, 3, 3), (M, 3)
        The residual motion's rotation and translation (m).
    covered : ndarray of bool, shape (M,)
        Whether the hand covers both instants (the residuals are meaningless elsewhere).
    """
    dt_ns = np.int64(round(time_offset_s * 1e9))
    R_h, p_h, ok = interpolate(hand, eye.t_ns - dt_ns)
    X = (np.asarray(T_HE[0], dtype=float), np.asarray(T_HE[1], dtype=float))
    A = relative((R_h, p_h), i, j)
    B = relative((matrix_from_quat(eye.q_xyzw), eye.p_xyz), i, j)
    err_R, err_p = residual_motions(A, B, X)
    return err_R, err_p, ok[i] & ok[j]


def residual_motions(A: Pose, B: Pose, X: Pose) -> tuple[Floats, Floats]:
    """``(X^-1 A X)^-1 B`` for hand motions A, eye motions B (rotations (M, 3, 3), translations
    (M, 3)) and the extrinsic X = T_HE: the motion by which AX = XB (eq. 2) fails, in the eye
    frame."""
    return compose(inverse(compose(compose(inverse(X), A), X)), B)


def eye_motion_errors(
    hand: Trajectory,
    eye: Trajectory,
    i: Indices,
    j: Indices,
    time_offset_s: float,
    T_HE: Pose,
) -> tuple[Floats, Floats, Mask]:
    """How far each eye motion is from the hand's (:func:`eye_motion_residuals`): the rotation
    angle (rad) and the translation norm (m) of the residual motion, and ``covered``."""
    err_R, err_p, covered = eye_motion_residuals(hand, eye, i, j, time_offset_s, T_HE)
    return rotation_angle(err_R), row_norms(err_p), covered
