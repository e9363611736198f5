"""The sections of a result's plain-data form, one function each (the schema's history is in
:mod:`.result`, whose :meth:`~.result.CalibrationResult.to_dict` puts them together).

Plain Python data only (floats, lists, strings, None): JSON has no NaN, so an unknown value is
null (:func:`num`); every transform carries its parent and child frames (:func:`transform_dict`).
"""

from __future__ import annotations

import numpy as np

from .arrays import Floats
from .batch.correlated import BLOCKS, Uncertainty
from .batch.noise import Noise
from .batch.refine import BatchSolution
from .checks.conventions import Correction
from .checks.screening import Screening
from .checks.selfcheck import Candidate
from .checks.verdict import drift_significant
from .config import CalibrationConfig
from .document import (
    BatchDoc,
    ClockDoc,
    ConventionDoc,
    CovarianceDoc,
    LinearDoc,
    MetricsDoc,
    NoiseDoc,
    ScreeningDoc,
    SelfCheckDoc,
    StdDoc,
    TimeAlignmentDoc,
    TrajectoryDoc,
    TransformDoc,
    UncertaintyDoc,
)
from .eye_model import EyeModel
from .geometry import positive_w, quat_from_matrix
from .linear.robust import LinearSolution
from .time.align import TimeAlignment
from .time.clock import DriftFit
from .trajectory import TrajectoryInfo
from .world import Metrics


def batch_section(
    b: BatchSolution | None, c: CalibrationConfig, offset_change_s: float
) -> BatchDoc:
    """Stage 3: its settings, noise, solver run, and how far it moved the offset (s)."""
    out: BatchDoc = {'enabled': c.batch, 'used': b is not None}
    if b is None:
        return out
    out.update(
        {
            'knot_spacing': b.knot_spacing,
            'spline_order': c.spline_order,
            'decoupled': c.batch_decoupled,
            'control_points': b.n_control_points,
            'residuals': {'hand': b.n_hand_residuals, 'eye': b.n_eye_residuals},
            'noise': {'hand': _noise_dict(b.hand_noise), 'eye': _noise_dict(b.eye_noise)},
            'iterations': b.iterations,
            'evaluations': b.evaluations,
            'cost_before': b.cost_before,
            'cost_after': b.cost_after,
            'reduced_chi2': b.reduced_chi2,
            'termination': b.termination,
            'converged': b.success,
            'seconds': b.seconds,
            'time_offset_change': float(offset_change_s),
            'mocap_noise_move': b.mocap_noise_move,
        }
    )
    return out


def clock_section(c: DriftFit | None) -> ClockDoc | None:
    """The offset measured in windows along the recording (eye clock) and the line through
    them: the drift check of every run, the first estimate with clock_drift."""
    if c is None:
        return None
    return {
        'windows': [
            {
                'stamp_ns': int(t),
                'time_offset': num(o),
                'correlation': num(r),
                'used': bool(u),
            }
            for t, o, r, u in zip(c.centres_ns, c.offsets_s, c.correlation, c.inliers, strict=True)
        ],
        'measured_drift': num(c.drift),
        'measured_drift_std': num(c.drift_std),
        'change_over_recording': num(c.change_s) if c.estimated else None,
        'drift_significant': drift_significant(c),
        'not_estimated_because': c.why or None,
        'units': {'time_offset': 's', 'measured_drift': 's/s', 'change_over_recording': 's'},
    }


def screening_section(
    screening: tuple[Screening, Screening] | None,
) -> dict[str, ScreeningDoc] | None:
    """Per stream: the poses removed, by kind and stamp, its breaks and its thresholds."""
    if screening is None:
        return None
    return {
        s.stream: {
            'poses_in': s.n_input,
            'removed': s.counts,
            'fraction': s.fraction,
            'short_segment_fraction': s.short_fraction,
            'removed_stamps_ns': [int(t) for t in s.removed_ns],
            'removed_kinds': list(s.removed_kind),
            'breaks_ns': [int(t) for t in s.breaks_ns],
            'thresholds': {
                'translation_m': num(s.threshold_translation_m),
                'rotation_deg': num(np.degrees(s.threshold_rotation_rad)),
            },
        }
        for s in screening
    }


def std_section(b: BatchSolution | None, m: EyeModel | None) -> StdDoc | None:
    """The 1-sigmas of stage 3 (and of the drift and scale), how they were made, and their
    terms."""
    if b is None:
        return None
    return {
        'time_offset': float(b.std[0]),
        'translation': [float(v) for v in b.std[1:4]],
        'rotation': [float(v) for v in b.std[4:7]],
        'clock_drift': (num(m.drift_std) if m is not None and m.drift_estimated else None),
        'scale': num(m.scale_std) if m is not None and m.scale_estimated else None,
        'units': {
            'time_offset': 's',
            'translation': 'm',
            'rotation': 'rad, tangent of T_HE on the right (eye frame)',
            'clock_drift': 's/s',
            'scale': '1',
        },
        'method': f'long-run (Newey-West, Bartlett kernel, bandwidth {b.bandwidth} eye '
        'poses) over the eye residuals, with the errors correlated over the recording '
        f'({BLOCKS} blocks refitted alone) and the eye scale as a nuisance',
        'white_inflation': [float(v) for v in b.inflation],
        **_uncertainty_dict(b.uncertainty),
    }


