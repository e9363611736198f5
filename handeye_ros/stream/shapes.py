"""The fields of the ROS 2 messages this package reads, as structural types.

rclpy's message classes (live) and rosbags' dataclasses (a bag replayed) carry the same field
names; each Protocol names the fields read and nothing else, so both fit without a base
class. Members are read-only (properties), as the package never writes into a message.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol


class Vector(Protocol):
    """geometry_msgs Point or Vector3 (m)."""

    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def z(self) -> float: ...


class Quaternion(Protocol):
    """geometry_msgs Quaternion (Hamilton, x y z w)."""

    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def z(self) -> float: ...
    @property
    def w(self) -> float: ...


class Time(Protocol):
    """builtin_interfaces Time: seconds and nanoseconds."""

    @property
    def sec(self) -> int: ...
    @property
    def nanosec(self) -> int: ...


class Header(Protocol):
    """std_msgs Header: the stamp the data is valid at and the frame it is in."""

    @property
    def stamp(self) -> Time: ...
    @property
    def frame_id(self) -> str: ...


class Pose(Protocol):
    """geometry_msgs Pose."""

    @property
    def position(self) -> Vector: ...
    @property
    def orientation(self) -> Quaternion: ...


class Transform(Protocol):
    """geometry_msgs Transform."""

    @property
    def translation(self) -> Vector: ...
    @property
    def rotation(self) -> Quaternion: ...


class Stamped(Protocol):
    """Any message with a header (every one this package reads)."""

    @property
    def header(self) -> Header: ...


class PoseStamped(Stamped, Protocol):
    @property
    def pose(self) -> Pose: ...


class PoseWithCovariance(Protocol):
    @property
    def pose(self) -> Pose: ...


class PoseWithCovarianceStamped(Stamped, Protocol):
    @property
    def pose(self) -> PoseWithCovariance: ...


class TransformStamped(Stamped, Protocol):
    @property
    def child_frame_id(self) -> str: ...
    @property
    def transform(self) -> Transform: ...


class Odometry(PoseWithCovarianceStamped, Protocol):
    """nav_msgs Odometry: a PoseWithCovarianceStamped with the body's frame (its twist unread)."""

    @property
    def child_frame_id(self) -> str: ...


class TFMessage(Protocol):
    """tf2_msgs TFMessage (/tf and /tf_static)."""

    @property
    def transforms(self) -> Sequence[TransformStamped]: ...


class RigidBody(Protocol):
    """mocap4r2_msgs RigidBody."""

    @property
    def rigid_body_name(self) -> str: ...
    @property
    def pose(self) -> Pose: ...


class RigidBodies(Stamped, Protocol):
    """mocap4r2_msgs RigidBodies."""

    @property
    def rigidbodies(self) -> Sequence[RigidBody]: ...


#: A message of one pose (the types of :data:`.convert.SUPPORTED_TYPES`).
OnePose = PoseStamped | PoseWithCovarianceStamped | TransformStamped | Odometry
#: Any message a stream is read from.
Message = OnePose | TFMessage | RigidBodies
#: rclpy's MessageInfo: a dict of int (source_timestamp, received_timestamp in ns, ...).
MessageInfo = Mapping[str, int]
