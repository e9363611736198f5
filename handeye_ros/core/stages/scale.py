"""The eye's scale, as the pipeline uses it: with ``estimate_scale`` a first scale from the
rotations before stage 2 and stage 2's on top of it; without it, the translation fit with and
without a scale, to name an eye whose translations a scale explains (:mod:`.scale` holds the
fits, :class:`~handeye_ros.core.eye_model.EyeModel` applies them)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..association import PosePairs, associate
from ..checks.verdict import Findings
from ..config import CalibrationConfig
from ..eye_model import EyeModel
from ..geometry import matrix_from_quat
from ..linear.axxb import build_motions
from ..linear.refits import drift_weights
from ..linear.robust import LinearSolution, calibrate_linear
from ..linear.scale import ScaleFit, observable, scale_prior, translation_and_scale
from ..trajectory import Trajectory


def scale_from_rotations(
    hand: Trajectory, eye: Trajectory, model: EyeModel, cfg: CalibrationConfig
) -> tuple[Trajectory, EyeModel]:
    """With estimate_scale, before stage 2: a first scale (:func:`rotations_scale`), so that
    stage 2's thresholds in metres mean metres."""
    fit = rotations_scale(hand, eye, cfg)
    if fit is None:
        return eye, model
    if not fit.observable:  # the eye stays as it is; the verdict will say why
        return eye, replace(model, scale_std=fit.scale_std, scale_estimated=True)
    return model.add_scale(eye, fit.scale, fit.scale_std)


def rotations_scale(hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig) -> ScaleFit | None:
    """The eye's scale (:func:`.linear.scale.scale_prior`) at the rotation of T_HE that the
    rotations alone give (RANSAC with no translation threshold): it needs no threshold in
    metres, so it holds whatever units the positions are in. None when the rotations leave
    T_HE's rotation unobservable."""
    pairs = associate(hand, eye, 0.0)
    m = build_motions(pairs, cfg.relative_poses, np.deg2rad(cfg.eta))
    rot = calibrate_linear(
        m,
        robust_kernel=False,
        ransac_iterations=cfg.ransac_iterations,
        inlier_rotation_rad=np.deg2rad(cfg.inlier_rotation),
        inlier_translation_m=np.inf,
        min_motions=cfg.min_motions,
        adaptive_inliers=False,
        decoupled_refit=True,
        rng=np.random.default_rng(cfg.seed),
    )
    if rot.unobservable:
        return None
    k = rot.inliers
    return scale_prior(m.A[0][k], m.A[1][k], m.B[1][k], rot.q_HE, drift_weights(m, k))


def fold_linear_scale(
    eye: Trajectory, model: EyeModel, lin: LinearSolution
) -> tuple[Trajectory, EyeModel, Findings]:
    """Stage 2's scale (on top of the first one) into the eye, whose translations its T_HE
    assumes; a note when its two paths disagree."""
    if not model.scale_observable or not observable(lin.scale, lin.scale_std):
        std = lin.scale_std * model.scale if np.isfinite(lin.scale_std) else np.inf
        return eye, replace(model, scale_std=max(std, model.scale_std)), Findings()
    found = Findings()
    if lin.scale_dq > 0 and abs(lin.scale_dq / lin.scale - 1.0) > 0.05:
        found = Findings.of(
            f'the dual-quaternion path gives a scale {lin.scale_dq:.4f} against '
            f"the translation refit's {lin.scale:.4f} (relative to the first "
            'estimate)'
        )
    return *model.add_scale(eye, lin.scale, model.scale * lin.scale_std), found


def scale_check(pairs: PosePairs, lin: LinearSolution, cfg: CalibrationConfig) -> ScaleFit | None:
    """Without estimate_scale: the translation part of AX = XB fitted with and without a scale
    (all motions, Huber loss), to name an eye whose translations a scale explains."""
    if lin.unobservable:
        return None
    m = build_motions(pairs, cfg.relative_poses, np.deg2rad(cfg.eta))
    if len(m) < cfg.min_motions:
        return None
    every = np.ones(len(m), bool)
    return translation_and_scale(
        m.A[0], m.A[1], m.B[1], matrix_from_quat(lin.q_HE), drift_weights(m, every), robust=True
    )
