"""The calibration result and its plain-data form (written as YAML/JSON, published by the node).

Schema history of :meth:`CalibrationResult.to_dict` (key ``schema_version``):

- 1: time_offset, extrinsic (T_HE) and extrinsic_inverse (T_EH), world_alignment (T_WG),
  time_alignment, association, linear, std, covariance, batch, metrics, inputs, config,
  warnings (and, from the front ends, summary and streams). ``linear`` holds the stage-2
  extrinsic apart (``linear.extrinsic``) when the batch stage refined it.
- 2: ``quality`` (verdict, reasons, notes); ``time_offset_ns`` (exact, for clocks on
  different epochs); ``screening`` (per stream: removed poses by kind with their stamps,
  breaks); ``conventions`` (readings applied); ``self_check`` (candidate offsets, scores, the
  winner); ``time_alignment.candidates`` and ``time_alignment.vector``; ``linear.unobservable``
  and ``linear.seed_check``; ``std.method`` (the long-run covariance) with
  ``std.white_inflation``; ``world_alignment.segments``.
- 3: ``clock_drift`` [s/s] and ``time_offset_stamp`` [s, eye clock] (with
  ``time_offset_stamp_ns``): the linear clock ``dt(t) = time_offset + clock_drift (t -
  time_offset_stamp)``, null without ``clock_drift``; ``scale`` (s * eye positions metric),
  null without ``estimate_scale``; ``clock`` (the offset measured in windows along the
  recording, and the drift it shows); ``std.clock_drift`` and ``std.scale``; the covariance's
  ``order`` gains ``clock_drift`` and ``scale`` when they were estimated by the batch stage.
- 4: ``coverage`` (the MoCap's gaps inside the eye's span and the part of it the MoCap covers,
  :mod:`.checks.coverage`); ``time_alignment.method`` may be ``keyframes`` (a keyframe-only eye).
- 5: ``readiness`` (:mod:`.checks.readiness`): whether the recording supports the required
  precision, the 1-sigmas it predicts, how far the device turned about each of its axes, and
  what it lacks.

Every transform is written as ``{translation: [x, y, z] (m), rotation: [qx, qy, qz, qw],
matrix: 4x4 rows}`` with the parent/child frames spelled out, as Kalibr does, so that nobody has
to guess the direction.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from .batch.correlated import BLOCKS
from .batch.refine import BatchSolution
from .checks.conventions import Correction
from .checks.coverage import Coverage
from .checks.readiness import Readiness
from .checks.screening import Screening
from .checks.selfcheck import Candidate
from .checks.verdict import Quality, Verdict, drift_significant
from .config import CalibrationConfig
from .eye_model import EyeModel
from .geometry import inverse, matrix_from_quat, positive_w, quat_from_matrix
from .linear.robust import LinearSolution
from .time.align import TimeAlignment
from .time.clock import DriftFit, linear_clock
from .trajectory import Trajectory, TrajectoryInfo
from .world import Metrics, WorldAlignment

SCHEMA_VERSION = 5
CONVENTION = (
    'T_WE(t) = T_WG * T_GH(t - dt(t)) * T_HE; dt(t) = time_offset + clock_drift * '
    '(t - time_offset_stamp) = eye clock minus hand clock (s; clock_drift 0 unless '
    'estimated); with a scale s, s * eye positions are metric (T_WG then maps the '
    'hand into that scaled eye world); quaternions Hamilton, x y z w'
)


@dataclass(frozen=True)
class UsedStreams:
    """The poses the calibration ended on, for evaluation, exports and plots.

    hand: the hand (T_GH) after unit and convention corrections and screening, on its own
    clock. eye: the eye (T_WE) likewise, moved onto the hand's clock up to ``time_offset``
    (stage 1's shift and any drift taken out) and made metric by the scale; its breaks split
    it into segments with their own VIO worlds. eye_stamps_ns: the eye's poses' stamps on the
    eye's own clock (int64 ns, as in its file or bag). time_offset_s: the offset left between
    ``eye`` and ``hand`` [s]: the eye pose stamped t there belongs to hand time t - it.
    """

    hand: Trajectory
    eye: Trajectory
    eye_stamps_ns: np.ndarray
    time_offset_s: float


@dataclass(frozen=True)
class CalibrationResult:
    """Everything the calibration found, in the package conventions.

    ``q_HE, p_HE`` is the extrinsic T_HE (eye frame E in hand frame H), ``time_offset_s`` is dt.
    ``hand``, ``eye``: the input streams as given (name, count, rate, stamps), without their
    poses; ``used`` has the poses the calibration ended on (None once :meth:`detached`).
    """

    time_offset_s: float
    q_HE: np.ndarray
    p_HE: np.ndarray
    world: WorldAlignment
    time_alignment: TimeAlignment
    linear: LinearSolution
    metrics: Metrics
    n_pairs: int
    hand: TrajectoryInfo
    eye: TrajectoryInfo
    config: CalibrationConfig
    warnings: tuple[str, ...] = field(default=())
    batch: BatchSolution | None = None
    time_offset_ns: int = 0
    vector_alignment: TimeAlignment | None = None
    screening: tuple[Screening, Screening] | None = None
    corrections: tuple[Correction, ...] = ()
    candidates: tuple[Candidate, ...] = ()
    quality: Quality = field(default_factory=lambda: Quality(Verdict.GOOD))
    seed_check: LinearSolution | None = None
    eye_model: EyeModel | None = None
    clock: DriftFit | None = None
    used: UsedStreams | None = field(default=None, repr=False, compare=False)
    coverage: Coverage | None = None
    readiness: Readiness | None = None

    @property
    def clock_drift(self) -> float | None:
        """The estimated drift [s/s] of the linear clock, None when not estimated."""
        m = self.eye_model
        return m.drift if m is not None and m.drift_estimated else None

    @property
    def scale(self) -> float | None:
        """s with s * eye positions metric, None when not estimated."""
        m = self.eye_model
        return m.scale if m is not None and m.scale_estimated else None

    def time_offset_at(self, t_eye_ns: np.ndarray) -> np.ndarray:
        """dt(t) [s] at eye stamps [ns, eye clock]: the time offset with the drift, if any."""
        if self.clock_drift is None or self.eye_model is None:
            return np.full(np.shape(t_eye_ns), self.time_offset_s)
        return linear_clock(
            self.time_offset_s, self.clock_drift, self.eye_model.time_offset_stamp_ns, t_eye_ns
        )

    def detached(self) -> CalibrationResult:
        """The result without its pose arrays (:attr:`used`, the linear stage's motions), to
        send to another process: an hour of 1 kHz MoCap is 230 MB of poses, the rest a few
        hundred kB. :meth:`to_dict` and :meth:`summary` are the same on it; the evaluation and
        the plots need :attr:`used`."""
        seed = self.seed_check
        return replace(
            self,
            used=None,
            linear=replace(self.linear, motions=None),
            seed_check=None if seed is None else replace(seed, motions=None),
        )

    def summary(self) -> str:
        """One line: verdict, offset, translation, rotation, inliers, quality (the reasons'
        sentences apart: :meth:`said`)."""
        t = ', '.join(f'{v:.4f}' for v in self.p_HE)
        # the sign of the YAML, the terminal and the messages (w >= 0), not the solver's
        q = ', '.join(f'{v:.4f}' for v in positive_w(self.q_HE))
        std = ''
        if self.batch is not None:
            s = self.batch.std
            std = (
                f' (1-sigma {s[0] * 1e3:.2f} ms, {np.linalg.norm(s[1:4]) * 1e3:.1f} mm, '
                f'{np.degrees(np.linalg.norm(s[4:7])):.2f} deg)'
            )
        extra = ''
        if self.clock_drift is not None:
            extra += f'; clock drift {self.clock_drift * 1e6:+.2f} ppm'
        if self.scale is not None:
            extra += f'; scale {self.scale:.4f}'
        return (
            f'{self.quality.label()}: '
            f'time_offset {self.time_offset_s * 1e3:+.2f} ms (device clock minus MoCap '
            f'clock); device in the marker frame (T_HE): translation [{t}] m, '
            f'rotation xyzw [{q}]; inliers {self.linear.n_inliers}/{self.linear.n_motions}; '
            f'peak correlation {self.time_alignment.peak_correlation:.3f}; '
            f'APE {self.metrics.ape_rmse_m * 1e3:.1f} mm, '
            f'ARE {self.metrics.are_rmse_deg:.2f} deg'
            + std
            + extra
            + (f'; {len(self.warnings)} warning(s)' if self.warnings else '')
        )

    def said(self) -> str:
        """The summary, then each reason of the verdict with what to do, as the node answers
        and logs a calibration."""
        return self.summary() + ''.join(f'. {r.code}: {r.message}' for r in self.quality.reasons)

    def _batch_dict(self) -> dict[str, Any]:
        b, c = self.batch, self.config
        out: dict[str, Any] = {'enabled': c.batch, 'used': b is not None}
        if b is None:
            return out
        out.update(
            {
                'knot_spacing': c.knot_spacing,
                'spline_order': c.spline_order,
                'joint': c.batch_joint,
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
                'time_offset_change': float(
                    self.time_offset_s - self.time_alignment.time_offset_s
                ),
            }
        )
        return out

    def _clock_dict(self) -> dict[str, Any] | None:
        """The offset measured in windows along the recording (eye clock) and the line through
        them: the drift check of every run, the first estimate with clock_drift."""
        c = self.clock
        if c is None:
            return None
        return {
            'windows': [
                {
                    'stamp_ns': int(t),
                    'time_offset': _num(o),
                    'correlation': _num(r),
                    'used': bool(u),
                }
                for t, o, r, u in zip(
                    c.centres_ns, c.offsets_s, c.correlation, c.inliers, strict=True
                )
            ],
            'measured_drift': _num(c.drift),
            'measured_drift_std': _num(c.drift_std),
            'change_over_recording': _num(c.change_s) if c.estimated else None,
            'drift_significant': drift_significant(c),
            'not_estimated_because': c.why or None,
            'units': {'time_offset': 's', 'measured_drift': 's/s', 'change_over_recording': 's'},
        }

    def _screening_dict(self) -> dict[str, Any] | None:
        if self.screening is None:
            return None
        return {
            s.stream: {
                'poses_in': s.n_input,
                'removed': s.counts,
                'fraction': s.fraction,
                'removed_stamps_ns': [int(t) for t in s.removed_ns],
                'removed_kinds': list(s.removed_kind),
                'breaks_ns': [int(t) for t in s.breaks_ns],
                'thresholds': {
                    'translation_m': _num(s.threshold_translation_m),
                    'rotation_deg': _num(np.degrees(s.threshold_rotation_rad)),
                },
            }
            for s in self.screening
        }

    def _std_dict(self) -> dict[str, Any] | None:
        b = self.batch
        if b is None:
            return None
        m = self.eye_model
        return {
            'time_offset': float(b.std[0]),
            'translation': [float(v) for v in b.std[1:4]],
            'rotation': [float(v) for v in b.std[4:7]],
            'clock_drift': (_num(m.drift_std) if m is not None and m.drift_estimated else None),
            'scale': _num(m.scale_std) if m is not None and m.scale_estimated else None,
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

    def to_dict(
        self,
        hand_frame: str = 'hand',
        eye_frame: str = 'eye',
        hand_world: str = 'hand_world',
        eye_world: str = 'eye_world',
    ) -> dict[str, Any]:
        """Plain Python data (floats, lists, strings) for YAML/JSON.

        The frame names label the transforms' parent and child (H, E, G and W).
        """
        R_HE = matrix_from_quat(self.q_HE)
        R_EH, p_EH = inverse((R_HE, self.p_HE))
        return {
            'schema_version': SCHEMA_VERSION,
            'convention': CONVENTION,
            'quality': self.quality.to_dict(),
            'time_offset': float(self.time_offset_s),
            'time_offset_ns': int(self.time_offset_ns),
            'time_offset_stamp': (
                None if self.clock_drift is None else self.eye_model.time_offset_stamp_ns * 1e-9
            ),
            'time_offset_stamp_ns': (
                None if self.clock_drift is None else self.eye_model.time_offset_stamp_ns
            ),
            'clock_drift': self.clock_drift,
            'scale': self.scale,
            'clock': self._clock_dict(),
            'extrinsic': transform_dict(R_HE, self.p_HE, hand_frame, eye_frame),
            'extrinsic_inverse': transform_dict(R_EH, p_EH, eye_frame, hand_frame),
            'world_alignment': {
                **transform_dict(self.world.R_WG, self.world.p_WG, eye_world, hand_world),
                'method': self.world.method,
                'segments': self.world.segments,
            },
            'time_alignment': self._time_alignment_dict(),
            'screening': self._screening_dict(),
            'conventions': [
                {
                    'stream': c.stream,
                    'what': c.what,
                    'assumed': c.assumed,
                    'option': c.option,
                    'message': c.message,
                }
                for c in self.corrections
            ],
            'self_check': [
                {
                    'time_offset': float(c.time_offset_s),
                    'source': c.source,
                    'score': _num(c.score),
                    'rotation_residual_deg': _num(c.rotation_residual_deg),
                    'translation_residual_m': _num(c.translation_residual_m),
                    'chosen': c.chosen,
                }
                for c in self.candidates
            ],
            'association': {'pairs': int(self.n_pairs)},
            'coverage': None if self.coverage is None else self.coverage.to_dict(),
            'readiness': None if self.readiness is None else self.readiness.to_dict(),
            'linear': self._linear_dict(),
            'std': self._std_dict(),
            'covariance': None
            if self.batch is None
            else {
                'order': ['time_offset', 'tx', 'ty', 'tz', 'rx', 'ry', 'rz']
                + ['clock_drift'] * (self.batch.clock_drift is not None)
                + ['scale'] * (self.batch.scale is not None),
                'matrix': [[float(v) for v in row] for row in self.batch.covariance],
            },
            'batch': self._batch_dict(),
            'metrics': self._metrics_dict(),
            'inputs': {
                name: _trajectory_info(info)
                for name, info in (('hand', self.hand), ('eye', self.eye))
            },
            'config': self.config.to_dict(),
            'warnings': list(self.warnings),
        }

    def _linear_dict(self) -> dict[str, Any]:
        """Stage 2: its motions, consensus, solutions and checks."""
        lin = self.linear
        return {
            'relative_poses': self.config.relative_poses,
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
            'decoupled_refit': self.config.decoupled_refit,
            'dual_quaternion_solution': {
                'translation': [float(v) for v in lin.p_HE_dq],
                'rotation': [float(v) for v in positive_w(lin.q_HE_dq)],
            },
            'sigma_ratio': _num(lin.sigma_ratio),
            'singular_values': [float(v) for v in lin.singular_values],
            'axis_spread_deg': _num(lin.axis_spread_deg),
            'rotation_residual_deg': _num(lin.rotation_residual_deg),
            'translation_residual_m': _num(lin.translation_residual_m),
            'unobservable': list(lin.unobservable),
            'seed_check': None
            if self.seed_check is None
            else {
                'seed': self.config.seed + 1,
                'translation': [float(v) for v in self.seed_check.p_HE],
                'rotation': [float(v) for v in positive_w(self.seed_check.q_HE)],
            },
        }

    def _metrics_dict(self) -> dict[str, Any]:
        """APE / ARE of the eye against the calibrated hand, and AX = XB over the keyframe motions."""
        m = self.metrics
        return {
            'ape_rmse': m.ape_rmse_m,
            'are_rmse': m.are_rmse_deg,
            'ape_max': m.ape_max_m,
            'are_max': m.are_max_deg,
            'poses': m.n_poses,
            'motion_rotation_median': _num(m.motion_rotation_deg),
            'motion_translation_median': _num(m.motion_translation_m),
            'motion_length_median': _num(m.motion_length_m),
            'motions': m.n_motions,
            'units': {
                'ape': 'm',
                'are': 'deg',
                'motion_rotation': 'deg',
                'motion_translation': 'm',
                'motion_length': 'm',
            },
        }

    def _time_alignment_dict(self) -> dict[str, Any]:
        """Stage 1: its method, peak, window and candidates, and the vector refinement."""
        ta, vec = self.time_alignment, self.vector_alignment
        return {
            'method': ta.method,
            'peak_correlation': _num(ta.peak_correlation),
            'second_peak_ratio': _num(ta.second_peak_ratio),
            'step': _num(ta.step_s),
            'window': [_num(ta.window_s[0]), _num(ta.window_s[1])],
            'candidates': [
                {'time_offset': float(c), 'correlation': float(r)} for c, r in ta.candidates
            ],
            'vector': None
            if vec is None
            else {
                'time_offset': float(vec.time_offset_s),
                'peak_correlation': _num(vec.peak_correlation),
                'window': [_num(vec.window_s[0]), _num(vec.window_s[1])],
            },
        }


def _noise_dict(n: Any) -> dict[str, Any]:
    return {
        'rotation_rad': float(n.rotation),
        'translation_m': float(n.translation),
        'estimated': bool(n.estimated),
    }


def transform_dict(R: np.ndarray, p: np.ndarray, parent: str, child: str) -> dict[str, Any]:
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


def _trajectory_info(info: TrajectoryInfo) -> dict[str, Any]:
    return {
        'source': info.source,
        'poses': info.poses,
        'rate_hz': info.rate_hz,
        'duration_s': info.duration_s,
        'first_stamp_ns': info.first_stamp_ns,
        'last_stamp_ns': info.last_stamp_ns,
    }


def _num(x: float) -> float | None:
    """JSON has no NaN: unknown values become null."""
    return float(x) if np.isfinite(x) else None


def _uncertainty_dict(u: Any) -> dict[str, Any]:
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
