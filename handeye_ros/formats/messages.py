"""ROS messages out of a calibration result (:class:`Published`), for rclpy and rosbags alike.

Every builder takes ``types``: a mapping from a 'pkg/msg/Name' type name to its message class.
The node passes one that imports rclpy's classes (:class:`handeye_ros.ros.types.RclpyTypes`);
the bag writer passes its typestore's ``types``. Both kinds of class take every field as a keyword, so one builder
serves the live topics and the output bag, and the two cannot disagree.

What the calibration publishes (the node's latched topics, the output bag and
``publish_calibration`` use the same names, relative to the node, ``calibrator`` by default):

- ``extrinsic``: geometry_msgs/TransformStamped. This is T_HE: the parent is the hand frame H
  and the child is the eye frame E. The same transform goes on /tf_static.
- ``extrinsic_with_covariance``: geometry_msgs/PoseWithCovarianceStamped. This is T_HE with its
  6x6 covariance. A result without one (no batch stage) has -1 in the first element and zeros
  elsewhere: the covariance is unknown, as sensor_msgs marks it.
- ``time_offset``: std_msgs/Float64. This is dt [s], eye clock minus hand clock.
- ``time_reference``: sensor_msgs/TimeReference. This is the same offset with its stamp and
  frames:
  - ``header.stamp`` is an instant on the eye clock;
  - ``time_ref`` is that instant on the hand clock;
  - ``header.frame_id`` is E and ``source`` is H.
  - So dt = header.stamp - time_ref, and T_WE(t) = T_WG T_GH(t - dt) T_HE.
  - With an estimated clock drift, the stamp is the instant dt refers to.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, TypeAlias, cast

import numpy as np

from ..core.arrays import Floats, Stamps
from ..core.document import ResultDoc

if TYPE_CHECKING:  # the message builders serve sim_publisher, which needs no scipy
    from ..core.result import CalibrationResult
    from ..stream import shapes

#: Message classes by their 'pkg/msg/Name' (each takes its fields as keywords).
Types: TypeAlias = Mapping[str, Callable[..., object]]
#: A position (x y z) or a quaternion (x y z w).
Vec: TypeAlias = Sequence[float] | Floats

#: Topic names of the calibration, relative to the node (see the module docstring).
EXTRINSIC = 'extrinsic'
EXTRINSIC_WITH_COVARIANCE = 'extrinsic_with_covariance'
TIME_OFFSET = 'time_offset'
TIME_REFERENCE = 'time_reference'
#: The node's default name: the output bag's topics are those of a node of this name.
NODE_NAME = 'calibrator'
#: Every output topic (relative to the node) and its type; all latched.
OUTPUT_TYPES = {
    EXTRINSIC: 'geometry_msgs/msg/TransformStamped',
    EXTRINSIC_WITH_COVARIANCE: 'geometry_msgs/msg/PoseWithCovarianceStamped',
    TIME_OFFSET: 'std_msgs/msg/Float64',
    TIME_REFERENCE: 'sensor_msgs/msg/TimeReference',
}

#: The last ROS time: builtin_interfaces/Time holds the seconds in an int32 (to 2038).
ROS_TIME_MAX_NS = (2**31 - 1) * 1_000_000_000 + 999_999_999


def is_ros_time(t_ns: int) -> bool:
    """Whether ``t_ns`` fits builtin_interfaces/Time (1970 to 2038)."""
    return 0 <= t_ns <= ROS_TIME_MAX_NS


def time(types: Types, t_ns: int) -> shapes.Time:
    """builtin_interfaces/Time of an int64 nanosecond stamp."""
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return cast('shapes.Time', types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec))


def header(types: Types, t_ns: int, frame_id: str) -> shapes.Header:
    msg = types['std_msgs/msg/Header'](stamp=time(types, t_ns), frame_id=frame_id)
    return cast('shapes.Header', msg)


def transform_stamped(
    types: Types, t_ns: int, parent: str, child: str, p: Vec, q: Vec
) -> shapes.TransformStamped:
    """geometry_msgs/TransformStamped: the pose (p x y z, q x y z w) of ``child`` in
    ``parent`` at ``t_ns``."""
    msg = types['geometry_msgs/msg/TransformStamped'](
        header=header(types, t_ns, parent),
        child_frame_id=child,
        transform=types['geometry_msgs/msg/Transform'](
            translation=types['geometry_msgs/msg/Vector3'](
                x=float(p[0]), y=float(p[1]), z=float(p[2])
            ),
            rotation=_quaternion(types, q),
        ),
    )
    return cast('shapes.TransformStamped', msg)


def pose(types: Types, p: Vec, q: Vec) -> shapes.Pose:
    """geometry_msgs/Pose of a position (x y z) and a quaternion (x y z w)."""
    msg = types['geometry_msgs/msg/Pose'](
        position=types['geometry_msgs/msg/Point'](x=float(p[0]), y=float(p[1]), z=float(p[2])),
        orientation=_quaternion(types, q),
    )
    return cast('shapes.Pose', msg)


def path(types: Types, frame_id: str, t_ns: Stamps, p: Floats, q: Floats) -> object:
    """nav_msgs/Path of poses (stamps int64 ns, p (N, 3), q (N, 4) x y z w) in ``frame_id``,
    stamped with its last pose."""
    poses = [
        types['geometry_msgs/msg/PoseStamped'](
            header=header(types, int(t), frame_id), pose=pose(types, pk, qk)
        )
        for t, pk, qk in zip(t_ns, p, q, strict=True)
    ]
    last = int(t_ns[-1]) if len(poses) else 0
    return types['nav_msgs/msg/Path'](header=header(types, last, frame_id), poses=poses)


def rigid_bodies(
    types: Types, t_ns: int, frame_id: str, bodies: list[tuple[str, Vec, Vec]]
) -> shapes.RigidBodies:
    """mocap4r2_msgs/RigidBodies of (name, p x y z, q x y z w) bodies, in ``frame_id``."""
    return cast('shapes.RigidBodies', types['mocap4r2_msgs/msg/RigidBodies'](
        header=header(types, t_ns, frame_id),
        frame_number=0,
        rigidbodies=[
            types['mocap4r2_msgs/msg/RigidBody'](rigid_body_name=name, markers=[],
                                                  pose=pose(types, p, q))
            for name, p, q in bodies
        ],
    ))  # fmt: skip


def pose_message(
    types: Types, msgtype: str, t_ns: int, p: Vec, q: Vec, frames: tuple[str, str]
) -> shapes.Message:
    """One pose (p [m], q x y z w) of the frame child_frame_id in frame_id (``frames``) as a
    message of any supported type ('pkg/msg/Name'): a TFMessage holds one transform, a
    RigidBodies message one body named child_frame_id, an Odometry a zero twist; covariances
    are zero (unknown to a simulator or a file)."""
    frame_id, child_frame_id = frames
    if msgtype == 'tf2_msgs/msg/TFMessage':
        tf = types[msgtype](
            transforms=[transform_stamped(types, t_ns, frame_id, child_frame_id, p, q)]
        )
        return cast('shapes.TFMessage', tf)
    if msgtype.endswith('/msg/RigidBodies'):
        return rigid_bodies(types, t_ns, frame_id, [(child_frame_id, p, q)])
    if msgtype == 'geometry_msgs/msg/TransformStamped':
        return transform_stamped(types, t_ns, frame_id, child_frame_id, p, q)
    head = header(types, t_ns, frame_id)
    if msgtype == 'geometry_msgs/msg/PoseStamped':
        return cast('shapes.PoseStamped', types[msgtype](header=head, pose=pose(types, p, q)))
    pwc = types['geometry_msgs/msg/PoseWithCovariance'](
        pose=pose(types, p, q), covariance=np.zeros(36)
    )
    if msgtype == 'geometry_msgs/msg/PoseWithCovarianceStamped':
        return cast('shapes.PoseWithCovarianceStamped', types[msgtype](header=head, pose=pwc))
    zero = types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)
    twist = types['geometry_msgs/msg/TwistWithCovariance'](
        twist=types['geometry_msgs/msg/Twist'](linear=zero, angular=zero), covariance=np.zeros(36)
    )
    odometry = types[msgtype](header=head, child_frame_id=child_frame_id, pose=pwc, twist=twist)
    return cast('shapes.Odometry', odometry)


def _quaternion(types: Types, q: Vec) -> object:
    return types['geometry_msgs/msg/Quaternion'](
        x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])
    )


@dataclass(frozen=True)
class Published:
    """What the outputs state, typed (made from a result, or read back from a result file).

    parent, child: the frames of T_HE (H, E); translation [m], rotation (x y z w, w >= 0) and
    R (3, 3) of T_HE; time_offset_s / time_offset_ns: dt; instant_ns: the eye-clock instant
    dt is stated at (:func:`time_reference`); covariance: (6, 6) of T_HE's translation and
    rotation (tangent on the right, eye frame), or None without a batch stage.
    """

    parent: str
    child: str
    translation: Floats
    rotation: Floats
    R: Floats
    time_offset_s: float
    time_offset_ns: int
    instant_ns: int
    covariance: Floats | None

    @classmethod
    def from_result(cls, result: CalibrationResult, frames: Mapping[str, str]) -> Published:
        """Of a result and the frame names (``hand``, ``eye``) it is published under; the
        instant is the one dt refers to under a clock drift, else the eye's last stamp."""
        from ..core.geometry import matrix_from_quat, quat_from_matrix

        R = matrix_from_quat(result.q_HE)
        model = result.eye_model
        instant = (
            model.time_offset_stamp_ns
            if result.clock_drift is not None and model is not None
            else result.eye.last_stamp_ns
        )
        b = result.batch
        return cls(
            parent=frames['hand'],
            child=frames['eye'],
            translation=np.asarray(result.p_HE, dtype=float),
            rotation=quat_from_matrix(R),  # as the result file writes it (w >= 0)
            R=R,
            time_offset_s=float(result.time_offset_s),
            time_offset_ns=int(result.time_offset_ns),
            instant_ns=int(instant),
            # the batch covariance's order: dt, translation, rotation[, drift][, scale]
            covariance=None if b is None else np.asarray(b.covariance)[1:7, 1:7],
        )

    @classmethod
    def from_document(cls, d: ResultDoc) -> Published:
        """Of a result file's contents (:func:`handeye_ros.formats.result_file.read_result`)."""
        e = d['extrinsic']
        cov = (d.get('covariance') or {'matrix': None})['matrix']
        stamp = d.get('time_offset_stamp_ns')
        return cls(
            parent=e['parent'],
            child=e['child'],
            translation=np.asarray(e['translation'], dtype=float),
            rotation=np.asarray(e['rotation'], dtype=float),
            R=np.asarray(e['matrix'], dtype=float)[:3, :3],
            time_offset_s=float(d['time_offset']),
            time_offset_ns=int(d['time_offset_ns']),
            instant_ns=int(stamp if stamp is not None else d['inputs']['eye']['last_stamp_ns']),
            covariance=None if cov is None else np.asarray(cov, dtype=float)[1:7, 1:7],
        )


