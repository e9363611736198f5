"""Options of the calibration, shared by the offline tool's ``--config`` YAML and the node.

The names here are the parameter names everywhere: YAML keys, node parameters and (with ``-``
for ``_``) command-line options. Angles are in degrees, times in seconds, lengths in metres.
Each option's description and range live in its field (see :mod:`.options`).
"""

from __future__ import annotations

from dataclasses import dataclass

from .options import Options, option

PEAK_FITS = ('quadratic', 'none')
#: Relative-pose strategies (see :mod:`.keyframes`); kept here so that reading the options
#: does not import numpy and scipy (instant --help).
STRATEGIES = ('rotation', 'global', 'interframe')


@dataclass(frozen=True)
class CalibrationConfig(Options):
    """Every option of stages 1 and 2, with the paper's defaults.

    ``max_time_offset`` = 0.5 s covers the latency between a MoCap system and a VIO recorded on
    one machine (transport, exposure, filter delay: typically 5-200 ms) with margin, while a
    narrower window makes a spurious peak on a repetitive motion less likely; clocks that
    differ by more need ``time_offset_guess``.
    """

    time_offset: float | None = option(
        None, 'float', 'fix the time offset dt = eye clock - hand clock [s] instead of '
        'estimating it; NaN/null estimates it', optional=True)
    time_offset_guess: float = option(
        0.0, 'float', 'centre of the time offset search window [s]')
    max_time_offset: float = option(
        0.5, 'float', 'half-width of the time offset search window [s]', low=0.0, high=3600.0,
        open_low=True)
    resample_rate_hz: float | None = option(
        None, 'float', 'rate of the correlation grid [Hz]; NaN/null: the faster stream, at most '
        '200 Hz', optional=True, low=0.0, high=10_000.0, open_low=True)
    peak_fit: str = option(
        'quadratic', 'str', 'correlation peak: quadratic (sub-sample fit, the paper) or none '
        '(integer peak, the baseline)', choices=PEAK_FITS)
    relative_poses: str = option(
        'rotation', 'str', 'relative motions: rotation (keyframes at least eta apart, the '
        'paper), global or interframe', choices=STRATEGIES)
    eta: float = option(
        5.0, 'float', 'minimum rotation between keyframes [deg] (eq. 9)', low=0.0, high=90.0,
        open_low=True)
    robust_kernel: bool = option(
        True, 'bool', 'weight motions by the screw-congruence kernel (eq. 13)')
    mu: float = option(
        5.0, 'float', 'robust kernel sharpness (eq. 13)', low=0.0, high=1000.0)
    ransac_iterations: int = option(
        200, 'int', 'RANSAC two-motion hypotheses; 0 disables RANSAC', low=0, high=1_000_000)
    inlier_rotation: float = option(
        0.5, 'float', 'RANSAC inlier threshold on the rotation error of eq. 14 [deg]', low=0.0,
        high=180.0, open_low=True)
    inlier_translation: float = option(
        0.02, 'float', 'RANSAC inlier threshold on the translation error of eq. 14 [m]',
        low=0.0, high=100.0, open_low=True)
    adaptive_inliers: bool = option(
        True, 'bool', 'widen the final consensus thresholds to the noise measured from the '
        'best model (never narrower than the configured ones)')
    decoupled_refit: bool = option(
        True, 'bool', 're-estimate rotation (rotation-vector alignment) and translation '
        '(drift-weighted least squares) apart on the final consensus; false keeps the '
        'dual-quaternion solution')
    batch: bool = option(
        True, 'bool', 'refine dt and T_HE by the continuous-time batch stage (Section III-C) and '
        'report their covariance; the linear result is kept, with a warning, if it fails')
    knot_spacing: float = option(
        0.05, 'float', 'knot spacing of the hand B-spline [s]: 20 knots/s follow hand-held and '
        'flying motion (mostly below 5 Hz) from MoCap at >= 100 Hz', low=0.005, high=1.0)
    spline_order: int = option(
        4, 'int', 'order of the hand B-spline (4: cubic)', low=3, high=6)
    batch_decoupled: bool = option(
        True, 'bool', 'batch stage: the rotation of T_HE from the rotation residuals alone, then '
        'dt and the translation from all residuals (false: all together)')
    batch_joint: bool = option(
        False, 'bool', 'also free the spline control poses in the batch solve (the full joint '
        'problem; slower, the same result while the MoCap is much less noisy than the VIO)')
    hand_noise_rotation: float | None = option(
        None, 'float', 'hand (MoCap) noise of each pose per axis [rad]; NaN/null estimates it '
        'from the data', optional=True, low=0.0, high=1.0, open_low=True)
    hand_noise_translation: float | None = option(
        None, 'float', 'hand (MoCap) noise of each pose per axis [m]; NaN/null estimates it',
        optional=True, low=0.0, high=10.0, open_low=True)
    eye_noise_rotation: float | None = option(
        None, 'float', 'eye relative-pose noise per axis between consecutive poses [rad]; '
        'NaN/null estimates it from the data', optional=True, low=0.0, high=1.0, open_low=True)
    eye_noise_translation: float | None = option(
        None, 'float', 'eye relative-pose noise per axis between consecutive poses [m]; '
        'NaN/null estimates it', optional=True, low=0.0, high=10.0, open_low=True)
    huber_delta: float = option(
        1.345, 'float', 'Huber threshold of the batch stage, in noise standard deviations '
        '(1.345: 95 % efficiency on Gaussian noise)', low=0.0, high=1000.0, open_low=True)
    batch_max_iterations: int = option(
        50, 'int', 'most solver iterations of the batch stage', low=1, high=10_000)
    min_motions: int = option(
        10, 'int', 'fewest relative motions accepted', low=2, high=1_000_000)
    seed: int = option(
        0, 'int', 'RANSAC seed: the same input and seed give the same result', low=0,
        high=2 ** 31 - 1)
