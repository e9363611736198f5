"""What the batch stage's covariance misses on a real VIO, measured on the recording itself.

The long-run covariance of :mod:`.long_run` holds for residuals correlated over seconds. A real
VIO also errs alike over minutes or over the whole recording: biases and a slow drift of its
attitude that change as it moves, and a scale of its translations that is not 1 (TUM-VI
outdoors4: Basalt VIO and ORB-SLAM3 VIO on the same MoCap put T_HE 11 mm apart in y where each
reported 0.4-1.2 mm). Two terms, added to the long-run covariance ``C``:

1. **Correlated (blocks).** The covered eye poses are cut into ``B`` contiguous blocks, each
   refitted alone from the solution; the blocks' deviations ``d_b`` from the solution,
   measured against their own covariances ``C_b``, give per group g (time offset, translation,
   rotation; p_g parameters) the dispersion ratio ``k_g^2 = sum_b d_b^T C_b^-1 d_b / (p_g
   (B - 1))`` (Birge's ratio: 1 when the blocks agree as their sigmas say). The group's rows
   and columns of ``C`` are multiplied by ``max(1, k_g)``.
2. **Scale.** The solution refitted with a factor on the eye's translations as a nuisance
   parameter. T_HE stays the one at s = 1, as the user's metric eye asks; its covariance gains
   what not knowing s adds (the marginal minus the conditional covariance) and the shift that
   the fitted s moves it by (the bias of s = 1): ``C_free - C_fixed + delta delta^T``.

Neither term sees an error that is the same over the whole recording and is no scale (two
estimators whose body frames differ by a lever arm); docs/method.md gives the figures.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: The correlated term refits this many contiguous blocks of the covered eye poses (a quarter of
#: the recording each: on the white simulations their dispersion ratio is 1.0 in the median,
#: 1.2-1.45 at the 90th percentile, with 4 blocks of 15 or 30 s); with fewer than
#: MIN_BLOCK_POSES eye poses in a block the term is not estimated.
BLOCKS = 4
MIN_BLOCK_POSES = 100
#: The reported covariance's groups: (dt), translation (3), rotation (3), in its order.
GROUPS = {'time_offset': (0,), 'translation': (1, 2, 3), 'rotation': (4, 5, 6)}
#: The terms of the uncertainty, as the result names them.
TERMS = ('white', 'correlated', 'scale')


@dataclass(frozen=True)
class Uncertainty:
    """The reported covariance of (dt, translation, rotation) and its parts.

    white: ``s^2 (J^T J)^-1``; long_run: :mod:`.long_run`'s; covariance: the reported one (all
    three in the reported order: dt, translation, rotation, then a drift and a scale when
    estimated); factors: the blocks' k_g per group (1: not inflated), None when the blocks could
    not be fitted; scale: the nuisance fit's (s, its 1-sigma, the shift of (dt, translation,
    rotation) from s = 1 to s), None when it was not fitted; not_estimated: why a term is
    missing.
    """

    white: np.ndarray
    long_run: np.ndarray
    factors: dict[str, float] | None
    scale: tuple[float, float, np.ndarray] | None
    covariance: np.ndarray
    not_estimated: tuple[str, ...] = field(default=())

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

    def over_long_run(self) -> dict[str, float]:
        """Per group, the reported 1-sigma (norm over its axes) over the long-run one: what
        the blocks and the scale added (the readiness status carries it into its
        predictions, which are long-run ones)."""
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

    def _scale_part(self) -> np.ndarray:
        return self.covariance - inflated(self.long_run, self.factors or {})


def dispersion(deviations: np.ndarray, covariances: np.ndarray) -> dict[str, float]:
    """k_g (>= 1) per group from the blocks' deviations (B, 7) and their covariances
    (B, 7, 7), in the reported order (see the module docstring); a group held fixed has
    none."""
    B = deviations.shape[0]
    out = {}
    for group, idx in GROUPS.items():
        i = list(idx)
        if not np.all(covariances[:, i, i] > 0.0):  # held fixed (a given time offset)
            continue
        chi2 = sum(
            float(d[i] @ np.linalg.solve(C[np.ix_(i, i)], d[i]))
            for d, C in zip(deviations, covariances, strict=True)
        )
        out[group] = float(np.sqrt(max(1.0, chi2 / (len(i) * (B - 1)))))
    return out


def inflated(cov: np.ndarray, factors: dict[str, float]) -> np.ndarray:
    """``cov`` (at least 7 x 7, reported order) with each group's rows and columns multiplied
    by its factor."""
    d = np.ones(cov.shape[0])
    for group, k in factors.items():
        d[list(GROUPS[group])] = k
    return cov * np.outer(d, d)


def scale_term(fixed: np.ndarray, free: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """What not knowing the eye's scale adds to the covariance of (dt, translation, rotation)
    (7, 7) at s = 1: the marginal (``free``) minus the conditional (``fixed``) covariance, and
    the shift (7,) of the estimate when s is fitted; the nearest positive semi-definite
    matrix (two separately estimated covariances may differ by more than the term)."""
    term = free - fixed + np.outer(shift, shift)
    w, V = np.linalg.eigh(0.5 * (term + term.T))
    return (V * np.clip(w, 0.0, None)) @ V.T
