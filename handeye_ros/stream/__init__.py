"""Pose streams from messages: conversion, bounded buffering and the calibration call, shared
by the node and the bag replay (no rclpy here: it works on rclpy and rosbags messages alike)."""

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
