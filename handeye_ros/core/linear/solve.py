"""Stage 2 at one offset (Section III-B): the streams associated at dt, the keyframe motions
(eq. 6) and the robust dual-quaternion solve (eq. 12-13, Algorithm 1) with the options of a
:class:`~handeye_ros.core.config.CalibrationConfig`."""

from __future__ import annotations

import numpy as np

from ..association import PosePairs, associate
from ..config import CalibrationConfig
from ..trajectory import Trajectory
from .axxb import build_motions
from .robust import LinearSolution, calibrate_linear


def solve_linear(
    hand: Trajectory,
    eye: Trajectory,
    dt: float,
    cfg: CalibrationConfig,
    seed: int | None = None,
) -> tuple[LinearSolution, PosePairs]:
    """Stage 2 at offset dt: its solution and the streams associated there."""
    pairs = associate(hand, eye, dt)
    motions = build_motions(pairs, cfg.relative_poses, np.deg2rad(cfg.eta))
    lin = calibrate_linear(
        motions,
        robust_kernel=cfg.robust_kernel,
        mu=cfg.mu,
        ransac_iterations=cfg.ransac_iterations,
        inlier_rotation_rad=np.deg2rad(cfg.inlier_rotation),
        inlier_translation_m=cfg.inlier_translation,
        min_motions=cfg.min_motions,
        adaptive_inliers=cfg.adaptive_inliers,
        decoupled_refit=cfg.decoupled_refit,
        estimate_scale=cfg.estimate_scale,
        rng=np.random.default_rng(cfg.seed if seed is None else seed),
    )
    return lin, pairs
