"""ROS bags (ROS 2 sqlite3 and mcap, ROS 1) read and written with rosbags.

Reading lists a bag's topics and yields its messages in the order they were recorded (the
replay through the node's Recorder is :mod:`handeye_ros.app.replay`, above this layer and the
stream layer). Writing covers simulated recordings (for the demo and the tests) and the result
(``/tf_static`` as tf2_msgs/TFMessage, latched).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast

from ..core.errors import InputError
from ..core.trajectory import Trajectory
from ..stream import SUPPORTED_TYPES
from ..stream.convert import (
    MULTI_POSE_TYPES,
    TF_TYPE,
    UnsupportedTypeError,
    normalise_type,
)
from . import messages

if TYPE_CHECKING:  # typing.Self is 3.11+; annotations here are never evaluated
    from typing import Self

    from rosbags.interfaces import Connection, Qos
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys.store import Typestore

    from ..stream.shapes import Message

STORAGES = ('mcap', 'sqlite3', 'ros1')


@dataclass(frozen=True)
class Topic:
    name: str
    msgtype: str
    count: int


#: mocap4r2_msgs as the package publishes them, for bags that carry no message definitions
#: (ROS 2 Humble's sqlite3 bags); a bag's own definitions take precedence when it has them.
MOCAP4R2_MSGS = {
    'mocap4r2_msgs/msg/Marker': 'int8 USE_NAME=0\nint8 USE_INDEX=1\nint8 USE_BOTH=2\n'
    'int8 id_type\nint32 marker_index\nstring marker_name\n'
    'geometry_msgs/Point translation\n',
    'mocap4r2_msgs/msg/RigidBody': 'string rigid_body_name\nmocap4r2_msgs/Marker[] markers\n'
    'geometry_msgs/Pose pose\n',
    'mocap4r2_msgs/msg/RigidBodies': 'std_msgs/Header header\nuint32 frame_number\n'
    'mocap4r2_msgs/RigidBody[] rigidbodies\n',
}


def _typestore() -> Typestore:
    """Jazzy's types (tf2_msgs included) and mocap4r2_msgs."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in MOCAP4R2_MSGS.items():
        store.register(get_types_from_msg(text, name))
    return store


#: The first bytes of a ROS 1 bag file.
ROS1_MAGIC = b'#ROSBAG V2.0'


