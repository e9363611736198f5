"""A simulated MoCap + VIO rig on two topics, to try the calibrator node without hardware, or a
recorded one replayed from its files.

``ros2 run handeye_ros sim_publisher [--seed 3 --level 3 --duration 60 ...]``
``ros2 run handeye_ros sim_publisher --replay HAND.csv EYE.txt [--speed 1]``

Simulates a recording with the paper's protocol (see ``handeye_ros.core.simulate``), waits for
subscribers, publishes the hand and eye poses interleaved by stamp at ``--rate`` messages per
second (stamps are the recording's, not the wall clock's), and prints one JSON line when done:
the truth (null for a replay) and how many messages went out per topic. ``--replay`` reads two
trajectory files as ``offline_calibrate`` does and publishes them at the pace of their stamps
(``--speed`` times real time), as ``ros2 bag play`` would a bag of them. ``--bag PATH[:mcap|sqlite3|ros1]`` also
writes the very same messages to a bag, for ``offline_calibrate --bag``.

Many-pose types (they need tf2_msgs / mocap4r2_msgs importable), as drivers publish them:
``--hand-type TFMessage`` publishes world -> rig (moving) on the hand topic and rig -> marker
on /tf_static (latched), so the hand is ``/tf:world.marker``; ``--eye-type TFMessage``
publishes the inverse link imu -> odom, so the eye is ``/tf:odom.imu``; ``--hand-type
RigidBodies`` publishes the bodies 'wand' and 'rig' (the hand: ``TOPIC:rig``) in each message.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from typing import TYPE_CHECKING, NamedTuple

from .lifecycle import ignore_signals, quiet_start, stop_requested
from .sim_options import parse, parser
from .types import RclpyTypes

if TYPE_CHECKING:  # the core is imported once the command line is read
    from rclpy.node import Node
    from rclpy.publisher import Publisher

    from handeye_ros.core.simulate import Truth
    from handeye_ros.core.trajectory import Trajectory
    from handeye_ros.formats.messages import Vec
    from handeye_ros.stream.shapes import Message

    #: Per stream: what goes on the wire (trajectory, frame, child frame).
    Wire = dict[str, tuple[Trajectory, str, str]]


class Outgoing(NamedTuple):
    """What is published: the hand's and the eye's poses, and the truth when simulated."""

    hand: Trajectory
    eye: Trajectory
    truth: Truth | None


#: rclpy message classes, imported on first use.
TYPES = RclpyTypes()
#: A second body in every RigidBodies message, as a MoCap tracking more than the rig sends.
WAND = ('wand', (1.0, 2.0, 0.5), (0.0, 0.0, 0.0, 1.0))


def message_class(cls_name: str) -> type:
    from handeye_ros.stream import normalise_type

    return TYPES[normalise_type(cls_name)]


def message(cls_name: str, t_ns: int, p: Vec, q: Vec, frame: str, child: str) -> Message:
    """One pose as a message of type ``cls_name`` (formats/messages.py builds it)."""
    from handeye_ros.formats import messages
    from handeye_ros.stream import normalise_type

    msgtype = normalise_type(cls_name)
    if cls_name == 'RigidBodies':
        return messages.rigid_bodies(TYPES, t_ns, frame, [WAND, (child, p, q)])
    return messages.pose_message(TYPES, msgtype, t_ns, p, q, (frame, child))


def _publishers(node: Node, args: argparse.Namespace, rec: Outgoing) -> dict[str, Publisher]:
    """The hand's and the eye's publishers ('hand', 'eye'); with a TFMessage hand, the rig's
    marker also on /tf_static (latched), as a MoCap driver publishes it."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from handeye_ros.formats.bag import RIG_TO_MARKER

    # reliable: a history as long as the recording, so that a subscriber that falls behind
    # (a loaded machine) is waited for rather than overwritten
    depth = max(1000, len(rec.hand)) if args.reliable else 1000
    hand_qos = QoSProfile(
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE if args.reliable else ReliabilityPolicy.BEST_EFFORT,
    )
    pubs = {
        'hand': node.create_publisher(message_class(args.hand_type), args.hand_topic, hand_qos),
        'eye': node.create_publisher(
            message_class(args.eye_type), args.eye_topic, QoSProfile(depth=max(1000, len(rec.eye)))
        ),
    }
    if args.hand_type == 'TFMessage':
        static = node.create_publisher(
            message_class('TFMessage'),
            '/tf_static',
            QoSProfile(
                depth=1,
                reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.TRANSIENT_LOCAL,
            ),
        )
        static.publish(
            message('TFMessage', int(rec.hand.t_ns[0]), *RIG_TO_MARKER, 'rig', 'marker')
        )
    return pubs


