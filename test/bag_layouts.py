"""Bag layouts the tests write (not shipped: no front end writes them):
both streams on /tf, the hand among mocap4r2 rigid bodies; and the offset read back from a
TimeReference."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from handeye_ros.core.trajectory import Trajectory
from handeye_ros.formats import messages
from handeye_ros.formats.bag import RIG_TO_MARKER, BagWriter, pose_messages, tf_links
from handeye_ros.formats.messages import transform_stamped
from handeye_ros.stream.convert import RIGID_BODIES_TYPES, TF_TYPE

#: Topics and selectors of the layouts below (the hand on /tf as tf_links lays it out).
TF_SELECTORS = {'hand': '/tf:world.marker', 'eye': '/tf:odom.imu'}
RIGID_BODIES_TOPIC = '/mocap/rigid_bodies'


def write_tf_recording(
    path: str | Path,
    hand: Trajectory,
    eye: Trajectory,
    storage: str = 'mcap',
    slash: str = '',
    static_after: int = 5,
) -> None:
    """Both streams on /tf as :func:`tf_links` lays them out, interleaved by stamp, and the
    static rig -> marker on /tf_static after the first ``static_after`` messages (a recorder
    started before the static broadcaster). ``slash``: '/' gives ROS 1 frame names."""
    rig, imu = tf_links(hand, eye)
    with BagWriter(path, storage) as w:
        items = [
            (t, 0, m) for t, m in pose_messages(w.store, rig, TF_TYPE, slash + 'world', 'rig')
        ]
        items += [(t, 1, m) for t, m in pose_messages(w.store, imu, TF_TYPE, 'imu', 'odom')]
        items.sort(key=lambda x: (x[0], x[1]))
        static = w.store.types[TF_TYPE](
            transforms=[
                transform_stamped(
                    w.store.types, items[0][0], 'rig', slash + 'marker', *RIG_TO_MARKER
                )
            ]
        )
        for k, (t, _, m) in enumerate(items):
            w.write('/tf', TF_TYPE, t, m)
            if k == static_after:
                w.write('/tf_static', TF_TYPE, t, static)


def write_rigid_bodies_recording(
    path: str | Path, hand: Trajectory, eye: Trajectory, storage: str = 'mcap', lost_every: int = 0
) -> None:
    """The hand as the body 'rig' between 'wand' and 'table' in mocap4r2 RigidBodies messages
    (as a driver publishes each capture frame) on RIGID_BODIES_TOPIC, missing from every
    ``lost_every``-th frame (0: never); the eye as nav_msgs/Odometry on /vio/odom."""
    odom = 'nav_msgs/msg/Odometry'
    with BagWriter(path, storage) as w:
        items = [
            (t, 1, '/vio/odom', odom, m)
            for t, m in pose_messages(w.store, eye, odom, 'odom', 'imu')
        ]
        for k, (t, p, q) in enumerate(
            zip(hand.t_ns.tolist(), hand.p_xyz.tolist(), hand.q_xyzw.tolist(), strict=True)
        ):
            bodies = [('wand', (0.3 * k % 7, 1.0, 0.5), (0.0, 0.0, 0.0, 1.0))]
            if not lost_every or k % lost_every != lost_every // 2:
                bodies.append(('rig', p, q))
            bodies.append(('table', (1.0, 2.0, 0.0), (0.0, 0.0, 0.0, 1.0)))
            items.append(
                (
                    t,
                    0,
                    RIGID_BODIES_TOPIC,
                    RIGID_BODIES_TYPES[0],
                    messages.rigid_bodies(w.store.types, t, 'mocap', bodies),
                )
            )
        items.sort(key=lambda x: (x[0], x[1]))
        for t, _, topic, msgtype, m in items:
            w.write(topic, msgtype, t, m)


def offset_of(msg: Any) -> float:
    """dt [s] from a TimeReference built by :func:`time_reference`."""
    s, r = msg.header.stamp, msg.time_ref
    return ((int(s.sec) - int(r.sec)) * 1_000_000_000 + int(s.nanosec) - int(r.nanosec)) * 1e-9
