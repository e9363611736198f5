"""Readers and writers of trajectory files: text (TUM, EuRoC, CSV) here, ROS bags in
:mod:`.bag` (imported on use: rosbags is loaded only for bags)."""

from .text import FORMATS, detect_format, read_trajectory, write_euroc, write_tum

__all__ = ['FORMATS', 'detect_format', 'read_trajectory', 'write_euroc', 'write_tum']