def _subscribed(pubs: dict[str, Publisher], args: argparse.Namespace) -> bool:
    """Wait for a subscriber on both topics, at most ``args.wait_subscribers`` (said on stderr
    when it passes); False when a signal came meanwhile."""
    deadline = time.monotonic() + args.wait_subscribers
    while time.monotonic() < deadline and not all(
        p.get_subscription_count() for p in pubs.values()
    ):
        if stop_requested():
            return False
        time.sleep(0.05)
    alone = [p.topic_name for p in pubs.values() if not p.get_subscription_count()]
    if alone and args.wait_subscribers > 0:
        print(
            f'sim_publisher: nobody subscribes to {" and ".join(alone)} after '
            f'{args.wait_subscribers:g} s (is the calibrator running, with these topics?): '
            'publishing anyway',
            file=sys.stderr,
            flush=True,
        )
    return True


def _publish(
    node: Node, args: argparse.Namespace, rec: Outgoing, wire: Wire
) -> tuple[dict[str, int], float] | None:
    """Publish the recording's poses interleaved by stamp (at ``--rate`` messages per second,
    or at the pace of their stamps: :func:`_due_s`), once a subscriber is on both topics (or
    ``args.wait_subscribers`` has passed, said on stderr); (sent per stream, seconds), or None
    when a signal stopped it."""
    import numpy as np

    pubs = _publishers(node, args, rec)
    if not _subscribed(pubs, args):
        return None
    time.sleep(0.3)  # let discovery settle on both sides
    items = sorted(
        [(int(t), 0, k) for k, t in enumerate(rec.hand.t_ns)]
        + [(int(t), 1, k) for k, t in enumerate(rec.eye.t_ns)]
    )
    speed = _speed(args)
    _say_pace(args, rec, speed)
    due = _due_s([t for t, _, _ in items], args.rate, speed)
    sent = {'hand': 0, 'eye': 0}
    jump_ns, jump_from = round(args.clock_jump * 1e9), len(rec.eye) // 2
    lost = (0, 0)  # the MoCap dropout's stamps [ns), from the first hand stamp
    if args.mocap_dropout is not None:
        start, length = (round(v * 1e9) for v in args.mocap_dropout)
        lost = (int(rec.hand.t_ns[0]) + start, int(rec.hand.t_ns[0]) + start + length)
    t0 = time.monotonic()
    for j, (t, s, k) in enumerate(items):
        if stop_requested():
            return None
        name = 'hand' if s == 0 else 'eye'
        traj, frame, child = wire[name]
        p = traj.p_xyz[k]
        if name == 'eye' and args.nan_every and k % args.nan_every == args.nan_every - 1:
            p = np.array([math.nan, 0.0, 0.0])
        if name == 'hand' and lost[0] <= t < lost[1]:
            p = np.full(3, math.nan)
        unset = args.zero_stamps in (name, 'both')
        if name == 'eye' and k >= jump_from:
            t += jump_ns
        kind = args.hand_type if s == 0 else args.eye_type
        pubs[name].publish(message(kind, 0 if unset else t, p, traj.q_xyzw[k], frame, child))
        sent[name] += 1
        ahead = due[j] - (time.monotonic() - t0)
        if ahead > 0:
            time.sleep(ahead)
    _let_leave(pubs, args.reliable)
    return sent, time.monotonic() - t0


def _say_pace(args: argparse.Namespace, rec: Outgoing, speed: float | None) -> None:
    """What is published where, and at which pace, on stderr."""
    pace = f'{args.rate:g} messages/s' if speed is None else f'{speed:g}x their stamps'
    print(
        f'sim_publisher: publishing {len(rec.hand)} MoCap poses on {args.hand_topic} and '
        f'{len(rec.eye)} device poses on {args.eye_topic} at {pace}',
        file=sys.stderr,
        flush=True,
    )


def _due_s(stamps: list[int], rate: float, speed: float | None) -> list[float]:
    """When each message (by its stamp [ns]) is due, in seconds from the first: at ``rate``
    per second, or at ``speed`` times the pace of the stamps."""
    if speed is None:
        return [(j + 1) / rate for j in range(len(stamps))]
    return [(t - stamps[0]) * 1e-9 / speed for t in stamps]


def _speed(args: argparse.Namespace) -> float | None:
    """How many times real time the stamps are followed; None: at ``--rate`` messages/s."""
    return args.speed if args.speed is not None or args.replay is None else 1.0


def _let_leave(pubs: dict[str, Publisher], reliable: bool) -> None:
    """Let the last messages leave: reliable, until every subscriber acknowledged each (at most
    10 s); then 0.5 s, for a subscriber to take them from its queue before this leaves (a call
    right after it must see them)."""
    if reliable:
        from rclpy.duration import Duration

        for pub in pubs.values():
            pub.wait_for_all_acked(Duration(seconds=10.0))
    time.sleep(0.5)


