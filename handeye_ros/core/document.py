"""The schema of the result document: what :meth:`~.result.CalibrationResult.to_dict` writes
(YAML, JSON, the node's ``~/save``), section by section, and the keys the front ends add
(``summary``, ``evaluation``, ``files``, ``streams``, ``rig``).

Typed dictionaries, so that every writer and reader of a key is checked against one
declaration; units as the document's own ``units`` entries say (SI, rotations as quaternions
x y z w or in the named unit). An unknown value is null (JSON has no NaN): ``float | None``.
"""

from __future__ import annotations

from typing import Literal, NotRequired, Required, TypeAlias, TypedDict

#: A value of a plain-data document (JSON's types).
Json: TypeAlias = str | int | float | bool | None | list['Json'] | dict[str, 'Json']
#: A run's row of the many-recordings tables (``evaluate``): its cells by column name.
Row: TypeAlias = dict[str, Json]


class Reason(TypedDict):
    code: str
    severity: str
    message: str


class JudgedDoc(TypedDict):
    verdict: str
    codes: list[str]


class EvaluationJudgedDoc(JudgedDoc):
    figures_judged: bool


class QualityDoc(TypedDict):
    verdict: str
    purpose: str
    reasons: list[Reason]
    notes: list[str]
    for_evaluation: EvaluationJudgedDoc
    for_extrinsic: JudgedDoc


class ClockWindow(TypedDict):
    stamp_ns: int
    time_offset: float | None
    correlation: float | None
    used: bool


class ClockDoc(TypedDict):
    windows: list[ClockWindow]
    measured_drift: float | None
    measured_drift_std: float | None
    change_over_recording: float | None
    drift_significant: bool
    not_estimated_because: str | None
    units: dict[str, str]


class TransformDoc(TypedDict):
    """T_parent_child: translation [m], rotation x y z w, the 4 x 4 matrix."""

    parent: str
    child: str
    translation: list[float]
    rotation: list[float]
    matrix: list[list[float]]


class WorldDoc(TransformDoc):
    method: str
    segments: int


class OffsetCandidate(TypedDict):
    time_offset: float
    correlation: float


class TimeAlignmentDoc(TypedDict):
    method: str
    peak_correlation: float | None
    second_peak_ratio: float | None
    step: float | None
    window: list[float | None]
    candidates: list[OffsetCandidate]


class Thresholds(TypedDict):
    translation_m: float | None
    rotation_deg: float | None


class ScreeningDoc(TypedDict):
    poses_in: int
    removed: dict[str, int]
    fraction: float
    short_segment_fraction: float
    removed_stamps_ns: list[int]
    removed_kinds: list[str]
    breaks_ns: list[int]
    thresholds: Thresholds


class ConventionDoc(TypedDict):
    stream: str
    what: str
    assumed: str
    option: str
    message: str


class SelfCheckDoc(TypedDict):
    time_offset: float
    source: str
    score: float | None
    rotation_residual_deg: float | None
    translation_residual_m: float | None
    chosen: bool


class CoverageDoc(TypedDict):
    hand_gaps: int
    hand_gap_s: float
    longest_hand_gap_s: float
    eye_s: float
    covered_s: float
    fraction: float


class StatusDoc(TypedDict):
    """The node's status while recording (:class:`.checks.readiness.Readiness`): READY, the
    latest calibration of the buffers (its verdict, the span it calibrated and its age [s],
    its 1-sigmas by the keys time_offset_ms, translation_mm and rotation_deg) and the motion so
    far."""

    ready: bool
    purpose: str
    verdict: str | None
    calibrated_span_s: float | None
    age_s: float | None
    checking: bool
    sigma: dict[str, float | None]
    rotation_deg: dict[str, float]
    axis_spread_deg: float
    angular_speed_dps: float
    travel_m: float
    span_s: float
    dropout: dict[str, float]
    missing: list[str]


class Extrinsic(TypedDict):
    translation: list[float]
    rotation: list[float]


class SeedCheck(Extrinsic):
    seed: int


class LinearDoc(TypedDict):
    relative_poses: str
    motions: int
    inliers: int
    inlier_thresholds: dict[str, float]
    extrinsic: Extrinsic
    decoupled_refit: bool
    dual_quaternion_solution: Extrinsic
    sigma_ratio: float | None
    singular_values: list[float]
    axis_spread_deg: float | None
    rotation_residual_deg: float | None
    translation_residual_m: float | None
    unobservable: list[str]
    seed_check: SeedCheck | None


class EyeScale(TypedDict):
    scale: float
    std: float


class UncertaintyDoc(TypedDict, total=False):
    """The reported 1-sigma's terms (white, correlated, scale) per group (norms over the
    axes, in the groups' units), the term that dominates each, and what was not estimated."""

    terms: dict[str, dict[str, float]]
    dominant: dict[str, str]
    over_long_run: dict[str, float]
    block_factors: dict[str, float] | None
    eye_scale: EyeScale | None
    not_estimated: list[str]


class StdDoc(UncertaintyDoc):
    """Stage 3's 1-sigmas: time_offset [s], translation [m] and rotation [rad] per axis."""

    time_offset: Required[float]
    translation: Required[list[float]]
    rotation: Required[list[float]]
    clock_drift: Required[float | None]
    scale: Required[float | None]
    units: Required[dict[str, str]]
    method: Required[str]
    white_inflation: Required[list[float]]


