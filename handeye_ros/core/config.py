"""Options of the calibration, shared by the offline tool's ``--config`` YAML and the node.

The names here are the parameter names everywhere: YAML keys, node parameters and (with ``-``
for ``_``) command-line options. Angles are in degrees, times in seconds, lengths in metres.
Each option's description and range live in its field (see :mod:`.options`).
"""

from __future__ import annotations

from dataclasses import dataclass

from .options import Options, option

#: The hand spline's default knot spacing [s]: about 20 knots/s (hand-held and flying motion,
#: mostly below 5 Hz), chosen not to be commensurate with an eye's frame period. At 0.05 s a
#: 20 Hz (or 10 Hz) eye samples every knot interval at one phase, where the spline's error from
#: the MoCap's noise is not stationary: the eye's relative poses (eq. 16) then read a bias into
#: dt that grows with the square of that noise (bench/results/accuracy.md). This value is the
#: spacing within 10 % of 0.05 s whose eye stamps spread most evenly over the knot interval, in
#: 60 and in 600 frames, at the frame rates cameras and VIOs commonly give (10, 15, 20, 25, 30,
#: 40, 50, 60, 90, 100, 120, 200, 400 Hz): no phase gap above 2.8 times the even one.
KNOT_SPACING_S = 0.0527

PEAK_FITS = ('quadratic', 'none')
#: What the calibration is for (:class:`.checks.verdict.Purpose`'s values, repeated here so
#: that reading the options imports no numpy): what the verdict's "precise enough" means.
PURPOSES = ('evaluation', 'extrinsic')
#: Names of the relative-pose strategies, owned by :data:`.linear.keyframes.STRATEGIES`; repeated here
#: so that reading the options does not import numpy and scipy (instant --help).
RELATIVE_POSES = ('rotation', 'global', 'interframe')


#: Offsets beyond this many seconds are refused as options (317 years: an epoch difference
#: between boot time and Unix time is ~2e9 s; a value in nanoseconds typed as seconds is 1e18).
MAX_OFFSET_S = 1e10


