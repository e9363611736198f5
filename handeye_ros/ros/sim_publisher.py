"""A simulated MoCap + VIO rig on two topics, to try the calibrator node without hardware.

``ros2 run handeye_ros sim_publisher [--seed 3 --level 3 --duration 40 ...]``

Simulates a recording with the paper's protocol (see ``handeye_ros.core.simulate``), waits for
subscribers, publishes the hand and eye poses interleaved by stamp at ``--rate`` messages per
second (stamps are the recording's, not the wall clock's), and prints one JSON line when done:
the truth and how many messages went out per topic. ``--bag PATH[:mcap|sqlite3|ros1]`` also
writes the very same messages to a bag, for ``offline_calibrate --bag``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy

from handeye_ros.core.simulate import noise_level, simulate
from handeye_ros.formats.bag import write_recording
from handeye_ros.stream import normalise_type


def message(cls_name: str, t_ns: int, p, q, frame: str, child: str):
    import geometry_msgs.msg as g
    import nav_msgs.msg as n
    cls = {'PoseStamped': g.PoseStamped, 'PoseWithCovarianceStamped': g.PoseWithCovarianceStamped,
           'TransformStamped': g.TransformStamped, 'Odometry': n.Odometry}[cls_name]
    m = cls()
    m.header.stamp.sec, m.header.stamp.nanosec = int(t_ns // 10 ** 9), int(t_ns % 10 ** 9)
    m.header.frame_id = frame
    if cls_name == 'TransformStamped':
        m.child_frame_id = child
        tr, rot = m.transform.translation, m.transform.rotation
    else:
        pose = m.pose if cls_name == 'PoseStamped' else m.pose.pose
        if cls_name == 'Odometry':
            m.child_frame_id = child
        tr, rot = pose.position, pose.orientation
    tr.x, tr.y, tr.z = (float(v) for v in p)
    rot.x, rot.y, rot.z, rot.w = (float(v) for v in q)
    return m


def main() -> int:
    ap = argparse.ArgumentParser(prog='sim_publisher', description=__doc__.split('\n')[0])
    ap.add_argument('--seed', type=int, default=3)
    ap.add_argument('--level', type=float, default=3.0)
    ap.add_argument('--duration', type=float, default=40.0)
    ap.add_argument('--hand-rate', type=float, default=100.0)
    ap.add_argument('--eye-rate', type=float, default=20.0)
    ap.add_argument('--hand-topic', default='/mocap/pose')
    ap.add_argument('--eye-topic', default='/vio/odom')
    ap.add_argument('--hand-type', default='PoseStamped')
    ap.add_argument('--eye-type', default='Odometry')
    ap.add_argument('--rate', type=float, default=1000.0, help='messages per second, both topics')
    ap.add_argument('--nan-every', type=int, default=0, help='every k-th eye message has NaN')
    ap.add_argument('--reliable', action='store_true', help='reliable publishers (default: '
                                                            'best-effort hand, reliable eye)')
    ap.add_argument('--bag', action='append', default=[], help='also write PATH:storage')
    ap.add_argument('--wait-subscribers', type=float, default=10.0)
    args = ap.parse_args()

    nm, nd = noise_level(args.level)
    rec = simulate(args.seed, duration_s=args.duration, hand_rate_hz=args.hand_rate,
                   eye_rate_hz=args.eye_rate, noise_m=nm, noise_deg=nd)
    for spec in args.bag:
        path, _, storage = spec.partition(':')
        write_recording(path, [(args.hand_topic, args.hand_type, rec.hand, 'mocap', 'marker'),
                               (args.eye_topic, args.eye_type, rec.eye, 'odom', 'imu')],
                        storage or 'mcap')
    rclpy.init()
    node = Node('recording_publisher')
    hand_qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE if args.reliable
                          else ReliabilityPolicy.BEST_EFFORT)
    import geometry_msgs.msg as g
    import nav_msgs.msg as n
    classes = {'PoseStamped': g.PoseStamped, 'PoseWithCovarianceStamped':
               g.PoseWithCovarianceStamped, 'TransformStamped': g.TransformStamped,
               'Odometry': n.Odometry}
    pubs = {'hand': node.create_publisher(classes[args.hand_type], args.hand_topic, hand_qos),
            'eye': node.create_publisher(classes[args.eye_type], args.eye_topic,
                                         QoSProfile(depth=1000))}
    deadline = time.monotonic() + args.wait_subscribers
    while time.monotonic() < deadline and not all(p.get_subscription_count() for p in
                                                    pubs.values()):
        time.sleep(0.05)
    time.sleep(0.3)  # let discovery settle on both sides
    items = sorted([(int(t), 0, k) for k, t in enumerate(rec.hand.t_ns)]
                   + [(int(t), 1, k) for k, t in enumerate(rec.eye.t_ns)])
    sent = {'hand': 0, 'eye': 0}
    t0 = time.monotonic()
    for j, (t, s, k) in enumerate(items):
        name = 'hand' if s == 0 else 'eye'
        traj = rec.hand if s == 0 else rec.eye
        p = traj.p_xyz[k]
        if name == 'eye' and args.nan_every and k % args.nan_every == args.nan_every - 1:
            p = [math.nan, 0.0, 0.0]
        pubs[name].publish(message(args.hand_type if s == 0 else args.eye_type, t, p,
                                   traj.q_xyzw[k], 'mocap' if s == 0 else 'odom',
                                   'marker' if s == 0 else 'imu'))
        sent[name] += 1
        ahead = (j + 1) / args.rate - (time.monotonic() - t0)
        if ahead > 0:
            time.sleep(ahead)
    time.sleep(0.5)  # let the last messages leave
    t = rec.truth
    print(json.dumps({'sent': sent, 'types': {'hand': normalise_type(args.hand_type),
                                              'eye': normalise_type(args.eye_type)},
                      'truth': {'time_offset': t.time_offset_s, 'q_HE': t.q_HE.tolist(),
                                'p_HE': t.p_HE.tolist()},
                      'seconds': time.monotonic() - t0}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