def extrinsic(types: Types, pub: Published, t_ns: int) -> shapes.TransformStamped:
    """T_HE as geometry_msgs/TransformStamped (parent H, child E), stamped ``t_ns``."""
    return transform_stamped(types, t_ns, pub.parent, pub.child, pub.translation, pub.rotation)


def extrinsic_covariance(pub: Published) -> Floats:
    """The 36 covariance values of T_HE in ROS order: x, y, z, then rotations about the
    parent's (H) fixed X, Y, Z axes. [-1, 0, ...] when the result has none.

    The result's rotation covariance is in the tangent on the right of T_HE (eye frame);
    ROS wants fixed parent-frame axes: dtheta_H = R_HE dtheta_E.
    """
    if pub.covariance is None:
        out = np.zeros(36)
        out[0] = -1.0
        return out
    J = np.eye(6)
    J[3:, 3:] = pub.R
    return (J @ pub.covariance @ J.T).ravel()


def extrinsic_with_covariance(
    types: Types, pub: Published, t_ns: int
) -> shapes.PoseWithCovarianceStamped:
    """T_HE with its covariance (see :func:`extrinsic_covariance`), stamped ``t_ns``."""
    x, y, z = (float(v) for v in pub.translation)
    pose = types['geometry_msgs/msg/Pose'](
        position=types['geometry_msgs/msg/Point'](x=x, y=y, z=z),
        orientation=_quaternion(types, pub.rotation),
    )
    msg = types['geometry_msgs/msg/PoseWithCovarianceStamped'](
        header=header(types, t_ns, pub.parent),
        pose=types['geometry_msgs/msg/PoseWithCovariance'](
            pose=pose, covariance=extrinsic_covariance(pub)
        ),
    )
    return cast('shapes.PoseWithCovarianceStamped', msg)


