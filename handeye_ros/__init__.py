"""handeye_ros: time offset and extrinsic between a motion-capture stream and a VO/VIO
trajectory (the method of ../shared/paper, with the checks real recordings need).

The public API, for use from Python without ROS::

    from handeye_ros import CalibrationConfig, calibrate, read_trajectory

    hand = read_trajectory('mocap.csv')      # T_GH(t): the marker H in the MoCap world G
    eye = read_trajectory('vio.txt')         # T_WE(t): the body E in the VIO world W
    result = calibrate(hand, eye, CalibrationConfig(eta=5.0))
    print(result.summary())                  # dt, T_HE (both directions), the verdict
    result.time_offset_s, result.q_HE, result.p_HE, result.quality.verdict

The packages: :mod:`.core` the algorithm, :mod:`.formats` files and bags, :mod:`.evaluation`
what a calibration is used for, :mod:`.stream` buffered pose streams, :mod:`.app` the command
line tools (``python -m handeye_ros.offline``, ``python -m handeye_ros.evaluate``), :mod:`.ros`
the node.

Conventions (docs/method.md): ``T_WE(t) = T_WG T_GH(t - dt) T_HE``; quaternions Hamilton,
``x y z w``; stamps int64 nanoseconds. The names below are loaded on first use, so that
importing a submodule (the node's ``--help``, the params file) costs no numpy or scipy.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__all__ = [
    'CalibrationConfig',
    'CalibrationResult',
    'HandeyeError',
    'StreamConfig',
    'Trajectory',
    'calibrate',
    'read_trajectory',
    'write_euroc',
    'write_tum',
]

#: Where each public name lives.
_HOMES = {
    'CalibrationConfig': 'handeye_ros.core.config',
    'CalibrationResult': 'handeye_ros.core.result',
    'HandeyeError': 'handeye_ros.core.errors',
    'StreamConfig': 'handeye_ros.stream.config',
    'Trajectory': 'handeye_ros.core.trajectory',
    'calibrate': 'handeye_ros.core.pipeline',
    'read_trajectory': 'handeye_ros.formats',
    'write_euroc': 'handeye_ros.formats',
    'write_tum': 'handeye_ros.formats',
}

if TYPE_CHECKING:
    from .core.config import CalibrationConfig
    from .core.errors import HandeyeError
    from .core.pipeline import calibrate
    from .core.result import CalibrationResult
    from .core.trajectory import Trajectory
    from .formats import read_trajectory, write_euroc, write_tum
    from .stream.config import StreamConfig


def __getattr__(name: str) -> object:
    if name in _HOMES:
        value = getattr(importlib.import_module(_HOMES[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
