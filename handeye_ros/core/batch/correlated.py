"""What the batch stage's covariance misses on a real VIO, measured on the recording itself.

The long-run covariance of :mod:`.long_run` holds for residuals correlated over seconds. A real
VIO also errs alike over minutes or over the whole recording: biases and a slow drift of its
attitude that change as it moves, and a scale of its translations that is not 1 (TUM-VI
outdoors4: Basalt VIO and ORB-SLAM3 VIO on the same MoCap put T_HE 11 mm apart in y where each
reported 0.4-1.2 mm). Two terms in the long-run covariance ``C``:

1. **Correlated (blocks).** The covered eye poses are cut into ``B`` contiguous blocks of as
   many poses, each refitted alone by one step from the solution (its linearised influence,
   which stays within what its covariance describes), with deviations ``d_b`` from it and
   covariances ``C_b``. What the blocks' disagreement means differs by group:

   - Translation and rotation: a VIO's errors over minutes (biases, a slow drift of its
     attitude) move each block's fit, and the recording's value is uncertain by the error of the
     blocks' mean as the solution weighs them, by their information (the cluster-robust
     covariance of a weighted mean, the blocks its clusters): with ``W_b = (sum_k C_k,g^-1)^-1
     C_b,g^-1`` and ``e_b = d_b,g - sum_k W_k d_k,g``, ``v_g = t^2 B / (B - 1) sum_b |W_b
     e_b|^2``. Blocks of equal information give the plain ``t^2 sum_b |d_b,g - mean_b
     d_b,g|^2 / (B (B - 1))``; a block that hardly determines the group (a planar start, a
     drone still on the ground) moves its own fit far and the mean little, and counts as
     little.
   - Time offset: a block's offset is the eye's latency over that block, and a latency that
     wanders (with a VIO's load, from one segment of a broken stream to the next) is a variation
     of the quantity, not an error of it: the result is the recording's mean offset, known to
     the long-run covariance plus how far the solution's weighting of the blocks (``w_b``
     proportional to their information ``1 / C_b,g``) takes it from their plain mean when
     their latencies differ by ``tau^2``: ``v = tr C_g + t^2 tau^2 sum_b (w_b - n_b / n)^2``.
     ``tau^2`` is the blocks' variance beyond their own noise (DerSimonian and Laird's moment
     estimate, ``(Q - (B - 1)) / (S_1 - S_2 / S_1)`` and at least 0, with ``Q = sum_b (d_b,g -
     sum_k w_k d_k,g)^2 / C_b,g`` and ``S_n = sum_b C_b,g^-n``): spread over every block, it
     keeps one block that hardly determines the offset (a planar start), whose refit strays
     beyond its own sigma, from passing its error off as the mean's. (On simulations whose
     offset wanders by 3 ms the error of the blocks' mean would be 4 times the errors;
     bench/results/accuracy.md.)

   ``t`` is the Student-t 1-sigma factor of B_eff - 1 degrees of freedom (1.20 for four
   blocks of equal information: a spread measured on four values is itself uncertain), B_eff =
   1 / sum_b w_b^2 the blocks that count (``w_b = tr W_b / p_g``), at least two. The plain mean
   the offset's weighting is measured from weighs each block by its share ``n_b / n`` of the
   covered poses (``1 / B`` for equal blocks).

   A spread of four values is a noisy figure, and where the quarters' edges fall decides part
   of it. So the recording is cut SHIFTS times
   (:func:`cuts`): at its quarters, and again a quarter, a half and three quarters of a block
   later (three whole blocks between two parts of one at the ends), and ``v_g`` is the mean of
   the cuttings' (overlapping batch means, which average over every start, here four). Where
   ``v_g`` exceeds the long-run variance of the group, its rows and columns of ``C`` are
   multiplied by ``k_g = sqrt(v_g / tr C_g)``. The quarters' Birge's ratio ``sum_b d_b^T
   C_b^-1 d_b / (p_g (B - 1))`` far above 1 (:func:`varies`) means that the group's value
   moves along the recording by more than the blocks' own noise: the result says so, with the
   blocks' spread. (Multiplying ``C`` by that ratio would count the long-run correlation twice
   where a block's covariance is not B times the whole one's.)
2. **Scale.** A metric VIO's translations are a little off in scale (1-3 % on the real runs of
   bench/results/accuracy.md), and holding s = 1 moves T_HE by the lever arm's share of that
   error. So the batch stage fits a factor on the eye's translations beside (dt, T_HE) as a
   nuisance parameter, and the reported covariance is the marginal one: T_HE carries what not
   knowing s adds (:func:`scale_share`, ``C_xs C_ss^-1 C_sx``), and the user's eye stays metric
   for every metric. (With ``estimate_scale`` s is a parameter of the result instead.)

Neither term sees an error that is the same over the whole recording and is no scale (two
estimators whose body frames differ by a lever arm); docs/method.md gives the figures.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.special import chdtri, stdtrit

from ..arrays import Floats, Indices

#: The correlated term refits this many contiguous blocks of the covered eye poses (a quarter of
#: the recording each), and the same cut SHIFTS - 1 times more, each 1 / SHIFTS of a block
#: later (:func:`cuts`); with fewer than MIN_BLOCK_POSES eye poses in a quarter the term is not
#: estimated. Four cuttings steady the verdict and the sigmas against where the quarters fall
#: better than two, and eight gain nothing more (their end parts hold an eighth of a block;
#: bench/results/accuracy.md); they cost the batch stage 0.2 s on 10 minutes of 200 + 30 Hz.
BLOCKS = 4
SHIFTS = 4
MIN_BLOCK_POSES = 100
#: Birge's ratio of the blocks above its upper quantile of this probability under their own
#: covariances (chi^2 with p_g (B - 1) degrees of freedom over them) says that a group's value
#: varies along the recording.
VARIES_QUANTILE = 0.999
#: The probability within one standard deviation of a normal distribution's mean.
ONE_SIGMA = 0.6826894921370859
#: The reported covariance's groups: (dt), translation (3), rotation (3), in its order.
GROUPS = {'time_offset': (0,), 'translation': (1, 2, 3), 'rotation': (4, 5, 6)}
#: The terms of the uncertainty, as the result names them.
TERMS = ('white', 'correlated', 'scale')


@dataclass(frozen=True)
class Uncertainty:
    """The reported covariance of (dt, translation, rotation) and its parts.

    white: ``s^2 (J^T J)^-1`` with the eye's scale known; long_run: :mod:`.long_run`'s;
    covariance: the reported one (all three in the reported order: dt, translation, rotation,
    then a drift and a scale when estimated); factors: the blocks' k_g per group (1: not
    inflated), None when the blocks could not be fitted; varies: the groups whose value moves
    along the recording (:func:`varies`); scale: the nuisance scale of a metric eye (s, its
    1-sigma, the shift of (dt, translation, rotation) from s = 1 to s), None when it was not
    fitted; scale_part: what not knowing the scale adds to the reported covariance's (dt,
    translation, rotation) (:func:`scale_share`), None without a scale; not_estimated: why a
    term is missing.
    """

    white: Floats
    long_run: Floats
    factors: dict[str, float] | None
    scale: tuple[float, float, Floats] | None
    covariance: Floats
    not_estimated: tuple[str, ...] = field(default=())
    varies: dict[str, tuple[float, float]] = field(default_factory=dict)
    scale_part: Floats | None = None

    def terms(self) -> dict[str, dict[str, float]]:
        """Per group, the 1-sigma (norm over its axes) of each term: white, correlated (what
        the long-run and the blocks add to it) and scale; their squares add up to the
        reported one's."""
        out = {}
        for group, idx in GROUPS.items():
            i = list(idx)
            white = float(np.trace(self.white[np.ix_(i, i)]))
            total = float(np.trace(self.covariance[np.ix_(i, i)]))
            scaled = float(np.trace(self._scale_part()[np.ix_(i, i)]))
            correlated = max(total - scaled - white, 0.0)
            out[group] = {
                'white': float(np.sqrt(white)),
                'correlated': float(np.sqrt(correlated)),
                'scale': float(np.sqrt(max(scaled, 0.0))),
            }
        return out

    def std(self, group: str) -> Floats:
        """The reported 1-sigma of each of the group's axes."""
        i = list(GROUPS[group])
        return np.sqrt(np.clip(np.diag(self.covariance)[i], 0.0, None))

    def over_long_run(self) -> dict[str, float]:
        """Per group, the reported 1-sigma (norm over its axes) over the long-run one (its
        scale marginalised too): what the blocks added."""
        out = {}
        for group, idx in GROUPS.items():
            i = list(idx)
            lr = float(np.trace(self.long_run[np.ix_(i, i)]))
            total = float(np.trace(self.covariance[np.ix_(i, i)]))
            out[group] = float(np.sqrt(total / lr)) if lr > 0.0 else 1.0
        return out

    def dominant(self) -> dict[str, str]:
        """Per group, the term that contributes the most variance."""
        return {g: max(TERMS, key=lambda t: s[t]) for g, s in self.terms().items()}

    def _scale_part(self) -> Floats:
        return np.zeros((7, 7)) if self.scale_part is None else self.scale_part


