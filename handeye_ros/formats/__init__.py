"""Readers and writers of trajectory files: text (TUM, EuRoC, CSV) in :mod:`.text` (the common
case read in bulk from its bytes by :mod:`.bulk`, its stamps made exact nanoseconds by
:mod:`.stamps`), ROS bags in :mod:`.bag` (imported on use:
rosbags is loaded only for bags); result files in :mod:`.result_file`, and the ROS messages of a
result in :mod:`.messages`."""

from .text import FORMATS, detect_format, read_trajectory, write_euroc, write_tum

__all__ = ['FORMATS', 'detect_format', 'read_trajectory', 'write_euroc', 'write_tum']
