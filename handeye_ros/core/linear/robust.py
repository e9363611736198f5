"""Stage 2: robust linear hand-eye calibration AX = XB with dual quaternions (Section III-B).

Robustness on top of the dual-quaternion algebra of :mod:`.linear.axxb` (eq. 2-13): the
screw-congruence kernel weights (eq. 11-12) and RANSAC on 2-motion subsets scored by
``sigma7 / sigma6`` (Algorithm 1), with inlier thresholds adapted to the measured noise, the
degenerate one-axis case and the optional scale.

One step beyond the paper, on by default (``decoupled_refit``): on the final consensus, the
extrinsic is re-estimated with rotation and translation apart. The rotation aligns the rotation
vectors of the inlier motions; the translation solves ``(R_A - I) t_X = R_X t_B - t_A`` by
least squares weighted for a drifting eye (:mod:`.linear.refits`).
Why: in the dual-quaternion system the rotation also has to satisfy the dual rows, which carry
the eye's translation error; a VIO's relative translations are far noisier than its relative
rotations, so that error leaks into the rotation. On the real flights of bench/real_cases.py
the rotation error drops from 0.4-1.7 deg to 0.03-0.5 deg, and on the paper's protocol at
level 10 from 0.82 to 0.47 deg (bench/simulated.py). The dual-quaternion solution is kept in the
result. The kernel and the inlier test are the paper's; two more departures are disclosed in
docs/method.md: the singular values come from the eigendecomposition of ``M^T M`` (batched 8x8
Gram matrices, never M itself), and a RANSAC refinement is eligible for the sigma7/sigma6
choice only when its consensus holds at least ``CONSENSUS_FRACTION`` of the largest one and,
where any eligible consensus spreads its rotation axes, only one that does
(:func:`.ransac.well_spread`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..arrays import Floats, Mask
from ..errors import TooFewMotionsError
from ..geometry import matrix_from_quat
from .axxb import (
    Motions,
    constraint_gram,
    motion_errors,
    scaled_motions,
    screw_log_weights,
)
from .ransac import Consensus, System, consensus, widened_consensus
from .refits import (
    MIN_AXIS_SPREAD_DEG,
    WARN_AXIS_SPREAD_DEG,
    axis_spread_deg,
    degenerate_refit,
    drift_weights,
    refit_rotation,
    refit_translation_gls,
)
from .scale import dual_quaternion_scale, translation_and_scale


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
        RMS of the inlier criteria (eq. 13) over the inliers at the solution.
    inlier_rotation_deg, inlier_translation_m : float
        Inlier thresholds of the final consensus (the configured ones, or wider when adapted to
        the measured noise).
    warnings : tuple of str
    unobservable : tuple of str
        Components of T_HE the motion cannot determine (one rotation axis), in words, with the
        value they were given; empty when the motion determines all of them.
    held_axis : ndarray, shape (3,), or None
        The only rotation axis (unit, hand frame) of a motion about one axis: the translation
        of T_HE along it is undetermined, and stage 3 holds it.
    held_rotation : bool
        The rotation of T_HE about that axis is undetermined too (a rig turned in place, not
        driven): stage 3 holds it as well.
    scale, scale_std, scale_dq : float
        With ``estimate_scale``: the factor s that makes the eye's translations metric (on top
        of any the eye already had), its least-squares standard deviation, and the
        dual-quaternion path's s (:mod:`.linear.scale`); 1, NaN, 1 otherwise.
    motions : Motions or None
        The motions the solution was found on (eye made metric by ``scale``), in the order of
        ``inliers``: for plots and diagnostics.
    """

    q_HE: Floats
    p_HE: Floats
    q_HE_dq: Floats
    p_HE_dq: Floats
    sigma_ratio: float
    singular_values: Floats
    n_motions: int
    n_inliers: int
    inliers: Mask
    axis_spread_deg: float
    rotation_residual_deg: float
    translation_residual_m: float
    inlier_rotation_deg: float
    inlier_translation_m: float
    warnings: tuple[str, ...] = ()
    unobservable: tuple[str, ...] = ()
    held_axis: Floats | None = None
    held_rotation: bool = False
    scale: float = 1.0
    scale_std: float = float('nan')
    scale_dq: float = 1.0
    motions: Motions | None = field(default=None, repr=False, compare=False)


def _check_enough(n: int, min_motions: int) -> None:
    """TooFewMotionsError unless there are ``min_motions`` (at least 2) motions."""
    if n < max(min_motions, 2):
        raise TooFewMotionsError(
            f'only {n} relative motions could be built (need {max(min_motions, 2)}): the '
            'recording rotates too little for the keyframe rule. Rotate the rig more (about '
            'several axes), or lower eta'
        )


