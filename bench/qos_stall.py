"""What the subscription queue's depth buys when the node's executor stalls (the node's
``qos_depth``; printed, not asserted).

A subscriber process like the node's (best effort, keep last ``depth``) stalls its executor once
for ``stall`` seconds (a callback that sleeps) while a separate publisher process sends
PoseStamped at ``--rate`` messages per second; counted: how many of the sent messages the
subscriber took. DDS keeps at most ``depth`` messages for a reader that does not take them, so
a stall loses about ``stall * rate - depth``: the depth is how long a stall the node rides out.

Usage: python bench/qos_stall.py [--depths 1000 5000] [--stalls 1.1 2.5] [--rate 1200]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import textwrap

from common import emit, table

SUBSCRIBER = textwrap.dedent(
    """
    import sys, time
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    depth, stall, seconds = int(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
    rclpy.init()
    node = rclpy.create_node('stalled_subscriber')
    got, stalled = [0], [False]
    qos = QoSProfile(depth=depth, reliability=ReliabilityPolicy.BEST_EFFORT,
                     history=HistoryPolicy.KEEP_LAST)
    node.create_subscription(PoseStamped, '/qos_stall', lambda m: got.__setitem__(0, got[0] + 1), qos)
    def stall_once():
        if got[0] > 500 and not stalled[0]:
            stalled[0] = True
            time.sleep(stall)
    node.create_timer(0.05, stall_once)
    print('ready', flush=True)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.1)
    print(got[0], flush=True)
    """
)

PUBLISHER = textwrap.dedent(
    """
    import sys, time
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.qos import QoSProfile
    n, rate = int(sys.argv[1]), float(sys.argv[2])
    rclpy.init()
    node = rclpy.create_node('steady_publisher')
    pub = node.create_publisher(PoseStamped, '/qos_stall', QoSProfile(depth=1000))
    deadline = time.monotonic() + 30
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.3)  # both sides' discovery settles
    t0 = time.monotonic()
    for k in range(n):
        m = PoseStamped()
        m.header.stamp.sec = k
        pub.publish(m)
        ahead = (k + 1) / rate - (time.monotonic() - t0)
        if ahead > 0:
            time.sleep(ahead)
    print(n, flush=True)
    """
)


def one(depth: int, stall: float, rate: float, seconds: float) -> tuple[int, int]:
    """(taken, sent) for one depth and stall."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    n = int(rate * seconds)
    sub = subprocess.Popen(
        [sys.executable, '-c', SUBSCRIBER, str(depth), str(stall), str(seconds + 8)],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    assert sub.stdout.readline().strip() == 'ready'
    pub = subprocess.run(
        [sys.executable, '-c', PUBLISHER, str(n), str(rate)],
        capture_output=True,
        text=True,
        env=env,
        check=True,
    )
    taken = int(sub.communicate(timeout=60)[0].split()[-1])
    return taken, int(pub.stdout.split()[-1])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--depths', type=int, nargs='+', default=[1000, 5000])
    p.add_argument('--stalls', type=float, nargs='+', default=[1.1, 2.5])
    p.add_argument('--rate', type=float, default=1200.0)
    p.add_argument('--seconds', type=float, default=5.0)
    args = p.parse_args()
    rows = []
    for depth in args.depths:
        for stall in args.stalls:
            taken, sent = one(depth, stall, args.rate, args.seconds)
            rows.append([depth, stall, sent, taken, sent - taken])
            print(rows[-1], flush=True)
    emit(
        'qos_stall',
        table(
            f'One executor stall while {args.rate:g} PoseStamped/s arrive (best effort, keep '
            'last depth); a separate publisher process',
            ['depth', 'stall s', 'sent', 'taken', 'lost'],
            rows,
        ),
    )


if __name__ == '__main__':
    main()
