"""Readers and writers of trajectory files (text now; bags come with the node)."""

from .text import FORMATS, detect_format, read_trajectory, write_euroc, write_tum

__all__ = ['FORMATS', 'detect_format', 'read_trajectory', 'write_euroc', 'write_tum']
