"""Algorithm 1's loop (Section III-B): RANSAC on 2-motion subsets of AX = XB, each hypothesis'
consensus re-solved with the robust kernel weights (eq. 12) and scored by sigma7/sigma6, the
best one chosen; then its consensus widened to the noise measured from it.

:mod:`.linear.robust` runs it and refits the extrinsic on the consensus it returns.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import Floats, Mask
from ..errors import NoConsensusError
from ..geometry import pose_from_dual_quat
from .axxb import Motions, motion_errors, sigma_ratio, solve_gram
from .refits import MIN_AXIS_SPREAD_DEG, WARN_AXIS_SPREAD_DEG, axis_spreads_deg, rotation_axes

#: A RANSAC model is eligible only if its consensus holds at least this fraction of the largest
#: consensus found: sigma7/sigma6 of a tiny subset is small by chance, not by quality.
CONSENSUS_FRACTION = 0.5
#: Hypotheses scored at once by RANSAC (bounds its memory: a chunk's errors are this many
#: hypotheses times the motions).
RANSAC_CHUNK_ELEMENTS = 4_000_000
#: Ratio of the 99 % quantile to the median of a chi distribution with 3 degrees of freedom
#: (3.368 / 1.538): the error norms of eq. 13 of inlier motions are roughly chi-3 distributed, so
#: this times their median is a threshold that keeps 99 % of the inliers at the measured noise.
CHI3_Q99_OVER_MEDIAN = 2.19


@dataclass(frozen=True)
class System:
    """The motions of eq. 2 as Algorithm 1 solves them: m, each motion's Gram matrix of its 6x8
    block of eq. 4 flattened (``gram``, (M, 64)), and the robust kernel's weights squared (``w2``,
    (M,), eq. 12)."""

    m: Motions
    gram: Floats
    w2: Floats

    def solve(self, inliers: Mask) -> tuple[Floats, Floats, Floats]:
        """(q, q', singular values) of the weighted system on the motions ``inliers`` (bool,
        (M,))."""
        return solve_gram(((inliers * self.w2) @ self.gram).reshape(8, 8))


@dataclass(frozen=True)
class Consensus:
    """A solution of Algorithm 1: T_HE (q_HE x y z w, p_HE [m]), the motions it holds
    (``inliers``, bool (M,)), the singular values of its system and their sigma7/sigma6."""

    q_HE: Floats
    p_HE: Floats
    inliers: Mask
    singular_values: Floats
    sigma_ratio: float


def _ransac(
    system: System, iterations: int, thresholds: tuple[float, float], rng: np.random.Generator
) -> tuple[Floats, Floats, Floats, Floats, Floats, tuple[Floats, Floats]]:
    """Algorithm 1's loop: per 2-motion hypothesis, its consensus size, the robust re-solve on
    that consensus (q, qd, sigma7/sigma6), evaluated in chunks so that memory does not grow
    with the number of hypotheses; ``thresholds``: eq. 13's (rotation [rad], translation [m]).
    Returns (counts, q1, qd1, ratio, the consensus' rotation axis spread [deg], hypotheses'
    (q0, p0))."""
    m, gram, w2 = system.m, system.gram, system.w2
    inlier_rotation_rad, inlier_translation_m = thresholds
    n = len(m)
    first = rng.integers(0, n, iterations)
    second = (first + rng.integers(1, n, iterations)) % n
    counts = np.empty(iterations, dtype=int)
    spread = np.empty(iterations)
    axes = rotation_axes(m)
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
        spread[a:b] = axis_spreads_deg(axes, masks)
        q0_all[a:b], p0_all[a:b] = q0, p0
    return counts, q1, qd1, ratio, spread, (q0_all, p0_all)


def well_spread(eligible: Mask, spread: Floats) -> Mask:
    """The eligible hypotheses whose consensus spreads its rotation axes the most, by tier:
    at least WARN_AXIS_SPREAD_DEG where any does, else at least MIN_AXIS_SPREAD_DEG, else all.

    Why: a consensus of motions about nearly one axis (a recording that was planar for a while)
    is degenerate in the translation along that axis, and its sigma7/sigma6 is then no measure
    of quality: it can come out smallest and win over the consensus of the whole recording
    (recordings poor in rotation at first, then rich)."""
    for floor in (WARN_AXIS_SPREAD_DEG, MIN_AXIS_SPREAD_DEG):
        tier = eligible & (spread >= floor)
        if tier.any():
            out: Mask = tier
            return out
    return eligible


def consensus(
    system: System,
    ransac_iterations: int,
    thresholds: tuple[float, float],
    rng: np.random.Generator,
) -> Consensus:
    """Algorithm 1 proper: the best-scoring robust refinement among the RANSAC hypotheses
    (or one robust solve on all motions); ``thresholds``: eq. 13's (rotation [rad],
    translation [m])."""
    m = system.m
    inlier_rotation_rad, inlier_translation_m = thresholds
    n = len(m)
    if ransac_iterations > 0:
        counts, q1, qd1, ratio, spread, (q0, p0) = _ransac(
            system, ransac_iterations, thresholds, rng
        )
    else:
        counts, spread = np.array([n]), np.zeros(1)
        q1, qd1, sigma = solve_gram((system.w2 @ system.gram).reshape(1, 8, 8))
        ratio = sigma_ratio(sigma)
    eligible = (counts >= 2) & (counts >= CONSENSUS_FRACTION * counts.max()) & np.isfinite(ratio)
    if not eligible.any():
        msg = (
            f'RANSAC found no model that 2 or more of the {n} motions agree with within '
            f'{np.degrees(inlier_rotation_rad):.2f} deg / {inlier_translation_m:.3f} m: the '
            'eye poses are too noisy for these thresholds, or the time offset is wrong'
        )
        raise NoConsensusError(msg)
    best = int(np.argmin(np.where(well_spread(eligible, spread), ratio, np.inf)))
    q_HE, p_HE = pose_from_dual_quat(q1[best], qd1[best])
    if ransac_iterations > 0:
        e_rot, e_trans = motion_errors(m, q0[best][None], p0[best][None])
        inliers = (e_rot[0] < inlier_rotation_rad) & (e_trans[0] < inlier_translation_m)
    else:
        inliers = np.ones(n, dtype=bool)
    sigma_best = system.solve(inliers)[2]
    return Consensus(q_HE, p_HE, inliers, sigma_best, float(ratio[best]))


def widened_consensus(
    system: System, won: Consensus, thresholds: tuple[float, float]
) -> tuple[tuple[float, float], Consensus | None]:
    """The winner's consensus (``won``) taken once more with thresholds no tighter than the
    configured ones (``thresholds``: rotation [rad], translation [m]) but wide enough for the
    noise measured from the winner's own residuals (``CHI3_Q99_OVER_MEDIAN`` times their
    median), and the system re-solved on it: ((rotation, translation thresholds), the wider
    consensus or None when it gathers no more motions).

    Why: the paper's 0.5 deg / 2 cm suit a good VIO over a 5 deg keyframe motion; a noisier eye
    pushes most clean motions over them, and a solution from the few left is far noisier than
    one from all clean motions. The median keeps true outliers (a minority) out.
    """
    e_rot, e_trans = motion_errors(system.m, won.q_HE[None], won.p_HE[None])
    thr_rot = max(thresholds[0], CHI3_Q99_OVER_MEDIAN * float(np.median(e_rot[0])))
    thr_trans = max(thresholds[1], CHI3_Q99_OVER_MEDIAN * float(np.median(e_trans[0])))
    wider = (e_rot[0] < thr_rot) & (e_trans[0] < thr_trans)
    if wider.sum() <= won.inliers.sum():
        return (thr_rot, thr_trans), None
    q2, qd2, s2 = system.solve(wider)
    q_HE, p_HE = pose_from_dual_quat(q2, qd2)
    return (thr_rot, thr_trans), Consensus(q_HE, p_HE, wider, s2, float(s2[6] / s2[5]))
