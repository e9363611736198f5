"""APE and RPE of an estimate against a reference at the same stamps (both in one world).

- APE (absolute pose error): per pose ``E_i = Q_i^-1 P_i``; the translation error is
  ``|t(E_i)| = |p_P - p_Q|`` (m), the rotation error the angle of ``R(E_i)`` (deg). No alignment
  is done here: the reference is already in the estimate's world (the calibration put it there).
- RPE (relative pose error, Sturm et al. 2012, as evo and the KITTI benchmark use it): for pose
  pairs (i, j) a fixed time or distance apart, ``E_ij = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)``. j is the
  pose whose time (or path length along the reference) from i is nearest to delta, and the pair
  is kept when that misses delta by at most :data:`RPE_TOLERANCE` of it: evo's rule for
  ``--all_pairs --pairs_from_reference`` (evo measures the path on the estimate by default; the
  reference's is the one without VIO noise). Pairs never join two eye segments.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import get_args

import numpy as np

from ..core.arrays import Floats, Indices
from ..core.document import ErrorKey, ErrorStatsDoc, EvaluationDoc, PoseErrorsDoc, SigmasMethodDoc
from ..core.geometry import rotation_angle, row_norms
from ..core.result_sections import num
from .aligned import AlignedTrajectories

#: The figures of :class:`PoseErrors`, and the statistics of each that carry error bars.
POSE_ERRORS: tuple[ErrorKey, ...] = get_args(ErrorKey)
STATS = ('rmse', 'mean', 'median')
#: An RPE pair may miss the time or distance step by this fraction of it (evo's default).
RPE_TOLERANCE = 0.1


@dataclass(frozen=True)
class ErrorStats:
    """Summary of a set of errors (translation in m, rotation in deg)."""

    rmse: float
    mean: float
    median: float
    max: float
    n: int

    @classmethod
    def of(cls, e: Floats) -> ErrorStats:
        e = np.asarray(e, dtype=float)
        if e.size == 0:
            nan = float('nan')
            return cls(nan, nan, nan, nan, 0)
        return cls(
            float(np.sqrt(np.mean(e**2))),
            float(e.mean()),
            float(np.median(e)),
            float(e.max()),
            int(e.size),
        )

    def to_dict(self) -> ErrorStatsDoc:
        return {
            'rmse': num(self.rmse),
            'mean': num(self.mean),
            'median': num(self.median),
            'max': num(self.max),
            'n': self.n,
        }


def ape(al: AlignedTrajectories) -> tuple[Floats, Floats]:
    """Per-pose translation (m) and rotation (deg) errors (module docstring)."""
    R_err = np.matmul(np.swapaxes(al.R_ref, -1, -2), al.R_est)  # R(Q^-1 P)
    return row_norms(al.p_est - al.p_ref), np.degrees(rotation_angle(R_err))


def rpe_pairs(al: AlignedTrajectories, delta: float, unit: str) -> tuple[Indices, Indices]:
    """Index pairs (i, j) for the RPE per ``unit`` 's' (time) or 'm' (reference path length)."""
    if not delta > 0:
        msg = f'the RPE delta must be positive, got {delta!r}'
        raise ValueError(msg)
    n = len(al)
    if n < 2:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    if unit == 's':
        axis = al.seconds()
    elif unit == 'm':
        step = row_norms(np.diff(al.p_ref, axis=0))
        step[np.diff(al.segment) != 0] = 0.0
        axis = np.concatenate([[0.0], np.cumsum(step)])
    else:
        msg = f"the RPE unit is 's' or 'm', got {unit!r}"
        raise ValueError(msg)
    i = np.arange(n - 1)
    # the nearest j > i to axis[i] + delta: axis is non-decreasing, so it is k or k - 1
    k = np.searchsorted(axis, axis[i] + delta, side='left')
    hi = np.minimum(k, n - 1)
    lo = np.maximum(k - 1, i + 1)
    take_lo = np.abs(axis[lo] - axis[i] - delta) <= np.abs(axis[hi] - axis[i] - delta)
    j = np.where(take_lo, lo, hi)
    keep = (j > i) & (np.abs(axis[j] - axis[i] - delta) <= RPE_TOLERANCE * delta)
    keep &= al.segment[i] == al.segment[j]
    return i[keep], j[keep]


def rpe(al: AlignedTrajectories, delta: float, unit: str = 's') -> tuple[Floats, Floats, Indices]:
    """Per-pair translation (m) and rotation (deg) errors and the pairs' first indices."""
    i, j = rpe_pairs(al, delta, unit)
    # with dQ = Q_i^-1 Q_j = (R_Qi^T R_Qj, R_Qi^T (q_j - q_i)) and dP alike, E = dQ^-1 dP has
    # rotation R_dQ^T R_dP and translation R_dQ^T (t_dP - t_dQ), whose norm is |t_dP - t_dQ|
    R_dQ, t_dQ = _relative(al.R_ref, al.p_ref, i, j)
    R_dP, t_dP = _relative(al.R_est, al.p_est, i, j)
    R_err = np.matmul(np.swapaxes(R_dQ, -1, -2), R_dP)
    return (row_norms(t_dP - t_dQ), np.degrees(rotation_angle(R_err)), i)


