"""The hand spline where the MoCap is noisy for its eye: a wider knot spacing when the eye's
relative motions say it predicts them better, and how far the MoCap's noise moves the answer.

The spline held through the MoCap (docs/method.md) carries the MoCap's rotation noise into the
relative rotations of eq. 16, where it multiplies T_HE's translation: noise in the regressor,
which draws the lever arm toward zero and the offset toward its start (errors-in-variables
attenuation), by about the square of that noise. A wider knot spacing averages more MoCap poses
into each control pose, at the price of fast motion the spline cannot follow. The eye tells
which spacing predicts its relative motions best: its poses are independent of the MoCap's
noise, so at one (dt, T_HE) the eye residuals are smallest for the spline nearest the motion at
the eye's own frames (a cross-validation, :func:`wider_spacing`).

What noise is left is measured, not predicted: the MoCap's noise drawn once more (its variance
doubled, :func:`noisier_hand`) and the stage solved again. By the bias's square law the answer
moves about as far as the present noise has already moved it (:attr:`.refine.BatchSolution.
mocap_noise_move`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation

from ..arrays import Floats
from .loss import huber_rho
from .noise import Noise
from .residuals import BatchProblem, Weights

#: A spline_share (:attr:`.refine.BatchSolution.spline_share`) from which wider spacings are
#: tried and the noise's move measured: below it the spline's error is under 1 % of the eye
#: residuals' variance (twice its square, at two independent ends), which no spacing could
#: lower measurably, nor its bias move the answer.
WIDER_FROM_SHARE = 0.07
#: MoCap rotations whose noise measures below this [rad] (0.0006 deg, a twentieth of the best
#: MoCap's) are exact here: what the spline's residuals show then is its own approximation of
#: the motion, not noise to bias the answer with.
EXACT_ROTATION = 1e-5
#: Wider spacings tried, as factors on the one asked for: up to four times (0.21 s at the
#: default), beyond which a hand-held motion's turns (a few hertz) are smoothed away.
WIDER = (2**0.5, 2.0, 2**1.5, 4.0)
#: The eye's pairs are compared in blocks of this length [s]: longer than a spline segment's
#: support at the widest spacing (0.84 s), so that the blocks' differences are independent.
BLOCK_S = 2.0
#: A wider spacing is taken when its eye cost is lower by more than this many standard errors
#: of the blocks' paired differences.
SIGNIFICANT = 3.0
#: The seed of the MoCap's noise drawn again: the same recording gives the same answer.
NOISE_SEED = 0


def wider_spacing(
    at: BatchProblem,
    y: Floats,
    weights: Weights,
    delta: float,
    problem_at: Callable[[float], BatchProblem | None],
    spacings: list[float],
) -> BatchProblem:
    """The problem whose spline predicts the eye's relative poses best: ``at`` unless the one
    at one of ``spacings`` lowers the eye's Huber cost at y (whitened by ``weights``,
    ``delta`` as the solve's) by more than SIGNIFICANT standard errors, paired pair by pair
    and summed in blocks of BLOCK_S (its spline is then the one to solve on).
    ``problem_at(spacing)``: the same problem with that spacing's spline (None where its
    pieces leave too little)."""
    base = _pair_costs(at, y, weights, delta)
    best, best_total = at, 0.0
    for spacing in spacings:
        wide = problem_at(spacing)
        if wide is None:
            continue
        common, i, j = np.intersect1d(at.ei, wide.ei, return_indices=True)
        if common.size == 0:
            continue
        d = _pair_costs(wide, y, weights, delta)[j] - base[i]
        blocks = np.floor((at.te[common] - at.te[common[0]]) / BLOCK_S).astype(np.int64)
        per = np.bincount(blocks, weights=d)[np.bincount(blocks) > 0]  # blocks with pairs
        if per.size < 3:
            continue
        total = float(per.sum())
        if total < best_total and -per.mean() > SIGNIFICANT * per.std(ddof=1) / np.sqrt(per.size):
            best, best_total = wide, total
    return best


def _pair_costs(prob: BatchProblem, y: Floats, weights: Weights, delta: float) -> Floats:
    """The Huber cost of each eye pair's whitened residual (6 parts) at y."""
    out: Floats = huber_rho(prob.eye_raw(y) * weights.eye, delta).sum(axis=1)
    return out


def noisier_hand(prob: BatchProblem, noise: Noise) -> tuple[Floats, Floats]:
    """The MoCap poses of ``prob`` (x y z w quaternions, positions [m]) with white noise of
    ``noise`` (per axis, rad and m: the MoCap's own, measured) drawn once more, from
    NOISE_SEED: the same MoCap with its noise's variance doubled."""
    rng = np.random.default_rng(NOISE_SEED)
    n = prob.hand_q.shape[0]
    turn = Rotation.from_rotvec(rng.normal(0.0, noise.rotation, (n, 3)))
    q: Floats = (Rotation.from_quat(prob.hand_q) * turn).as_quat()
    p: Floats = prob.hand_p + rng.normal(0.0, noise.translation, (n, 3))
    return q, p
