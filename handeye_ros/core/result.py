"""The calibration result and its plain-data form (written as YAML/JSON, published by the node).

The document's schema is versioned (key ``schema_version``); its history is in CHANGELOG.md.

Every transform is written as ``{translation: [x, y, z] (m), rotation: [qx, qy, qz, qw],
matrix: 4x4 rows}`` with the parent/child frames spelled out, as Kalibr does, so that nobody has
to guess the direction.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from .arrays import Floats, Stamps
from .batch.refine import BatchSolution
from .checks.conventions import Correction
from .checks.coverage import Coverage
from .checks.screening import Screening
from .checks.selfcheck import Candidate
from .checks.verdict import Quality, Verdict
from .config import CalibrationConfig
from .document import ResultDoc
from .eye_model import EyeModel
from .geometry import inverse, matrix_from_quat, positive_w
from .linear.robust import LinearSolution
from .result_sections import (
    batch_section,
    clock_section,
    conventions_entry,
    covariance_section,
    linear_section,
    metrics_section,
    screening_section,
    self_check_entry,
    std_section,
    time_alignment_section,
    trajectory_section,
    transform_dict,
)
from .time.align import TimeAlignment
from .time.clock import DriftFit, linear_clock
from .trajectory import Trajectory, TrajectoryInfo
from .world import Metrics, WorldAlignment

SCHEMA_VERSION = 11
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
    eye_stamps_ns: Stamps
    time_offset_s: float


@dataclass(frozen=True)
class CalibrationResult:
    """Everything the calibration found, in the package conventions.

    ``q_HE, p_HE`` is the extrinsic T_HE (eye frame E in hand frame H), ``time_offset_s`` is dt.
    ``hand``, ``eye``: the input streams as given (name, count, rate, stamps), without their
    poses; ``used`` has the poses the calibration ended on (None once :meth:`detached`).
    """

    time_offset_s: float
    q_HE: Floats
    p_HE: Floats
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
    screening: tuple[Screening, Screening] | None = None
    corrections: tuple[Correction, ...] = ()
    candidates: tuple[Candidate, ...] = ()
    quality: Quality = field(default_factory=lambda: Quality(Verdict.GOOD))
    seed_check: LinearSolution | None = None
    eye_model: EyeModel | None = None
    clock: DriftFit | None = None
    used: UsedStreams | None = field(default=None, repr=False, compare=False)
    coverage: Coverage | None = None

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

    def time_offset_at(self, t_eye_ns: Stamps) -> Floats:
        """dt(t) [s] at eye stamps [ns, eye clock]: the time offset with the drift, if any."""
        if self.clock_drift is None or self.eye_model is None:
            return np.full(np.shape(t_eye_ns), self.time_offset_s)
        return linear_clock(
            self.time_offset_s, self.clock_drift, self.eye_model.time_offset_stamp_ns, t_eye_ns
        )

    def streams(self) -> UsedStreams:
        """:attr:`used`, the poses the evaluation and the plots read; ValueError for a result
        without them (:meth:`detached`, or read from a file)."""
        if self.used is None:
            msg = 'this result does not hold the streams it was computed on'
            raise ValueError(msg)
        return self.used

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

    def to_dict(
        self,
        hand_frame: str = 'hand',
        eye_frame: str = 'eye',
        hand_world: str = 'hand_world',
        eye_world: str = 'eye_world',
    ) -> ResultDoc:
        """Plain Python data (floats, lists, strings) for YAML/JSON (:mod:`.document`).

        The frame names label the transforms' parent and child (H, E, G and W).
        """
        R_HE = matrix_from_quat(self.q_HE)
        R_EH, p_EH = inverse((R_HE, self.p_HE))
        model = None if self.clock_drift is None else self.eye_model
        stamp_ns = None if model is None else model.time_offset_stamp_ns
        doc: ResultDoc = {
            'schema_version': SCHEMA_VERSION,
            'convention': CONVENTION,
            'quality': self.quality.to_dict(),
            'time_offset': float(self.time_offset_s),
            'time_offset_ns': int(self.time_offset_ns),
            'time_offset_stamp': None if stamp_ns is None else stamp_ns * 1e-9,
            'time_offset_stamp_ns': stamp_ns,
            'clock_drift': self.clock_drift,
            'scale': self.scale,
            'clock': clock_section(self.clock),
            'extrinsic': transform_dict(R_HE, self.p_HE, hand_frame, eye_frame),
            'extrinsic_inverse': transform_dict(R_EH, p_EH, eye_frame, hand_frame),
            'world_alignment': {
                **transform_dict(self.world.R_WG, self.world.p_WG, eye_world, hand_world),
                'method': self.world.method,
                'segments': self.world.segments,
            },
            'time_alignment': time_alignment_section(self.time_alignment),
            'screening': screening_section(self.screening),
            'conventions': [conventions_entry(c) for c in self.corrections],
            'self_check': [self_check_entry(c) for c in self.candidates],
            'association': {'pairs': int(self.n_pairs)},
            'coverage': None if self.coverage is None else self.coverage.to_dict(),
            'linear': linear_section(self.linear, self.config, self.seed_check),
            'std': std_section(self.batch, self.eye_model),
            'covariance': covariance_section(self.batch),
            'batch': batch_section(
                self.batch, self.config, self.time_offset_s - self.time_alignment.time_offset_s
            ),
            'metrics': metrics_section(self.metrics),
            'inputs': {'hand': trajectory_section(self.hand), 'eye': trajectory_section(self.eye)},
            'config': {**self.config.to_dict(), **self.config.ablations()},
            'warnings': list(self.warnings),
        }
        return doc