@dataclass(frozen=True)
class Blocks:
    """One cutting's blocks, each refitted alone: their deviations (B, 7) from the solution and
    covariances (B, 7, 7) in the reported order, and their shares (B,) of the covered eye poses
    (equal when None)."""

    deviations: Floats
    covariances: Floats
    shares: Floats | None = None


def cuts(n: int) -> list[Indices]:
    """The edges (indices into ``n`` covered eye poses, each from its first to past its last)
    of the SHIFTS cuttings: the BLOCKS quarters first, then the same ``j / SHIFTS`` of a block
    later for ``j = 1 .. SHIFTS - 1`` (a part of a block at each end)."""
    quarters = np.linspace(0.0, n, BLOCKS + 1)
    later = [np.r_[0.0, quarters[1:] - j / SHIFTS * quarters[1], n] for j in range(1, SHIFTS)]
    return [edges.astype(np.int64) for edges in (quarters, *later)]


def error_of_mean(cuttings: Sequence[Blocks], long_run: Floats) -> dict[str, float]:
    """k_g (>= 1) per group: the error of the recording's value over the long-run 1-sigma
    (module docstring), its variance the mean of the cuttings' (each a :class:`Blocks`), from
    the long-run covariance (reported order); a group held fixed (zero variance) has none."""
    ratios: dict[str, list[float]] = {}
    for blocks in cuttings:
        for group, ratio in _variance_ratios(blocks, long_run).items():
            ratios.setdefault(group, []).append(ratio)
    return {g: float(np.sqrt(max(1.0, float(np.mean(r))))) for g, r in ratios.items()}


