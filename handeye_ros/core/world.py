"""World alignment T_WG and the accuracy metrics of the calibrated eye trajectory.

Once T_HE and dt are known, the eye origin predicted from the MoCap is ``c_G = T_GH T_HE`` (in
G) and the VIO gives the same point in W. T_WG is the rigid transform that best maps the one
onto the other in the least-squares sense (Kabsch/Umeyama without scale, solved by
``scipy.spatial.transform.Rotation.align_vectors``). When the positions do not span a plane
(a rig turned in place), the positions cannot fix the rotation and it is taken from the
orientations instead (the chordal mean of ``R_WE (R_GH R_HE)^T``).

APE and ARE are the RMS of the translation (m) and rotation angle (deg) of
``(T_WG T_GH T_HE)^-1 T_WE`` over all pairs: how well the calibrated MoCap explains the VIO,
including the VIO's own drift.

When screening split the eye at VIO resets, each segment has its own VIO world: T_WG is found
per segment; the result reports the longest segment's, and the metrics use each segment's own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from .arrays import Floats, Indices
from .association import PosePairs
from .geometry import Pose, apply, compose, inverse, matrix_from_quat, rotation_angle, row_norms

#: Positions whose second principal spread is below this (metres RMS) do not fix a rotation.
MIN_PLANAR_SPREAD_M = 0.05


@dataclass(frozen=True)
class WorldAlignment:
    """T_WG: the MoCap world G expressed in the VIO world W, and how it was found."""

    R_WG: Floats
    p_WG: Floats
    method: str
    segment: int = 0
    segments: int = 1


@dataclass(frozen=True)
class Metrics:
    """Residuals of the eye trajectory against the calibrated hand trajectory.

    ape_rmse_m / are_rmse_deg: RMS position (m) and orientation (deg) error;
    ape_max_m / are_max_deg: their maxima; n_poses: pairs evaluated.
    motion_rotation_deg / motion_translation_m: median AX = XB error over the eye's keyframe
    motions (eq. 6; relative motions, so the VIO's drift does not enter);
    motion_length_m: their median translation; n_motions: how many.
    """

    ape_rmse_m: float
    are_rmse_deg: float
    ape_max_m: float
    are_max_deg: float
    n_poses: int
    motion_rotation_deg: float = float('nan')
    motion_translation_m: float = float('nan')
    motion_length_m: float = float('nan')
    n_motions: int = 0


def predicted_eye(pairs: PosePairs, X: Pose) -> Pose:
    """``T_GH T_HE`` for every pair: the eye pose predicted in the MoCap world G."""
    return compose((pairs.R_GH, pairs.p_GH), X)


def align_worlds(pairs: PosePairs, q_HE: Floats, p_HE: Floats) -> WorldAlignment:
    """Least-squares T_WG from the calibrated pairs of the longest eye segment (see module
    docstring)."""
    labels, counts = np.unique(pairs.segment, return_counts=True)
    longest = int(labels[np.argmax(counts)])
    out = _align_segment(pairs, pairs.segment == longest, q_HE, p_HE)
    return WorldAlignment(out.R_WG, out.p_WG, out.method, longest, int(labels.size))


def _align_segment(pairs: PosePairs, sel: Indices, q_HE: Floats, p_HE: Floats) -> WorldAlignment:
    X = (matrix_from_quat(q_HE), np.asarray(p_HE, dtype=float))
    R_GE, c_G = predicted_eye(pairs, X)
    R_GE, c_G = R_GE[sel], c_G[sel]
    c_W = pairs.p_WE[sel]
    mean_G, mean_W = c_G.mean(axis=0), c_W.mean(axis=0)
    # a segment of one or two pairs (a short piece between two eye breaks) spans no plane:
    # np.cov of one sample is NaN, so the spread is taken as the mean square directly
    d = c_G - mean_G
    spread = np.sqrt(
        np.clip(np.linalg.eigvalsh(d.T @ d / max(d.shape[0] - 1, 1))[::-1], 0.0, None)
    )
    if d.shape[0] >= 3 and spread[1] >= MIN_PLANAR_SPREAD_M:
        R_WG, p_WG = rigid_fit(c_G, c_W)
        return WorldAlignment(R_WG, p_WG, 'positions')
    R_WG = (
        Rotation.from_matrix(np.matmul(pairs.R_WE[sel], np.swapaxes(R_GE, -1, -2)))
        .mean()
        .as_matrix()
    )
    return WorldAlignment(R_WG, mean_W - R_WG @ mean_G, 'orientations')


def rigid_fit(points_a: Floats, points_b: Floats) -> Pose:
    """The rotation and translation (R, p) that best map ``points_a`` (N, 3) onto ``points_b``
    in the least-squares sense: Kabsch/Umeyama without scale (``b ~ R a + p``)."""
    mean_a, mean_b = points_a.mean(axis=0), points_b.mean(axis=0)
    rot, _ = Rotation.align_vectors(points_b - mean_b, points_a - mean_a)
    R = rot.as_matrix()
    return R, mean_b - R @ mean_a


def metrics_of(pairs: PosePairs, q_HE: Floats, p_HE: Floats, world: WorldAlignment) -> Metrics:
    """APE/ARE of the eye poses against ``T_WG T_GH T_HE`` (see module docstring), each eye
    segment against its own T_WG (``world`` is the longest segment's)."""
    X = (matrix_from_quat(q_HE), np.asarray(p_HE, dtype=float))
    pred = compose(worlds_per_pair(pairs, q_HE, p_HE, world), predicted_eye(pairs, X))
    R_err, p_err = compose(inverse(pred), (pairs.R_WE, pairs.p_WE))
    # Translation error measured in W (not in the predicted body frame): the usual APE.
    e_t = row_norms(apply(pred[0], p_err))
    e_r = np.degrees(rotation_angle(R_err))
    return Metrics(
        float(np.sqrt(np.mean(e_t**2))),
        float(np.sqrt(np.mean(e_r**2))),
        float(e_t.max()),
        float(e_r.max()),
        int(e_t.size),
    )


def worlds_per_pair(pairs: PosePairs, q_HE: Floats, p_HE: Floats, world: WorldAlignment) -> Pose:
    """T_WG for every pair: ``world`` on its own segment, each other eye segment aligned on its
    own pairs (a VIO reset starts a new world W). Shapes (N, 3, 3), (N, 3)."""
    R_WG = np.empty((pairs.segment.size, 3, 3))
    p_WG = np.empty((pairs.segment.size, 3))
    for label in np.unique(pairs.segment):
        sel = pairs.segment == label
        w = world if label == world.segment else _align_segment(pairs, sel, q_HE, p_HE)
        R_WG[sel], p_WG[sel] = w.R_WG, w.p_WG
    return R_WG, p_WG