def _squared_weights(m: Motions, mu: float, dual: bool) -> Floats:
    """The robust kernel's weights (eq. 11) squared, scaled to a largest of 1 (the rows of
    eq. 12 carry W, their Gram matrices W^2); ``dual``: E compares the screws' translations
    too (:func:`.axxb.screw_log_weights`)."""
    log_w = screw_log_weights(m, mu, dual)
    out: Floats = np.exp(2.0 * (log_w - log_w.max()))
    return out


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

    Then ``adaptive_inliers`` widens the consensus to the noise measured from the winner
    (:func:`.ransac.widened_consensus`), and the extrinsic is refitted on it (:func:`_refit`:
    ``decoupled_refit``, one rotation axis, ``estimate_scale``).

    Raises
    ------
    TooFewMotionsError, NoConsensusError (DegenerateMotionError)
        With fewer than ``min_motions`` motions; when no hypothesis gathers a consensus.
    """
    n = len(m)
    _check_enough(n, min_motions)
    rng = rng if rng is not None else np.random.default_rng(0)
    # about one axis (its hand axes spread less than MIN_AXIS_SPREAD_DEG: a ground robot, a
    # turntable) the screws' translations along it are 0, their ratio noise over noise
    dual = axis_spread_deg(m, np.ones(n, dtype=bool)) >= MIN_AXIS_SPREAD_DEG
    w2 = _squared_weights(m, mu, dual) if robust_kernel else np.ones(n)
    system = System(m, constraint_gram(m).reshape(n, 64), w2)
    thresholds = (inlier_rotation_rad, inlier_translation_m)
    won = consensus(system, ransac_iterations, thresholds, rng)
    if adaptive_inliers:
        thresholds, wider = widened_consensus(system, won, thresholds)
        won = won if wider is None else wider
    spread = axis_spread_deg(m, won.inliers)
    refit = _refit(m, won, spread, decoupled_refit, estimate_scale)
    return _solution(m, refit, won, spread, thresholds)


@dataclass(frozen=True)
class _Refit:
    """What :func:`_refit` found on the consensus: the extrinsic (q_HE, p_HE) and the
    dual-quaternion solution's (q_dq, p_dq), what is unobservable, the warnings, and the eye's
    scale with its dual-quaternion value and standard deviation (1, 1 and NaN without one)."""

    q_HE: Floats
    p_HE: Floats
    q_dq: Floats
    p_dq: Floats
    unobservable: tuple[str, ...]
    warnings: tuple[str, ...]
    scale: float
    scale_dq: float
    scale_std: float
    held_axis: Floats | None
    held_rotation: bool


def _solution(
    m: Motions, refit: _Refit, won: Consensus, spread: float, thresholds: tuple[float, float]
) -> LinearSolution:
    """The stage's answer from the refit on the consensus ``won`` (its rotation axes spread
    ``spread`` deg), with the inlier criteria of eq. 13 (``thresholds``: rotation [rad],
    translation [m]) at it (on the eye made metric when a scale was estimated)."""
    inliers = won.inliers
    if refit.scale != 1.0:
        m = scaled_motions(m, refit.scale)
    e_rot, e_trans = motion_errors(m, refit.q_HE[None], refit.p_HE[None])
    return LinearSolution(
        q_HE=refit.q_HE,
        p_HE=refit.p_HE,
        q_HE_dq=refit.q_dq,
        p_HE_dq=refit.p_dq,
        sigma_ratio=won.sigma_ratio,
        singular_values=won.singular_values,
        n_motions=len(m),
        n_inliers=int(inliers.sum()),
        inliers=inliers,
        axis_spread_deg=spread,
        rotation_residual_deg=float(np.degrees(np.sqrt(np.mean(e_rot[0, inliers] ** 2)))),
        translation_residual_m=float(np.sqrt(np.mean(e_trans[0, inliers] ** 2))),
        inlier_rotation_deg=float(np.degrees(thresholds[0])),
        inlier_translation_m=float(thresholds[1]),
        warnings=refit.warnings,
        unobservable=refit.unobservable,
        held_axis=refit.held_axis,
        held_rotation=refit.held_rotation,
        scale=refit.scale,
        scale_std=refit.scale_std,
        scale_dq=refit.scale_dq,
        motions=m,
    )


def _refit(
    m: Motions, won: Consensus, spread: float, decoupled_refit: bool, estimate_scale: bool
) -> _Refit:
    """The final extrinsic on the consensus ``won``, whose rotation axes spread ``spread`` deg
    (:class:`_Refit`).

    With ``decoupled_refit`` it is re-estimated with rotation (:func:`refit_rotation`) and
    translation (:func:`refit_translation_gls`) apart; otherwise the dual-quaternion solution
    is the result. Either way the dual-quaternion solution is kept (q_dq, p_dq). When the
    rotation axes of the consensus are all parallel (one rotation axis), the determined part of
    T_HE comes from :func:`degenerate_refit` and ``unobservable`` names the rest.

    ``estimate_scale``: the eye's translations are metric only up to a factor s (a monocular
    eye, :mod:`.scale`); both refits then solve for it: the translation refit in (t_X, s), the
    dual-quaternion one in (q', s) with its rotation fixed. RANSAC's thresholds in metres need
    the eye near metric already (the pipeline scales it by :func:`.scale.scale_prior` first).
    """
    inliers, q_HE, p_HE = won.inliers, won.q_HE, won.p_HE
    q_dq, p_dq = q_HE, p_HE
    unobservable: tuple[str, ...] = ()
    held_axis, held_rotation = None, False
    warnings: list[str] = []
    scale = scale_dq = 1.0
    scale_std = float('nan')
    if estimate_scale and spread >= MIN_AXIS_SPREAD_DEG:
        p_dq, scale_dq = _dual_quaternion_scale(m, inliers, q_dq, p_HE)
        if not decoupled_refit:
            p_HE, scale = p_dq, scale_dq
    if spread < MIN_AXIS_SPREAD_DEG:
        # one rotation axis: the dual-quaternion system has a 3-D null space and picks an
        # arbitrary point of it; the determined part is solved apart and the rest named
        q_HE, p_HE, unobservable, held_axis, held_rotation = degenerate_refit(m, inliers)
        warnings.append(
            f'the rotation axes of the {inliers.sum()} inlier motions are within '
            f'{spread:.2f} deg of one direction, so part of the extrinsic cannot be '
            'observed: ' + '; '.join(unobservable) + '. Rotate the rig about at '
            'least two different axes to determine it'
        )
    elif decoupled_refit:
        q_HE, p_HE, scale, scale_std = _decoupled(m, inliers, q_dq, estimate_scale)
    if MIN_AXIS_SPREAD_DEG <= spread < WARN_AXIS_SPREAD_DEG:
        warnings.append(
            f'rotation axes spread only {spread:.1f} deg: the extrinsic is weakly '
            'constrained; rotate about more different axes'
        )
    return _Refit(
        q_HE,
        p_HE,
        q_dq,
        p_dq,
        unobservable,
        tuple(warnings),
        scale,
        scale_dq,
        scale_std,
        held_axis,
        held_rotation,
    )


def _dual_quaternion_scale(
    m: Motions, inliers: Mask, q_dq: Floats, p_HE: Floats
) -> tuple[Floats, float]:
    """The paper's baseline with a scale: the rotation of the dual-quaternion solution, then its
    dual part and s from the lower rows of eq. 4 (:func:`.scale.dual_quaternion_scale`); the
    translation ``p_HE`` and s = 1 when that gives no positive finite s."""
    p_dq, scale_dq = dual_quaternion_scale(
        m.qa[inliers],
        m.qad[inliers],
        m.qb[inliers],
        m.qbd[inliers],
        q_dq,
        drift_weights(m, inliers),
    )
    if not (np.isfinite(scale_dq) and scale_dq > 0.0):
        return p_HE, 1.0
    return p_dq, scale_dq


def _decoupled(
    m: Motions, inliers: Mask, q_dq: Floats, estimate_scale: bool
) -> tuple[Floats, Floats, float, float]:
    """The decoupled refit: the rotation from the motions' rotation vectors
    (:func:`.refits.refit_rotation`, in q_dq's hemisphere), then the translation (and the
    scale, when estimated and observable) by weighted least squares: (q_HE, p_HE, s, std of
    s; 1 and NaN without a scale)."""
    q_HE = refit_rotation(m, inliers)
    q_HE *= 1.0 if float(np.dot(q_HE, q_dq)) >= 0.0 else -1.0  # same hemisphere as before
    R_HE = matrix_from_quat(q_HE)
    fit = (
        translation_and_scale(
            m.A[0][inliers], m.A[1][inliers], m.B[1][inliers], R_HE, drift_weights(m, inliers)
        )
        if estimate_scale
        else None
    )
    scale_std = fit.scale_std if fit is not None else float('nan')
    if fit is not None and fit.observable:
        return q_HE, fit.p_HE, fit.scale, scale_std
    # no scale, or an unobservable one (the pipeline's verdict names it)
    return q_HE, refit_translation_gls(m, inliers, R_HE), 1.0, scale_std
