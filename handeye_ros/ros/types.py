"""rclpy message classes by their 'pkg/msg/Name', for the builders of
:mod:`handeye_ros.formats.messages` (the node, publish_calibration and sim_publisher)."""

from __future__ import annotations

import importlib
import sys

from ..core.errors import ConfigError


class RclpyTypes(dict[str, type]):
    """rclpy message classes by 'pkg/msg/Name', imported on first use (the ``types`` of
    :mod:`handeye_ros.formats.messages`)."""

    def __missing__(self, msgtype: str) -> type:
        cls = self[msgtype] = message_class(msgtype)
        return cls


def message_class(msgtype: str) -> type:
    """The rclpy class of 'pkg/msg/Name'; ConfigError naming the package when this Python
    cannot import it (tf2_msgs and mocap4r2_msgs come with a ROS 2 install, not from PyPI)."""
    pkg, _, name = msgtype.split('/')
    try:
        return getattr(importlib.import_module(f'{pkg}.msg'), name)
    except (ImportError, AttributeError):
        raise ConfigError(
            f'{msgtype} cannot be imported in this Python ({sys.executable}): '
            f'install {pkg} (e.g. apt install ros-jazzy-{pkg.replace("_", "-")} '
            'and source /opt/ros/jazzy/setup.bash)'
        ) from None
