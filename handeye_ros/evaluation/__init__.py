"""From a calibration to an evaluation: the ground truth in the eye's frame, world and clock,
APE/RPE with and without the calibration, evo-ready exports, and the visual report.

This layer sits above :mod:`handeye_ros.core` and :mod:`handeye_ros.formats` and never imports
rclpy; matplotlib is imported only by the plots.
"""

from .aligned import AlignedTrajectories, calibrated, uncalibrated
from .metrics import ErrorStats, Evaluation, evaluate

__all__ = [
    'AlignedTrajectories',
    'ErrorStats',
    'Evaluation',
    'calibrated',
    'evaluate',
    'uncalibrated',
]
