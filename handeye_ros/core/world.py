"""World alignment T_WG and the accuracy metrics of the calibrated eye trajectory.

Once T_HE and dt are known, the eye origin predicted from the MoCap is ``c_G = T_GH T_HE`` (in
G) and the VIO gives the same point in W. T_WG is the rigid transform that best maps the one
onto the other in the least-squares sense (Kabsch/Umeyama without scale, solved by
``scipy.spatial.transform.Rotation.align_vectors``) when the positions span at least twice
MIN_PLANAR_SPREAD_M in a plane (their second principal spread, RMS), as evo's ``--align`` does.
Positions that span less than MIN_PLANAR_SPREAD_M (a rig turned in place, a turntable's circle of
a few centimetres beside a VIO's drift of as many) cannot fix the rotation, and it is taken from
the orientations (the chordal mean of ``R_WE (R_GH R_HE)^T``). Between the two spreads the
rotation moves from the one to the other along the geodesic, in proportion: T_WG so moves
continuously with the calibration, as the figures' error bars (draws of the calibration) need.

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
from .geometry import (
    Extrinsic,
    Pose,
    apply,
    compose,
    inverse,
    matrix_from_quat,
    rotation_angle,
    row_norms,
)

#: Positions whose second principal spread is below this (metres RMS) do not fix a rotation;
#: from twice it they fix it alone (module docstring).
MIN_PLANAR_SPREAD_M = 0.05


@dataclass(frozen=True)
class WorldAlignment:
    """T_WG: the MoCap world G expressed in the VIO world W, and what fixed its rotation
    (``method``: 'positions' when they span at least twice MIN_PLANAR_SPREAD_M in a plane,
    else 'orientations', alone or with the positions)."""

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


def _predicted(pairs: PosePairs, sel: Indices, extrinsic: Extrinsic) -> Pose:
    """:func:`predicted_eye` of the pairs ``sel`` at T_HE = ``extrinsic`` (x y z w, m)."""
    q_HE, p_HE = extrinsic
    X = (matrix_from_quat(q_HE), np.asarray(p_HE, dtype=float))
    # the segment's pairs alone: worlds_per_pair asks once a segment, and a VI-SLAM run has
    # dozens of segments
    return compose((pairs.R_GH[sel], pairs.p_GH[sel]), X)


def align_worlds(
    pairs: PosePairs, q_HE: Floats, p_HE: Floats, spread_at: Extrinsic | None = None
) -> WorldAlignment:
    """Least-squares T_WG from the calibrated pairs of the longest eye segment (see module
    docstring). ``spread_at``: the T_HE (x y z w, m) whose predicted positions' spread weighs
    the positions against the orientations, when not T_HE itself (the reported calibration,
    for draws about it: the weighing is then the same in every draw)."""
    labels, counts = np.unique(pairs.segment, return_counts=True)
    longest = int(labels[np.argmax(counts)])
    out = _align_segment(pairs, pairs.segment == longest, (q_HE, p_HE), spread_at)
    return WorldAlignment(out.R_WG, out.p_WG, out.method, longest, int(labels.size))


def _align_segment(
    pairs: PosePairs, sel: Indices, extrinsic: Extrinsic, spread_at: Extrinsic | None
) -> WorldAlignment:
    R_GE, c_G = _predicted(pairs, sel, extrinsic)
    c_W, R_WE = pairs.p_WE[sel], pairs.R_WE[sel]
    mean_G, mean_W = c_G.mean(axis=0), c_W.mean(axis=0)
    spread = _second_spread(c_G if spread_at is None else _predicted(pairs, sel, spread_at)[1])
    # 0: the orientations' rotation, 1: the positions'
    toward_positions = float(np.clip(spread / MIN_PLANAR_SPREAD_M - 1.0, 0.0, 1.0))
    if toward_positions == 1.0:
        R_WG, p_WG = rigid_fit(c_G, c_W)
        return WorldAlignment(R_WG, p_WG, 'positions')
    by_orientations = Rotation.from_matrix(np.matmul(R_WE, np.swapaxes(R_GE, -1, -2))).mean()
    blend = by_orientations
    if toward_positions > 0.0:
        by_positions = Rotation.from_matrix(rigid_fit(c_G, c_W)[0])
        step = (by_orientations.inv() * by_positions).as_rotvec()
        blend = by_orientations * Rotation.from_rotvec(toward_positions * step)
    R_WG = blend.as_matrix()
    return WorldAlignment(R_WG, mean_W - R_WG @ mean_G, 'orientations')


def _second_spread(points: Floats) -> float:
    """The second principal spread (m RMS) of ``points`` (N, 3): how far they span a plane;
    zero for fewer than three (a short piece between two eye breaks spans none)."""
    if points.shape[0] < 3:
        return 0.0
    d = points - points.mean(axis=0)
    return float(np.sqrt(max(np.linalg.eigvalsh(d.T @ d / (d.shape[0] - 1))[1], 0.0)))


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


def worlds_per_pair(
    pairs: PosePairs,
    q_HE: Floats,
    p_HE: Floats,
    world: WorldAlignment,
    spread_at: Extrinsic | None = None,
) -> Pose:
    """T_WG for every pair: ``world`` on its own segment, each other eye segment aligned on its
    own pairs (a VIO reset starts a new world W; ``spread_at`` as :func:`align_worlds` has
    it). Shapes (N, 3, 3), (N, 3)."""
    R_WG = np.empty((pairs.segment.size, 3, 3))
    p_WG = np.empty((pairs.segment.size, 3))
    for label in np.unique(pairs.segment):
        sel = pairs.segment == label
        w = (
            world
            if label == world.segment
            else _align_segment(pairs, sel, (q_HE, p_HE), spread_at)
        )
        R_WG[sel], p_WG[sel] = w.R_WG, w.p_WG
    return R_WG, p_WG