class BagReader:
    """An open bag (context manager) with errors turned into InputError naming the path."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        if not self.path.exists():
            raise InputError(f'{self.path}: no such bag')

    def __enter__(self) -> Self:
        from rosbags.highlevel import AnyReader, AnyReaderError

        try:
            self.reader = AnyReader([self.path], default_typestore=_typestore())
            self.reader.open()
        except (AnyReaderError, OSError, ValueError) as err:
            hint = ''
            if self.path.is_file() and self.path.suffix != '.bag':
                with self.path.open('rb') as f:
                    if f.read(len(ROS1_MAGIC)) == ROS1_MAGIC:
                        hint = '; it is a ROS 1 bag, which the readers know by the name *.bag'
            raise InputError(
                f'{self.path}: cannot be read as a ROS 1 or ROS 2 bag ({err}){hint}'
            ) from None
        return self

    def __exit__(self, *exc: object) -> None:
        self.reader.close()

    def topics(self) -> list[Topic]:
        """Every topic with its type and message count."""
        seen: dict[str, Topic] = {}
        for c in self.reader.connections:
            old = seen.get(c.topic)
            seen[c.topic] = Topic(c.topic, c.msgtype, c.msgcount + (old.count if old else 0))
        return sorted(seen.values(), key=lambda t: t.name)

    def pose_topics(self) -> list[Topic]:
        """Topics whose type carries a pose we read."""
        out = []
        for t in self.topics():
            try:
                if normalise_type(t.msgtype) in SUPPORTED_TYPES:
                    out.append(t)
            except UnsupportedTypeError:
                continue
        return out

    def multi_pose_topics(self) -> list[Topic]:
        """Topics of many poses per message (tf, rigid bodies), which need a selector."""
        out = []
        for t in self.topics():
            try:
                if normalise_type(t.msgtype) in MULTI_POSE_TYPES:
                    out.append(t)
            except UnsupportedTypeError:
                continue
        return out

    def messages(self, topics: list[str]) -> Iterator[tuple[str, int, object]]:
        """(topic, record time [ns], deserialised message) in recorded order; the record time
        is when the recorder received it (its arrival time)."""
        conns = [c for c in self.reader.connections if c.topic in topics]
        for conn, t_ns, raw in self.reader.messages(connections=conns):
            yield conn.topic, t_ns, self.reader.deserialize(raw, conn.msgtype)


# ----------------------------------------------------------------------------------- writing


def pose_messages(
    store: Typestore, traj: Trajectory, msgtype: str, frame_id: str, child_frame_id: str
) -> Iterator[tuple[int, Message]]:
    """(stamp ns, message) of a trajectory as one of the supported types (rosbags classes;
    :func:`handeye_ros.formats.messages.pose_message` builds each)."""
    msgtype = normalise_type(msgtype)
    for t, p, q in zip(traj.t_ns.tolist(), traj.p_xyz.tolist(), traj.q_xyzw.tolist(), strict=True):
        yield t, messages.pose_message(store.types, msgtype, t, p, q, (frame_id, child_frame_id))


def _latched_qos() -> Qos:
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    zero = QosTime(0, 0)
    return Qos(
        QosHistory.KEEP_LAST,
        1,
        QosReliability.RELIABLE,
        QosDurability.TRANSIENT_LOCAL,
        zero,
        zero,
        QosLiveliness.AUTOMATIC,
        zero,
        False,
    )


#: The QoS tf2's static broadcaster offers (transient local, reliable, keep last 1).
LATCHED_QOS = _latched_qos()


def check_bag_path(path: Path, storage: str) -> None:
    """InputError unless a new bag of ``storage`` can go to ``path``: nothing there yet, and a
    name its readers take for that storage (rosbags' AnyReader, and this package's, tell ROS 1
    from ROS 2 by the name alone)."""
    if path.exists():
        raise InputError(f'{path}: exists already; choose a new path for the bag')
    if (path.suffix == '.bag') != (storage == 'ros1'):
        kind = (
            'a ROS 1 bag is one file named *.bag'
            if storage == 'ros1'
            else f'a ROS 2 bag ({storage}) is a folder whose name does not end in .bag'
        )
        raise InputError(f'{path}: {kind}, as the readers tell them apart by the name')


class BagWriter:
    """Write messages to a new bag: storage 'mcap' or 'sqlite3' (ROS 2), or 'ros1'."""

    def __init__(self, path: str | Path, storage: str = 'mcap'):
        if storage not in STORAGES:
            raise InputError(f'unknown bag storage {storage!r}; use one of {", ".join(STORAGES)}')
        self.path, self.storage, self.store = Path(path), storage, _typestore()
        check_bag_path(self.path, storage)
        if storage == 'ros1':
            from rosbags.rosbag1 import Writer as Writer1

            self.writer = Writer1(self.path)
        else:
            from rosbags.rosbag2 import StoragePlugin, Writer

            plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
            self.writer = Writer(self.path, version=9, storage_plugin=plugin)
        self._conns: dict[str, Connection] = {}

    # the two rosbags writers share the calls made here
    writer: Writer1 | Writer2

    def __enter__(self) -> Self:
        try:
            self.writer.open()
        except OSError as err:  # a folder that cannot be made there, a full disk
            raise InputError(f'{self.path}: cannot write the bag ({err.strerror})') from None
        return self

    def __exit__(self, *exc: object) -> None:
        self.writer.close()

    def write(
        self, topic: str, msgtype: str, t_ns: int, msg: object, latched: bool = False
    ) -> None:
        """Append one message. ``latched`` (the first message of a topic decides): the topic is
        recorded as offered transient local, reliable, depth 1, so that a replay latches it as
        tf2's static broadcaster does (ROS 1 bags have no QoS; their reader latches
        /tf_static by name)."""
        if topic not in self._conns and latched and self.storage != 'ros1':
            ros2 = cast('Writer2', self.writer)
            self._conns[topic] = ros2.add_connection(
                topic, msgtype, typestore=self.store, offered_qos_profiles=[LATCHED_QOS]
            )
        elif topic not in self._conns:
            self._conns[topic] = self.writer.add_connection(topic, msgtype, typestore=self.store)
        if self.storage == 'ros1':
            data = self.store.serialize_ros1(msg, msgtype)
        else:
            data = self.store.serialize_cdr(msg, msgtype)
        self.writer.write(self._conns[topic], int(t_ns), data)


def write_recording(
    path: str | Path, streams: list[tuple[str, str, Trajectory, str, str]], storage: str = 'mcap'
) -> None:
    """Write trajectories as pose topics, interleaved by stamp as a recorder would log them.

    ``streams``: (topic, message type, trajectory, frame_id, child_frame_id) each.
    """
    with BagWriter(path, storage) as w:
        items = []
        for k, (topic, msgtype, traj, frame, child) in enumerate(streams):
            full = normalise_type(msgtype)
            items += [
                (t, k, topic, full, m) for t, m in pose_messages(w.store, traj, full, frame, child)
            ]
        items.sort(key=lambda x: (x[0], x[1]))
        for t, _, topic, full, msg in items:
            w.write(topic, full, t, msg)


#: The fixed rig -> marker transform of the /tf layout below (any fixed pose will do).
RIG_TO_MARKER = (
    (0.05, -0.02, 0.11),  # 10, -20, 30 deg about x, y, z
    (0.12767944069578063, -0.14487812541736914, 0.2685358227515692, 0.943714364147489),
)


def tf_links(hand: Trajectory, eye: Trajectory) -> tuple[Trajectory, Trajectory]:
    """A hand and an eye laid out as a tf tree would carry them: the hand as the moving link
    world -> rig, with rig -> marker static (RIG_TO_MARKER), and the eye as the inverse link
    imu -> odom; ``/tf:world.marker`` and ``/tf:odom.imu`` give them back."""
    from scipy.spatial.transform import Rotation

    s_p, s_q = RIG_TO_MARKER
    rot = Rotation.from_quat(hand.q_xyzw) * Rotation.from_quat(s_q).inv()
    rig = Trajectory.from_arrays(
        hand.t_ns, hand.p_xyz - rot.apply(s_p), rot.as_quat(), name='world->rig'
    )
    inv = Rotation.from_quat(eye.q_xyzw).inv()
    imu = Trajectory.from_arrays(eye.t_ns, -inv.apply(eye.p_xyz), inv.as_quat(), name='imu->odom')
    return rig, imu


def write_result_bag(
    path: str | Path, published: messages.Published, stamp_ns: int, storage: str = 'mcap'
) -> None:
    """The calibration as the node publishes it (see :mod:`handeye_ros.formats.messages`), all
    latched: the extrinsic on /tf_static (tf2_msgs/TFMessage, parent = hand frame, child = eye
    frame) and on /calibrator/extrinsic, its covariance, and the time offset on
    /calibrator/time_offset and /calibrator/time_reference, stamped ``stamp_ns``.

    Raises InputError when ``stamp_ns`` is no ROS time (builtin_interfaces/Time holds the
    seconds in an int32: 1970 to 2038; ROS 1 in a uint32)."""
    if not messages.is_ros_time(stamp_ns):
        msg = (
            f'{path}: cannot write the result bag: its stamp {stamp_ns} ns is no ROS time, '
            'whose seconds are an int32 (1970 to 2038)'
        )
        raise InputError(msg)
    with BagWriter(path, storage) as w:
        T = w.store.types
        out = messages.outputs(T, published, stamp_ns)
        frames = (published.parent, published.child)  # T_HE, as out[EXTRINSIC] states it
        w.write(
            '/tf_static',
            TF_TYPE,
            stamp_ns,
            messages.pose_message(
                T, TF_TYPE, stamp_ns, published.translation, published.rotation, frames
            ),
            latched=True,
        )
        for name, m in out.items():
            w.write(
                f'/{messages.NODE_NAME}/{name}',
                messages.OUTPUT_TYPES[name],
                stamp_ns,
                m,
                latched=True,
            )