class CovarianceDoc(TypedDict):
    order: list[str]
    matrix: list[list[float]]


class NoiseDoc(TypedDict):
    rotation_rad: float
    translation_m: float
    estimated: bool


class BatchDoc(TypedDict):
    enabled: bool
    used: bool
    knot_spacing: NotRequired[float]
    spline_order: NotRequired[int]
    decoupled: NotRequired[bool]
    control_points: NotRequired[int]
    residuals: NotRequired[dict[str, int]]
    noise: NotRequired[dict[str, NoiseDoc]]
    iterations: NotRequired[int]
    evaluations: NotRequired[int]
    cost_before: NotRequired[float]
    cost_after: NotRequired[float]
    reduced_chi2: NotRequired[float]
    termination: NotRequired[str]
    converged: NotRequired[bool]
    seconds: NotRequired[float]
    time_offset_change: NotRequired[float]
    mocap_noise_move: NotRequired[float | None]


class MetricsDoc(TypedDict):
    ape_rmse: float
    are_rmse: float
    ape_max: float
    are_max: float
    poses: int
    motion_rotation_median: float | None
    motion_translation_median: float | None
    motion_length_median: float | None
    motions: int
    units: dict[str, str]


class TrajectoryDoc(TypedDict):
    source: str
    poses: int
    rate_hz: float
    duration_s: float
    first_stamp_ns: int
    last_stamp_ns: int


class InputsDoc(TypedDict):
    """The two trajectories read, and the bag they came from."""

    hand: TrajectoryDoc
    eye: TrajectoryDoc
    bag: NotRequired[str]


class ErrorStatsDoc(TypedDict):
    """One error's statistics (m or deg); ``calibration_sigma``: their 1-sigmas from the
    calibration's uncertainty, on the calibrated figures."""

    rmse: float | None
    mean: float | None
    median: float | None
    max: float | None
    n: int
    calibration_sigma: NotRequired[dict[str, float | None]]


#: The six errors of :class:`PoseErrorsDoc`, as keys.
ErrorKey: TypeAlias = Literal[
    'ape_translation',
    'ape_rotation',
    'rpe_time_translation',
    'rpe_time_rotation',
    'rpe_distance_translation',
    'rpe_distance_rotation',
]


class PoseErrorsDoc(TypedDict):
    what: str
    ape_translation: ErrorStatsDoc
    ape_rotation: ErrorStatsDoc
    rpe_time_translation: ErrorStatsDoc
    rpe_time_rotation: ErrorStatsDoc
    rpe_distance_translation: ErrorStatsDoc
    rpe_distance_rotation: ErrorStatsDoc


class SigmasMethodDoc(TypedDict, total=False):
    draws: int
    poses: int
    parameters: list[str]
    method: str
    sigmas: dict[str, dict[str, float | None]]
    why_not: str


class EvaluationDoc(TypedDict):
    rpe_delta_s: float
    rpe_delta_m: float
    units: dict[str, str]
    calibrated: PoseErrorsDoc
    uncalibrated: PoseErrorsDoc | None
    uncalibrated_why: str | None
    calibration_sigmas: SigmasMethodDoc


class FilesDoc(TypedDict, total=False):
    export: list[str]
    report: str


class StreamDoc(TypedDict):
    """The node's bookkeeping of one stream (:meth:`~handeye_ros.stream.Recorder.stream_dict`)."""

    topic: str
    type: str | None
    stamps: str
    received: int
    buffered: int
    dropped: int
    rejected: dict[str, int]
    span_s: float
    rate_hz: float
    frames: NotRequired[dict[str, str]]
    tf_chain: NotRequired[list[str]]


class RigPartDoc(TypedDict, total=False):
    """How one recording's result stands to the rig it belongs to."""

    own: dict[str, Json]
    follower: bool
    file: str
    session: str
    part: str
    recordings: int
    verdict: str
    reasons: list[str]


class ResultDoc(TypedDict):
    """A calibration's result document."""

    schema_version: int
    convention: str
    quality: QualityDoc
    time_offset: float
    time_offset_ns: int
    time_offset_stamp: float | None
    time_offset_stamp_ns: int | None
    clock_drift: float | None
    scale: float | None
    clock: ClockDoc | None
    extrinsic: TransformDoc
    extrinsic_inverse: TransformDoc
    world_alignment: WorldDoc
    time_alignment: TimeAlignmentDoc
    screening: dict[str, ScreeningDoc] | None
    conventions: list[ConventionDoc]
    self_check: list[SelfCheckDoc]
    association: dict[str, int]
    coverage: CoverageDoc | None
    linear: LinearDoc
    std: StdDoc | None
    covariance: CovarianceDoc | None
    batch: BatchDoc
    metrics: MetricsDoc
    inputs: InputsDoc
    config: dict[str, Json]
    warnings: list[str]
    # added by the front ends
    summary: NotRequired[str]
    evaluation: NotRequired[EvaluationDoc]
    files: NotRequired[FilesDoc]
    streams: NotRequired[dict[str, StreamDoc]]
    rig: NotRequired[RigPartDoc]
