"""The package's commands and their two names.

``ros2 run handeye_ros NAME`` starts the executables in ``lib/handeye_ros/`` (``ros2_run/``,
installed there by setup.py for colcon and pip alike); a pip install puts the same commands on
the user's PATH as ``handeye-ros-NAME`` (``_`` as ``-``), names no other package claims.
"""

from __future__ import annotations

import os
import sys

#: What the commands on a pip install's PATH start with.
PATH_PREFIX = 'handeye-ros-'


def path_name(ros_name: str) -> str:
    """The PATH command of ``ros2 run handeye_ros ros_name``."""
    return PATH_PREFIX + ros_name.replace('_', '-')


def prog(ros_name: str) -> str:
    """The name the user typed, for usage and error lines: the PATH command's when the process
    started as one, else the ``ros2 run`` name."""
    typed = os.path.basename(sys.argv[0]) if sys.argv else ''
    return typed if typed == path_name(ros_name) else ros_name
