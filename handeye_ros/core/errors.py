"""Errors raised by the calibration core.

Every error carries a message written for the user: what is wrong, with the numbers that show
it, and what to do. Front ends (offline tool, node) print the message; they never show a
traceback for these.
"""

from __future__ import annotations


class HandeyeError(Exception):
    """Base class of every error the calibration reports to its user."""


class InputError(HandeyeError):
    """A trajectory is malformed: empty, unsorted, non-finite, bad quaternions, unknown format."""


class TimeAlignmentError(HandeyeError):
    """The time offset cannot be found: no overlap, no correlation peak inside the window."""


class DegenerateMotionError(HandeyeError):
    """The motion does not constrain the extrinsic: too little rotation, a single rotation axis."""


class TooFewMotionsError(DegenerateMotionError):
    """Too few relative motions (rotation-constrained keyframes) could be built: the recording
    has turned too little so far."""


class NoConsensusError(DegenerateMotionError):
    """No T_HE that two or more relative motions agree on (RANSAC found no model)."""


class NoOverlapError(TimeAlignmentError):
    """The two streams do not overlap in time by enough at any offset searched."""


class TooFewKeyframesError(TimeAlignmentError):
    """A keyframe-only eye has too few keyframe pairs, or pairs that hardly rotate, for its
    time offset."""


class ConfigError(HandeyeError):
    """An option is unknown or outside its valid range."""


class BatchError(HandeyeError):
    """The batch stage cannot run on this input (the linear result is kept)."""