def _relative(R: Floats, p: Floats, i: Indices, j: Indices) -> tuple[Floats, Floats]:
    """``T_i^-1 T_j`` for index pairs: rotations (M, 3, 3), translations (M, 3)."""
    Ri_T = np.swapaxes(R[i], -1, -2)
    return np.matmul(Ri_T, R[j]), np.einsum('nab,nb->na', Ri_T, p[j] - p[i])


@dataclass(frozen=True)
class PoseErrors:
    """APE and RPE of one estimate against one reference."""

    what: str
    ape_translation: ErrorStats
    ape_rotation: ErrorStats
    rpe_time_translation: ErrorStats
    rpe_time_rotation: ErrorStats
    rpe_distance_translation: ErrorStats
    rpe_distance_rotation: ErrorStats

    @classmethod
    def of(cls, al: AlignedTrajectories, delta_s: float, delta_m: float) -> PoseErrors:
        a_t, a_r = ape(al)
        rt_t, rt_r, _ = rpe(al, delta_s, 's')
        rd_t, rd_r, _ = rpe(al, delta_m, 'm')
        return cls(al.what, *(ErrorStats.of(e) for e in (a_t, a_r, rt_t, rt_r, rd_t, rd_r)))

    def to_dict(self) -> PoseErrorsDoc:
        return {
            'what': self.what,
            'ape_translation': self.ape_translation.to_dict(),
            'ape_rotation': self.ape_rotation.to_dict(),
            'rpe_time_translation': self.rpe_time_translation.to_dict(),
            'rpe_time_rotation': self.rpe_time_rotation.to_dict(),
            'rpe_distance_translation': self.rpe_distance_translation.to_dict(),
            'rpe_distance_rotation': self.rpe_distance_rotation.to_dict(),
        }


@dataclass(frozen=True)
class CalibrationSigmas:
    """Per figure of :class:`~.metrics.PoseErrors` (``'ape_translation'``, ...), the 1-sigma of
    its rmse, mean and median that the calibration's uncertainty gives (m or deg, as the
    figure; None where the figure has no value), from ``draws`` draws over ``poses`` eye poses;
    ``parameters`` names what was drawn; ``through``: per figure, the group of parameters that
    moves its rmse most (:func:`~.error_bars.moved_most_by`; '' or absent when none can be
    named).
    """

    sigmas: dict[ErrorKey, dict[str, float | None]]
    draws: int
    poses: int
    parameters: tuple[str, ...]
    through: dict[ErrorKey, str] = field(default_factory=dict)

    def to_dict(self, exclude_sigmas: bool = False) -> SigmasMethodDoc:
        out: SigmasMethodDoc = {
            'draws': self.draws,
            'poses': self.poses,
            'parameters': list(self.parameters),
            'method': (
                'each figure again at draws of the parameters in opposite pairs whose second '
                'moment is their reported covariance, T_WG refitted; its 1-sigma the '
                'root-mean-square of the changes'
            ),
        }
        if not exclude_sigmas:
            out['sigmas'] = {str(k): v for k, v in self.sigmas.items()}
        return out


@dataclass(frozen=True)
class Evaluation:
    """APE/RPE with our calibration and, where the clocks allow, without it.

    delta_s / delta_m: the RPE's time and distance steps. uncalibrated is None when the
    baseline cannot be computed, and ``uncalibrated_why`` says why. sigmas: the calibrated
    figures' 1-sigmas from the calibration's own uncertainty (:mod:`.error_bars`), None with
    ``sigmas_why`` when it has none.
    """

    delta_s: float
    delta_m: float
    calibrated: PoseErrors
    uncalibrated: PoseErrors | None
    uncalibrated_why: str = ''
    sigmas: CalibrationSigmas | None = None
    sigmas_why: str = ''

    @classmethod
    def of(
        cls,
        cal: AlignedTrajectories,
        base: AlignedTrajectories | None,
        *,
        delta_s: float = 1.0,
        delta_m: float = 1.0,
        why: str = '',
        sigmas: tuple[CalibrationSigmas | None, str] = (None, 'not computed'),
    ) -> Evaluation:
        """APE/RPE of the eye with the calibration (``cal``) and without it (``base``; ``why``
        when there is none), with the calibrated figures' error bars where given."""
        return cls(
            delta_s,
            delta_m,
            PoseErrors.of(cal, delta_s, delta_m),
            None if base is None else PoseErrors.of(base, delta_s, delta_m),
            why,
            *sigmas,
        )

    def to_dict(self) -> EvaluationDoc:
        calibrated = self.calibrated.to_dict()
        if self.sigmas is not None:
            for name, sigma in self.sigmas.sigmas.items():
                calibrated[name]['calibration_sigma'] = sigma
        return {
            'rpe_delta_s': self.delta_s,
            'rpe_delta_m': self.delta_m,
            'units': {'translation': 'm', 'rotation': 'deg'},
            'calibrated': calibrated,
            'uncalibrated': None if self.uncalibrated is None else self.uncalibrated.to_dict(),
            'uncalibrated_why': self.uncalibrated_why or None,
            'calibration_sigmas': (
                {'why_not': self.sigmas_why}
                if self.sigmas is None
                else self.sigmas.to_dict(exclude_sigmas=True)
            ),
        }