def time_offset(types: Types, pub: Published) -> object:
    """dt [s] as std_msgs/Float64."""
    return types['std_msgs/msg/Float64'](data=pub.time_offset_s)


def time_reference(types: Types, pub: Published) -> object | None:
    """dt as sensor_msgs/TimeReference (see the module docstring). Returns None when the
    instant on either clock is no ROS time (a boot clock minus a larger offset)."""
    t_eye = pub.instant_ns
    t_hand = t_eye - pub.time_offset_ns
    if not (is_ros_time(t_eye) and is_ros_time(t_hand)):
        return None
    return types['sensor_msgs/msg/TimeReference'](
        header=header(types, t_eye, pub.child),
        time_ref=time(types, t_hand),
        source=pub.parent,
    )


def outputs(types: Types, pub: Published, t_ns: int) -> dict[str, object]:
    """Every output of one result (topic relative to the node -> message), the transforms
    stamped ``t_ns``. time_reference is left out when it cannot be stated (see
    :func:`time_reference`)."""
    out = {
        EXTRINSIC: extrinsic(types, pub, t_ns),
        EXTRINSIC_WITH_COVARIANCE: extrinsic_with_covariance(types, pub, t_ns),
        TIME_OFFSET: time_offset(types, pub),
        TIME_REFERENCE: time_reference(types, pub),
    }
    return {k: v for k, v in out.items() if v is not None}
