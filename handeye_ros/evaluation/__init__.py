"""From a calibration to an evaluation: the ground truth in the eye's frame, world and clock,
APE/RPE with and without the calibration, evo-ready exports, and the visual report.

:mod:`.aligned` maps the hand onto the eye, with and without the calibration; :mod:`.metrics`
is APE and RPE, :mod:`.error_bars` the part of their uncertainty that comes from the
calibration; :mod:`.outputs` what the front ends write after a calibration (the evaluation,
the evo exports, the report); :mod:`.terminal` the terminal report, :mod:`.html` the HTML one,
with :mod:`.plots` (on the canvas of :mod:`.figures`); :mod:`.rig_report` a rig's page.

This layer sits above :mod:`handeye_ros.core` and :mod:`handeye_ros.formats` and never imports
rclpy; matplotlib is imported only by the plots.
"""

from .aligned import AlignedTrajectories, calibrated, uncalibrated
from .metrics import ErrorStats, Evaluation

__all__ = [
    'AlignedTrajectories',
    'ErrorStats',
    'Evaluation',
    'calibrated',
    'uncalibrated',
]