def _variance_ratios(blocks: Blocks, long_run: Floats) -> dict[str, float]:
    """v_g / tr C_g per group for one cutting (module docstring)."""
    deviations, covariances = blocks.deviations, blocks.covariances
    B = deviations.shape[0]
    shares = np.full(B, 1.0 / B) if blocks.shares is None else blocks.shares / blocks.shares.sum()
    out = {}
    for group, idx in GROUPS.items():
        i = list(idx)
        own = float(np.trace(long_run[np.ix_(i, i)]))
        if not own > 0.0 or not np.all(covariances[:, i, i] > 0.0):  # held fixed
            continue
        # pseudo-inverses: a block's covariance may be singular along a direction it misses
        info = np.linalg.pinv(covariances[:, i][:, :, i])
        W = np.linalg.pinv(info.sum(axis=0)) @ info  # (B, p, p), their sum the identity
        w = np.trace(W, axis1=1, axis2=2) / len(i)
        t_1sigma = float(stdtrit(max(1.0 / np.sum(w**2), 2.0) - 1.0, 0.5 + 0.5 * ONE_SIGMA))
        d = deviations[:, i]
        if group == 'time_offset':
            a = info[:, 0, 0]
            q = float(np.sum(a * (d[:, 0] - np.sum(w * d[:, 0])) ** 2))
            tau2 = max(0.0, (q - (B - 1)) / (a.sum() - np.sum(a**2) / a.sum()))
            v = own + t_1sigma**2 * tau2 * float(np.sum((w - shares) ** 2))
        else:
            e = d - np.einsum('bij,bj->i', W, d)
            v = t_1sigma**2 * B / (B - 1) * float(np.sum(np.einsum('bij,bj->bi', W, e) ** 2))
        out[group] = v / own
    return out


def varies(deviations: Floats, covariances: Floats) -> dict[str, tuple[float, float]]:
    """The groups whose blocks disagree beyond their own covariances (B, 7, 7) (Birge's ratio
    above its VARIES_QUANTILE), each with (the blocks' spread: the norm over the group's axes
    of the deviations' (B, 7) sample standard deviation; the square root of Birge's ratio: how
    many times what the blocks' own noise explains)."""
    B = deviations.shape[0]
    out = {}
    for group, idx in GROUPS.items():
        i = list(idx)
        if not np.all(covariances[:, i, i] > 0.0):  # held fixed (a given time offset)
            continue
        chi2 = sum(
            float(d[i] @ np.linalg.pinv(C[np.ix_(i, i)]) @ d[i])
            for d, C in zip(deviations, covariances, strict=True)
        )
        dof = len(i) * (B - 1)
        if chi2 > chdtri(dof, 1.0 - VARIES_QUANTILE):
            spread = float(np.linalg.norm(np.std(deviations[:, i], axis=0, ddof=1)))
            out[group] = (spread, float(np.sqrt(chi2 / dof)))
    return out


def inflated(cov: Floats, factors: dict[str, float]) -> Floats:
    """``cov`` (at least 7 x 7, reported order) with each group's rows and columns multiplied
    by its factor."""
    d = np.ones(cov.shape[0])
    for group, k in factors.items():
        d[list(GROUPS[group])] = k
    return cov * np.outer(d, d)


def scale_share(cov: Floats, at: int) -> Floats:
    """What not knowing the eye's scale (index ``at`` of ``cov``, reported order) adds to the
    covariance of (dt, translation, rotation) (7, 7): the marginal minus the conditional one,
    ``C_xs C_ss^-1 C_sx``."""
    c = cov[:7, at]
    out: Floats = np.outer(c, c) / cov[at, at]
    return out


def without(cov: Floats, at: int) -> Floats:
    """``cov`` marginalised over its parameter ``at`` (its row and column left out)."""
    keep = np.delete(np.arange(cov.shape[0]), at)
    out: Floats = cov[np.ix_(keep, keep)]
    return out


def scale_shift(white: Floats, at: int, scale: float) -> Floats:
    """(7,) how far (dt, translation, rotation) move from s = 1 to the fitted ``scale``: the
    least-squares conditional mean's change, ``C_xs / C_ss (s - 1)``, from the white covariance
    ``white`` (its scale at ``at``)."""
    out: Floats = white[:7, at] / white[at, at] * (scale - 1.0)
    return out