@dataclass(frozen=True)
class CalibrationConfig(Options):
    """Every option of the calibration, with the paper's defaults where the paper has one.

    By default stage 1 searches every lag at which the two recordings overlap, so offsets of
    seconds or minutes and clocks on different epochs are found; ``max_time_offset`` (with
    ``time_offset_guess``, default 0) narrows the search to a window when the offset is known
    to lie in one (a narrower window makes a spurious peak on a repetitive motion less likely).
    """

    time_offset: float | None = option(
        None,
        'float',
        'fix the time offset dt = eye clock - hand clock [s] instead of '
        'estimating it; NaN/null estimates it',
        optional=True,
        low=-MAX_OFFSET_S,
        high=MAX_OFFSET_S,
    )
    time_offset_guess: float | None = option(
        None,
        'float',
        'centre of the time offset search window [s] (with max_time_offset; '
        'alone it sets a window of +-0.5 s); NaN/null: no window',
        optional=True,
        low=-MAX_OFFSET_S,
        high=MAX_OFFSET_S,
    )
    max_time_offset: float | None = option(
        None,
        'float',
        'half-width of the time offset search window [s]; NaN/null searches '
        'every lag at which the recordings overlap',
        optional=True,
        low=0.0,
        high=MAX_OFFSET_S,
        open_low=True,
    )
    resample_rate_hz: float | None = option(
        None,
        'float',
        'rate of the correlation grid [Hz]; NaN/null: the faster stream, at most 200 Hz',
        optional=True,
        low=0.0,
        high=10_000.0,
        open_low=True,
        expert=True,
    )
    clock_drift: bool = option(
        False,
        'bool',
        'estimate a linear clock, dt(t) = time_offset + clock_drift * (t - '
        'time_offset_stamp), instead of one constant offset (without it the offset is still '
        'measured along the recording, and a drift beyond its uncertainty is fitted: '
        'auto_drift)',
    )
    auto_drift: bool = option(
        True,
        'bool',
        'fit the clock drift in the same run when the offset measured along the recording '
        'drifts beyond its uncertainty (said in a note); off: one constant offset unless '
        'clock_drift',
        alias='clock-drift',
        expert=True,
    )
    estimate_scale: bool = option(
        False,
        'bool',
        "estimate the eye's scale s (s * eye positions are metric: a monocular "
        'VO) in all stages (without it a scale the data show is named)',
        alias='scale',
    )
    peak_fit: str = option(
        'quadratic',
        'str',
        'correlation peak: quadratic (sub-sample fit, the paper) or none '
        '(integer peak, the baseline)',
        choices=PEAK_FITS,
        ablation=True,
    )
    relative_poses: str = option(
        'rotation',
        'str',
        'relative motions: rotation (keyframes at least eta apart, the '
        'paper), global or interframe',
        choices=RELATIVE_POSES,
        ablation=True,
    )
    eta: float = option(
        5.0,
        'float',
        'minimum rotation between keyframes [deg] (eq. 6); below 0.01 deg the rotation is noise',
        low=0.01,
        high=90.0,
        expert=True,
    )
    robust_kernel: bool = option(
        True,
        'bool',
        'weight motions by the screw-congruence kernel (eq. 10-12)',
        ablation=True,
    )
    mu: float = option(
        5.0, 'float', 'robust kernel sharpness mu (eq. 11)', low=0.0, high=1000.0, expert=True
    )
    ransac_iterations: int = option(
        200,
        'int',
        'RANSAC two-motion hypotheses; 0 disables RANSAC (evaluated in chunks: '
        'memory stays flat, time grows with the count)',
        low=0,
        high=100_000,
        expert=True,
    )
    inlier_rotation: float = option(
        0.5,
        'float',
        'RANSAC inlier threshold on the rotation error e1 of eq. 13 [deg]',
        low=0.0,
        high=180.0,
        open_low=True,
        expert=True,
    )
    inlier_translation: float = option(
        0.02,
        'float',
        'RANSAC inlier threshold on the translation error e2 of eq. 13 [m]',
        low=0.0,
        high=100.0,
        open_low=True,
        expert=True,
    )
    adaptive_inliers: bool = option(
        True,
        'bool',
        'widen the final consensus thresholds to the noise measured from the '
        'best model (never narrower than the configured ones)',
        ablation=True,
    )
    decoupled_refit: bool = option(
        True,
        'bool',
        're-estimate rotation (rotation-vector alignment) and translation '
        '(drift-weighted least squares) apart on the final consensus; false keeps the '
        'dual-quaternion solution',
        ablation=True,
    )
    batch: bool = option(
        True,
        'bool',
        'refine dt and T_HE by the continuous-time batch stage (Section III-C) and '
        'report their covariance; the linear result is kept, with a warning, if it fails',
        expert=True,
    )
    knot_spacing: float = option(
        KNOT_SPACING_S,
        'float',
        'knot spacing of the hand B-spline [s]: about 20 knots/s follow hand-held and '
        'flying motion (mostly below 5 Hz) from MoCap at >= 100 Hz; not a multiple or a '
        "divisor of the eye's frame period (at 0.05 s, a 20 Hz eye meets the knots at one "
        "phase, and the MoCap's noise biases dt); a MoCap of fewer than two samples a knot "
        'interval gets its own sample period, and one noisy for its eye up to four times '
        "the spacing where the eye's residuals say it predicts them better",
        low=0.005,
        high=1.0,
        expert=True,
    )
    spline_order: int = option(
        4, 'int', 'order of the hand B-spline (4: cubic)', low=3, high=6, expert=True
    )
    batch_decoupled: bool = option(
        True,
        'bool',
        'batch stage: the rotation of T_HE from the rotation residuals alone, then '
        'dt and the translation from all residuals (false: all together)',
        ablation=True,
    )
    hand_noise_rotation: float | None = option(
        None,
        'float',
        'hand (MoCap) noise of each pose per axis [rad]; NaN/null estimates it from the data',
        optional=True,
        low=0.0,
        high=1.0,
        open_low=True,
        expert=True,
    )
    hand_noise_translation: float | None = option(
        None,
        'float',
        'hand (MoCap) noise of each pose per axis [m]; NaN/null estimates it',
        optional=True,
        low=0.0,
        high=10.0,
        open_low=True,
        expert=True,
    )
    eye_noise_rotation: float | None = option(
        None,
        'float',
        'eye relative-pose noise per axis between consecutive poses [rad]; '
        'NaN/null estimates it from the data',
        optional=True,
        low=0.0,
        high=1.0,
        open_low=True,
        expert=True,
    )
    eye_noise_translation: float | None = option(
        None,
        'float',
        'eye relative-pose noise per axis between consecutive poses [m]; NaN/null estimates it',
        optional=True,
        low=0.0,
        high=10.0,
        open_low=True,
        expert=True,
    )
    huber_delta: float = option(
        1.345,
        'float',
        'Huber threshold of the batch stage, in noise standard deviations '
        '(1.345: 95 % efficiency on Gaussian noise; below 0.01 it is an L1 loss already)',
        low=0.01,
        high=1000.0,
        expert=True,
    )
    batch_max_iterations: int = option(
        50,
        'int',
        'most solver iterations of the batch stage',
        low=1,
        high=10_000,
        expert=True,
    )
    screening: bool = option(
        True,
        'bool',
        'remove isolated pose outliers (placeholders, marker swaps, glitches) '
        'before stage 1 and split the eye at VIO resets found against the hand',
        expert=True,
    )
    outlier_threshold: float = option(
        6.0,
        'float',
        'screening: a pose is an outlier when its interpolation residual exceeds '
        'the running median by this many robust standard deviations',
        low=3.0,
        high=1000.0,
        expert=True,
    )
    max_outlier_fraction: float = option(
        0.15,
        'float',
        'refuse a stream of which screening would remove more than this fraction as wrong '
        '(damaged rows, outliers; not placeholders or short segments: missing, not wrong)',
        low=0.0,
        high=1.0,
        open_low=True,
        expert=True,
    )
    check_conventions: bool = option(
        True,
        'bool',
        'detect stamp units and quaternion orders or inverted poses the data '
        'contradict, and apply the reading the data support (the verdict then says so)',
        expert=True,
    )
    invert_hand: bool = option(
        False,
        'bool',
        'the hand poses are T_HG (marker to MoCap world), not T_GH',
        expert=True,
    )
    invert_eye: bool = option(
        False,
        'bool',
        'the eye poses are T_EW (VIO world in body), not T_WE',
        expert=True,
    )
    purpose: str = option(
        'evaluation',
        'str',
        'what the result is for, which decides what precise enough means: evaluation (each '
        "APE/RPE figure's calibration 1-sigma within 5 % of it) or extrinsic (T_HE and dt "
        'within the precision_* targets); the result gives both verdicts',
        choices=PURPOSES,
    )
    precision_time_offset: float = option(
        1e-3,
        'float',
        'verdict for purpose extrinsic: a 1-sigma of the time offset above this [s] makes the '
        'result doubtful (reason imprecise)',
        low=0.0,
        high=3600.0,
        open_low=True,
        expert=True,
    )
    precision_translation: float = option(
        0.01,
        'float',
        'verdict for purpose extrinsic: a 1-sigma of the translation of T_HE above this [m] '
        'makes the result doubtful',
        low=0.0,
        high=100.0,
        open_low=True,
        expert=True,
    )
    precision_rotation: float = option(
        0.5,
        'float',
        'verdict for purpose extrinsic: a 1-sigma of the rotation of T_HE above this [deg] '
        'makes the result doubtful',
        low=0.0,
        high=180.0,
        open_low=True,
        expert=True,
    )
    held_lever_arm: float = option(
        0.0,
        'float',
        'where the motion turns about one axis only (a ground robot): the translation of T_HE '
        'along that axis [m], which no metric depends on and the data cannot tell, held here',
        low=-100.0,
        high=100.0,
        expert=True,
    )
    min_motions: int = option(
        10, 'int', 'fewest relative motions accepted', low=2, high=1_000_000, expert=True
    )
    seed: int = option(
        0,
        'int',
        'RANSAC seed: the same input and seed give the same result',
        low=0,
        high=2**31 - 1,
        expert=True,
    )

    @property
    def precision(self) -> tuple[float, float, float]:
        """The verdict's 1-sigma targets: time offset [s], translation [m], rotation [deg]."""
        return (self.precision_time_offset, self.precision_translation, self.precision_rotation)
