"""Pose streams from messages: conversion, bounded buffering and the calibration call, shared
by the node and the bag replay (no rclpy here: it works on rclpy and rosbags messages alike).

:mod:`.config` holds the streams' options; :mod:`.shapes` names the message fields read (as
structural types); :mod:`.convert` makes stamped poses of messages,
:mod:`.sources` picks them out of messages of many (/tf, rigid bodies); :mod:`.buffer` bounds
each stream; :mod:`.recorder` holds the two and makes the snapshot a calibration reads."""

from .buffer import BufferStats, PoseBuffer
from .config import StreamConfig
from .convert import SUPPORTED_TYPES, UnsupportedTypeError, normalise_type, pose_of
from .recorder import STREAMS, Recorder

__all__ = [
    'STREAMS',
    'SUPPORTED_TYPES',
    'BufferStats',
    'PoseBuffer',
    'Recorder',
    'StreamConfig',
    'UnsupportedTypeError',
    'normalise_type',
    'pose_of',
]