def linear_section(
    lin: LinearSolution, c: CalibrationConfig, seed_check: LinearSolution | None
) -> LinearDoc:
    """Stage 2: its motions, consensus, solutions and checks."""
    return {
        'relative_poses': c.relative_poses,
        'motions': int(lin.n_motions),
        'inliers': int(lin.n_inliers),
        'inlier_thresholds': {
            'rotation_deg': lin.inlier_rotation_deg,
            'translation_m': lin.inlier_translation_m,
        },
        'extrinsic': {
            'translation': [float(v) for v in lin.p_HE],
            'rotation': [float(v) for v in positive_w(lin.q_HE)],
        },
        'decoupled_refit': c.decoupled_refit,
        'dual_quaternion_solution': {
            'translation': [float(v) for v in lin.p_HE_dq],
            'rotation': [float(v) for v in positive_w(lin.q_HE_dq)],
        },
        'sigma_ratio': num(lin.sigma_ratio),
        'singular_values': [float(v) for v in lin.singular_values],
        'axis_spread_deg': num(lin.axis_spread_deg),
        'rotation_residual_deg': num(lin.rotation_residual_deg),
        'translation_residual_m': num(lin.translation_residual_m),
        'unobservable': list(lin.unobservable),
        'seed_check': None
        if seed_check is None
        else {
            'seed': c.seed + 1,
            'translation': [float(v) for v in seed_check.p_HE],
            'rotation': [float(v) for v in positive_w(seed_check.q_HE)],
        },
    }


def metrics_section(m: Metrics) -> MetricsDoc:
    """APE / ARE of the eye against the calibrated hand, and AX = XB over the keyframe motions."""
    return {
        'ape_rmse': m.ape_rmse_m,
        'are_rmse': m.are_rmse_deg,
        'ape_max': m.ape_max_m,
        'are_max': m.are_max_deg,
        'poses': m.n_poses,
        'motion_rotation_median': num(m.motion_rotation_deg),
        'motion_translation_median': num(m.motion_translation_m),
        'motion_length_median': num(m.motion_length_m),
        'motions': m.n_motions,
        'units': {
            'ape': 'm',
            'are': 'deg',
            'motion_rotation': 'deg',
            'motion_translation': 'm',
            'motion_length': 'm',
        },
    }


def time_alignment_section(ta: TimeAlignment) -> TimeAlignmentDoc:
    """Stage 1: its method, peak, window and candidates."""
    return {
        'method': ta.method,
        'peak_correlation': num(ta.peak_correlation),
        'second_peak_ratio': num(ta.second_peak_ratio),
        'step': num(ta.step_s),
        'window': [num(ta.window_s[0]), num(ta.window_s[1])],
        'candidates': [
            {'time_offset': float(c), 'correlation': float(r)} for c, r in ta.candidates
        ],
    }


def conventions_entry(c: Correction) -> ConventionDoc:
    """A convention the data contradicted, and the reading applied."""
    return {
        'stream': c.stream,
        'what': c.what,
        'assumed': c.assumed,
        'option': c.option,
        'message': c.message,
    }


def self_check_entry(c: Candidate) -> SelfCheckDoc:
    """A candidate offset of the self-check, its score and whether it was chosen."""
    return {
        'time_offset': float(c.time_offset_s),
        'source': c.source,
        'score': num(c.score),
        'rotation_residual_deg': num(c.rotation_residual_deg),
        'translation_residual_m': num(c.translation_residual_m),
        'chosen': c.chosen,
    }


def covariance_section(b: BatchSolution | None) -> CovarianceDoc | None:
    """Stage 3's covariance with the order of its rows (SI units, rotation in rad)."""
    if b is None:
        return None
    return {
        'order': ['time_offset', 'tx', 'ty', 'tz', 'rx', 'ry', 'rz']
        + ['clock_drift'] * (b.clock_drift is not None)
        + ['scale'] * (b.scale is not None),
        'matrix': [[float(v) for v in row] for row in b.covariance],
    }


def _noise_dict(n: Noise) -> NoiseDoc:
    return {
        'rotation_rad': float(n.rotation),
        'translation_m': float(n.translation),
        'estimated': bool(n.estimated),
    }


def transform_dict(R: Floats, p: Floats, parent: str, child: str) -> TransformDoc:
    """``{parent, child, translation, rotation (x y z w), matrix}`` of T_parent_child."""
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, p
    return {
        'parent': parent,
        'child': child,
        'translation': [float(v) for v in p],
        'rotation': [float(v) for v in quat_from_matrix(R)],
        'matrix': [[float(v) for v in row] for row in M],
    }


def trajectory_section(info: TrajectoryInfo) -> TrajectoryDoc:
    return {
        'source': info.source,
        'poses': info.poses,
        'rate_hz': info.rate_hz,
        'duration_s': info.duration_s,
        'first_stamp_ns': info.first_stamp_ns,
        'last_stamp_ns': info.last_stamp_ns,
    }


def num(x: float) -> float | None:
    """JSON has no NaN: unknown values become null."""
    return float(x) if np.isfinite(x) else None


def _uncertainty_dict(u: Uncertainty | None) -> UncertaintyDoc:
    """The reported 1-sigma's terms (white, correlated, scale) per group (norms over the axes,
    in the groups' units), the term that dominates each, and what could not be estimated."""
    if u is None:
        return {}
    return {
        'terms': {g: {k: float(v) for k, v in t.items()} for g, t in u.terms().items()},
        'dominant': u.dominant(),
        'over_long_run': {g: float(v) for g, v in u.over_long_run().items()},
        'block_factors': None if u.factors is None else dict(u.factors),
        'eye_scale': (
            None if u.scale is None else {'scale': float(u.scale[0]), 'std': float(u.scale[1])}
        ),
        'not_estimated': list(u.not_estimated),
    }
