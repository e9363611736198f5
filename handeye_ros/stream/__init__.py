"""Pose streams from messages: conversion and bounded buffering, shared by the node and the
bag replay (no rclpy here: it works on rclpy messages and rosbags messages alike)."""

from .buffer import BufferStats, PoseBuffer
from .convert import SUPPORTED_TYPES, UnsupportedTypeError, normalise_type, pose_of

__all__ = ['SUPPORTED_TYPES', 'BufferStats', 'PoseBuffer', 'UnsupportedTypeError',
           'normalise_type', 'pose_of']
