"""Options of the calibration, shared by the offline tool's ``--config`` YAML and the node.

The names here are the parameter names everywhere: YAML keys, node parameters and (with ``-``
for ``_``) command-line options. Angles are in degrees, times in seconds, lengths in metres.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace
from typing import Any

from .errors import ConfigError
from .keyframes import STRATEGIES

PEAK_FITS = ('quadratic', 'none')


@dataclass(frozen=True)
class CalibrationConfig:
    """Every option of stages 1 and 2, with the paper's defaults.

    Attributes
    ----------
    time_offset : float or None
        Fix dt (s, eye clock minus hand clock) instead of estimating it; None estimates it.
    time_offset_guess : float
        Centre of the offset search window, s.
    max_time_offset : float
        Half-width of the search window, s. 0.5 s covers the latency between a MoCap system and
        a VIO recorded on one machine (transport, exposure, filter delay: typically 5-200 ms)
        with margin, while a narrower window makes a spurious peak on a repetitive motion less
        likely. Clocks that differ by more need ``time_offset_guess``.
    resample_rate_hz : float or None
        Rate of the common grid for the correlation; None takes the faster stream's rate,
        capped at 200 Hz.
    peak_fit : str
        'quadratic' (sub-sample parabola, the paper's) or 'none' (integer peak, the baseline).
    relative_poses : str
        'rotation' (keyframes at least eta apart, the paper's), 'global' or 'interframe'.
    eta : float
        Minimum rotation between keyframes, degrees (paper: 5).
    robust_kernel : bool
        Weight motions by the screw-congruence kernel (eq. 13).
    mu : float
        Kernel sharpness (paper: 5).
    ransac_iterations : int
        Two-motion hypotheses drawn; 0 disables RANSAC (one robust solve on all motions).
    inlier_rotation : float
        RANSAC inlier threshold on the rotation error of eq. 14, degrees (paper: 0.5).
    inlier_translation : float
        RANSAC inlier threshold on the translation error of eq. 14, metres (paper: 0.02).
    adaptive_inliers : bool
        Widen the inlier thresholds of the final consensus to the noise measured from the best
        model's residuals (never narrower than the configured ones); see ``calibrate_linear``.
    decoupled_refit : bool
        Re-estimate T_HE on the final consensus with rotation (rotation-vector alignment) and
        translation (drift-weighted least squares) apart (see ``handeye_ros.core.linear``);
        False keeps the paper's dual-quaternion solution.
    min_motions : int
        Fewer relative motions than this is an error (too little rotation).
    seed : int
        Seed of the RANSAC sampler: the same input and seed give the same result.
    """

    time_offset: float | None = None
    time_offset_guess: float = 0.0
    max_time_offset: float = 0.5
    resample_rate_hz: float | None = None
    peak_fit: str = 'quadratic'
    relative_poses: str = 'rotation'
    eta: float = 5.0
    robust_kernel: bool = True
    mu: float = 5.0
    ransac_iterations: int = 200
    inlier_rotation: float = 0.5
    inlier_translation: float = 0.02
    adaptive_inliers: bool = True
    decoupled_refit: bool = True
    min_motions: int = 10
    seed: int = 0

    def __post_init__(self) -> None:
        _check_choice('peak_fit', self.peak_fit, PEAK_FITS)
        _check_choice('relative_poses', self.relative_poses, STRATEGIES)
        _check_range('time_offset_guess', self.time_offset_guess, None, None)
        _check_range('max_time_offset', self.max_time_offset, 0.0, None, open_low=True)
        _check_range('eta', self.eta, 0.0, 90.0, open_low=True)
        _check_range('mu', self.mu, 0.0, None)
        _check_range('ransac_iterations', self.ransac_iterations, 0, 1_000_000)
        _check_range('inlier_rotation', self.inlier_rotation, 0.0, 180.0, open_low=True)
        _check_range('inlier_translation', self.inlier_translation, 0.0, None, open_low=True)
        _check_range('min_motions', self.min_motions, 2, None)
        if self.time_offset is not None:
            _check_range('time_offset', self.time_offset, None, None)
        if self.resample_rate_hz is not None:
            _check_range('resample_rate_hz', self.resample_rate_hz, 0.0, 10_000.0,
                         open_low=True)

    @classmethod
    def from_mapping(cls, values: dict[str, Any], source: str = 'config') -> CalibrationConfig:
        """Options from a mapping (a parsed YAML file or node parameters).

        Unknown keys are refused (a typo must not silently fall back to a default); null or NaN
        for ``time_offset`` / ``resample_rate_hz`` mean 'estimate' / 'automatic'.
        """
        if not isinstance(values, dict):
            msg = f'{source}: expected a mapping of option names to values'
            raise ConfigError(msg)
        known = {f.name: f for f in fields(cls)}
        unknown = sorted(set(values) - set(known))
        if unknown:
            msg = (f'{source}: unknown option(s) {", ".join(unknown)}; known options are '
                   f'{", ".join(known)}')
            raise ConfigError(msg)
        clean: dict[str, Any] = {}
        default = cls()
        for key, value in values.items():
            clean[key] = _coerce(key, value, getattr(default, key), source)
        try:
            return replace(default, **clean)
        except ConfigError as err:
            raise ConfigError(f'{source}: {err}') from None

    def to_dict(self) -> dict[str, Any]:
        """Plain values, the inverse of :meth:`from_mapping`."""
        return asdict(self)


def _coerce(key: str, value: Any, default: Any, source: str) -> Any:
    optional = key in ('time_offset', 'resample_rate_hz')
    if optional and (value is None or (isinstance(value, float) and math.isnan(value))):
        return None
    expected = type(default) if default is not None else float
    if expected is bool:
        if isinstance(value, bool):
            return value
    elif expected is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
    elif expected is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    elif isinstance(value, expected):
        return value
    msg = f'{source}: option {key} must be of type {expected.__name__}, got {value!r}'
    raise ConfigError(msg)


def _check_choice(name: str, value: str, choices: tuple[str, ...]) -> None:
    if value not in choices:
        msg = f'option {name} must be one of {", ".join(choices)}; got {value!r}'
        raise ConfigError(msg)


def _check_range(name: str, value: float, low: float | None, high: float | None,
                 open_low: bool = False) -> None:
    if not math.isfinite(value):
        msg = f'option {name} must be a finite number; got {value!r}'
        raise ConfigError(msg)
    too_low = low is not None and (value <= low if open_low else value < low)
    if too_low or (high is not None and value > high):
        bound = f'{"(" if open_low else "["}{low}, {high if high is not None else "inf"}]'
        msg = f'option {name} must lie in {bound}; got {value!r}'
        raise ConfigError(msg)


#: Node parameters that are not algorithm options: ignored when the offline tool reads the
#: node's params file, so that one file configures both.
NODE_ONLY_KEYS = frozenset({
    'hand_topic', 'eye_topic', 'hand_type', 'eye_type', 'hand_frame_id', 'eye_frame_id',
    'buffer_duration', 'buffer_size', 'output_file', 'calibrate_period', 'use_sim_time',
})