def _check_types(args: argparse.Namespace) -> None:
    """A message type that carries no pose, or whose package this Python cannot import, is a
    usage error (exit 2), before anything is simulated or published."""
    from handeye_ros.core.errors import HandeyeError

    for flag, name in (('--hand-type', args.hand_type), ('--eye-type', args.eye_type)):
        try:
            message_class(name)
        except HandeyeError as err:
            parser().error(f'{flag} {name}: {err}')


def _recording(args: argparse.Namespace) -> Outgoing:
    """The recording: the ``--replay`` files' (no truth), or a simulated one
    (:func:`handeye_ros.core.simulate.simulate`); written into the ``--bag`` files asked for.
    A file that cannot be read, a bad simulation option or a bag that cannot be written is a
    usage error."""
    from handeye_ros.core.errors import InputError
    from handeye_ros.formats.bag import write_recording

    try:
        rec = _replayed(args.replay) if args.replay else _simulated(args)
        for spec in args.bag:
            path, _, storage = spec.partition(':')
            write_recording(
                path,
                [
                    (args.hand_topic, args.hand_type, rec.hand, 'mocap', 'marker'),
                    (args.eye_topic, args.eye_type, rec.eye, 'odom', 'imu'),
                ],
                storage or 'mcap',
            )
    except InputError as err:
        parser().error(str(err))
    return rec


def _replayed(paths: list[str]) -> Outgoing:
    """The two trajectory files as a recording without a truth; what the reader noted of them
    (a unit or quaternion order it assumed, repeated stamps it kept one of) said on stderr, as
    offline_calibrate's warnings say it."""
    from handeye_ros.formats import read_trajectory

    hand, eye = (read_trajectory(p) for p in paths)
    for note in (*hand.notes, *eye.notes):
        print(f'sim_publisher: {note}', file=sys.stderr, flush=True)
    return Outgoing(hand, eye, None)


def _simulated(args: argparse.Namespace) -> Outgoing:
    from handeye_ros.core.simulate import noise_level, simulate

    nm, nd = noise_level(args.level)
    rec = simulate(
        args.seed,
        duration_s=args.duration,
        hand_rate_hz=args.hand_rate,
        eye_rate_hz=args.eye_rate,
        noise_m=nm,
        noise_deg=nd,
        hand_noise_m=args.mocap_noise[0] * 1e-3,
        hand_noise_deg=args.mocap_noise[1],
        motion=args.motion,
    )
    return Outgoing(rec.hand, rec.eye, rec.truth)


def _wire(args: argparse.Namespace, rec: Outgoing) -> Wire:
    """What goes on the wire, and between which frames (see the module docstring): per
    stream (trajectory, frame, child frame)."""
    from handeye_ros.formats.bag import tf_links

    wire: Wire = {'hand': (rec.hand, 'mocap', 'marker'), 'eye': (rec.eye, 'odom', 'imu')}
    rig, imu = tf_links(rec.hand, rec.eye)
    if args.hand_type == 'TFMessage':
        wire['hand'] = (rig, 'world', 'rig')
    elif args.hand_type == 'RigidBodies':
        wire['hand'] = (rec.hand, 'mocap', 'rig')
    if args.eye_type == 'TFMessage':
        wire['eye'] = (imu, 'imu', 'odom')
    return wire


def _say_truth(
    args: argparse.Namespace, rec: Outgoing, sent: dict[str, int], seconds: float
) -> None:
    """One JSON line on stdout: what was sent, the types, the truth and the seconds taken."""
    from handeye_ros.core.geometry import positive_w
    from handeye_ros.stream import normalise_type

    t = rec.truth
    print(
        json.dumps(
            {
                'sent': sent,
                'types': {
                    'hand': normalise_type(args.hand_type),
                    'eye': normalise_type(args.eye_type),
                },
                'truth': None
                if t is None
                else {
                    'time_offset': t.time_offset_s,
                    'q_HE': positive_w(t.q_HE).tolist(),
                    'p_HE': t.p_HE.tolist(),
                },
                'seconds': seconds,
            }
        ),
        flush=True,
    )


def main(argv: list[str] | None = None) -> int:
    """Simulate, publish, print the truth; 0 also when stopped by Ctrl-C or SIGTERM, at any
    moment (the signals are only noted, as the calibrator's: :mod:`.lifecycle`)."""
    quiet_start()
    argv = sys.argv if argv is None else ['sim_publisher', *argv]
    # the ROS arguments (ros2 launch appends --ros-args to every node's command line) are rcl's
    from rclpy.utilities import remove_ros_args

    args = parse(remove_ros_args(argv)[1:])
    _check_types(args)
    rec = _recording(args)
    wire = _wire(args, rec)
    if stop_requested():
        return 0
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('recording_publisher')
    try:
        done = _publish(node, args, rec, wire)
    finally:
        ignore_signals()
        node.destroy_node()
        rclpy.try_shutdown()
    if done is None:
        return 0
    _say_truth(args, rec, *done)
    return 0


if __name__ == '__main__':
    sys.exit(main())
