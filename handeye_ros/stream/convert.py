"""Stamped poses out of ROS messages, by duck typing.

The functions read attributes only, so they serve rclpy messages (live) and rosbags messages
(replayed from a bag) alike: both carry the same field names. The stamp is always
``header.stamp`` (the time the pose is valid at), never the arrival time.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import cast

from ..core.errors import InputError
from .shapes import (
    Odometry,
    OnePose,
    Pose,
    PoseStamped,
    PoseWithCovarianceStamped,
    Quaternion,
    Stamped,
    Transform,
    TransformStamped,
    Vector,
)

#: A pose as plain numbers: (stamp ns, x, y, z, qx, qy, qz, qw).
StampedPose = tuple[int, float, float, float, float, float, float, float]


class UnsupportedTypeError(InputError):
    """A topic's message type carries no pose we can read."""


def _stamp(msg: Stamped) -> int:
    s = msg.header.stamp
    return int(s.sec) * 1_000_000_000 + int(s.nanosec)


def stamped_pose(t_ns: int, p: Vector, q: Quaternion) -> StampedPose:
    """``(t_ns, x, y, z, qx, qy, qz, qw)`` of a position (Point or Vector3) and a Quaternion."""
    return (
        t_ns,
        float(p.x),
        float(p.y),
        float(p.z),
        float(q.x),
        float(q.y),
        float(q.z),
        float(q.w),
    )


def _from_pose(t_ns: int, pose: Pose) -> StampedPose:
    return stamped_pose(t_ns, pose.position, pose.orientation)


def _from_transform(t_ns: int, tf: Transform) -> StampedPose:
    return stamped_pose(t_ns, tf.translation, tf.rotation)


#: The pose of a message by its type's name (what the topic says it is: hence the casts).
Converter = Callable[[OnePose], StampedPose]
_CONVERTERS: dict[str, Converter] = {
    'geometry_msgs/msg/PoseStamped': lambda m: _from_pose(_stamp(m), cast(PoseStamped, m).pose),
    'geometry_msgs/msg/PoseWithCovarianceStamped': lambda m: _from_pose(
        _stamp(m), cast(PoseWithCovarianceStamped, m).pose.pose
    ),
    'geometry_msgs/msg/TransformStamped': lambda m: _from_transform(
        _stamp(m), cast(TransformStamped, m).transform
    ),
    'nav_msgs/msg/Odometry': lambda m: _from_pose(_stamp(m), cast(Odometry, m).pose.pose),
}


def frame_name(name: str) -> str:
    """A frame id as tf2 compares them: without the leading slash of ROS 1 names."""
    return name.strip().lstrip('/')


def frames_of(msg: OnePose) -> tuple[str, str]:
    """(world, body) frame ids a one-pose message names: header.frame_id and child_frame_id
    (empty where the type has none, as PoseStamped)."""
    return frame_name(msg.header.frame_id), frame_name(getattr(msg, 'child_frame_id', ''))


#: Message types holding one pose each, in ROS 2 'pkg/msg/Name' form.
SUPPORTED_TYPES = tuple(_CONVERTERS)
#: Message types holding many poses, of which a topic selector picks one (see sources.py):
#: tf (``TOPIC:PARENT.CHILD``) and mocap4r2 rigid bodies (``TOPIC:NAME``; mocap_msgs is the
#: package's name before its rename, with the same fields).
TF_TYPE = 'tf2_msgs/msg/TFMessage'
RIGID_BODIES_TYPES = ('mocap4r2_msgs/msg/RigidBodies', 'mocap_msgs/msg/RigidBodies')
MULTI_POSE_TYPES = (TF_TYPE, *RIGID_BODIES_TYPES)


def normalise_type(name: str) -> str:
    """'geometry_msgs/msg/PoseStamped' from that, 'geometry_msgs/PoseStamped' (ROS 1 bags) or
    a bare 'PoseStamped' / 'Odometry' / 'TFMessage'; raises UnsupportedTypeError for anything
    else."""
    known = (*SUPPORTED_TYPES, *MULTI_POSE_TYPES)
    parts = name.strip().split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) == 1:
        matches = [t for t in known if t.endswith('/' + parts[0])]
        if matches:
            return matches[0]
    full = '/'.join(parts)
    if full in known:
        return full
    msg = f'message type {name!r} carries no pose this tool reads; supported: {", ".join(known)}'
    raise UnsupportedTypeError(msg)


def pose_of(msgtype: str) -> Converter:
    """The converter of a one-pose message type (KeyError for the many-pose ones)."""
    return _CONVERTERS[normalise_type(msgtype)]
