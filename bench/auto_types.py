"""What the node receives of a publisher that appears after it, with auto-typed topics (issue 13:
"type discovery that loses nothing"). Printed, not asserted.

Three nodes listen to one publisher process at once, each a calibrator as users start it:
``typed`` (hand_type PoseStamped, eye_type Odometry: subscribed at start, the reference),
``probed`` (auto, the default: type probes, see handeye_ros/ros/type_probes.py) and
``unprobed`` (auto with type_probes false: subscribes when the graph shows the type). The
publisher sends a 1 kHz hand and a 200 Hz eye (10 s of recording at 2000 messages/s), either
as soon as any subscriber has matched it (``waits``: sim_publisher's default, 0.3 s after the
first match) or 0.3 s after it appears whoever listens (``does not wait``: as ros2 bag play or
a MoCap driver). Each node's received counts are read from its /diagnostics.

Usage: python bench/auto_types.py [--runs 5]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import threading
import time

import common
from common import emit, table

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 101)))
ENV = dict(
    os.environ,
    PYTHONPATH=str(common.ROOT) + os.pathsep + os.environ.get('PYTHONPATH', ''),
    PYTHONUNBUFFERED='1',
)
NODES = {
    'typed': ['-p', 'hand_type:=PoseStamped', '-p', 'eye_type:=Odometry'],
    'probed': [],
    'unprobed': ['-p', 'type_probes:=false'],
}
PUBLISHER = ['--level', '2', '--duration', '10', '--hand-rate', '1000', '--eye-rate', '200']
RATE = '2000'


class Diagnostics:
    """The latest received counts of every node's streams, from /diagnostics."""

    def __init__(self) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        rclpy.init()
        self.rclpy = rclpy
        self.node = Node('bench_auto_types')
        self.counts: dict[tuple[str, str], int] = {}
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on, 100)
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on(self, msg) -> None:
        for st in msg.status:
            node, _, what = st.name.rpartition(': ')
            values = {kv.key: kv.value for kv in st.values}
            if what.endswith(' stream') and 'received' in values:
                self.counts[node.strip('/'), what.split()[0]] = int(values['received'])

    def close(self) -> None:
        self.executor.shutdown()
        self.thread.join(timeout=5.0)
        self.node.destroy_node()
        self.rclpy.try_shutdown()


def start(module: str, *args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, '-m', module, *args],
        env=ENV,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )


def stop(p: subprocess.Popen) -> str:
    if p.poll() is None:
        p.send_signal(signal.SIGINT)
    try:
        _, err = p.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        _, err = p.communicate()
    return err


def one_run(diag: Diagnostics, seed: int, waits: bool) -> dict:
    """Received and sent counts of one publisher run; and whether any log held a traceback."""
    diag.counts.clear()
    nodes = {
        name: start('handeye_ros.ros.calibrator', '--ros-args', '-r', f'__node:={name}', *args)
        for name, args in NODES.items()
    }
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and len(diag.counts) < 2 * len(NODES):
        time.sleep(0.1)
    pub = start(
        'handeye_ros.ros.sim_publisher',
        '--seed',
        str(seed),
        *PUBLISHER,
        '--rate',
        RATE,
        *([] if waits else ['--wait-subscribers', '0']),
    )
    out, _ = pub.communicate(timeout=300)
    sent = json.loads(out.strip().splitlines()[-1])['sent']
    time.sleep(2.5)  # two diagnostics periods
    counts = dict(diag.counts)
    logs = {name: stop(p) for name, p in nodes.items()}
    return {
        'sent': sent,
        'received': {n: {s: counts.get((n, s), 0) for s in sent} for n in NODES},
        'tracebacks': sum('Traceback' in e for e in logs.values()),
        'handovers': {n: logs[n].count('handed over from the type probe') for n in NODES},
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--runs', type=int, default=5, help='publisher runs per mode (default: 5)')
    args = ap.parse_args()
    diag = Diagnostics()
    rows = []
    seeds = []
    try:
        for waits in (True, False):
            runs = []
            for k in range(args.runs):
                seeds.append(100 + k)
                r = one_run(diag, 100 + k, waits)
                runs.append(r)
                print(json.dumps(r), flush=True)
            for name in NODES:
                sent = {s: sum(r['sent'][s] for r in runs) for s in ('hand', 'eye')}
                got = {s: sum(r['received'][name][s] for r in runs) for s in ('hand', 'eye')}
                lossy = sum(r['received'][name] != r['sent'] for r in runs)
                rows.append(
                    (
                        'waits' if waits else 'does not wait',
                        name,
                        f'{got["hand"]} / {sent["hand"]}',
                        f'{got["eye"]} / {sent["eye"]}',
                        f'{lossy} / {len(runs)}',
                        sum(r['tracebacks'] for r in runs),
                    )
                )
    finally:
        diag.close()
    emit(
        'auto_types',
        table(
            f'auto_types: received / sent over {args.runs} runs a mode (1 kHz hand + 200 Hz '
            f'eye, 10 s, {RATE} msg/s; three nodes on one publisher)',
            ['publisher', 'node', 'hand', 'eye', 'runs with loss', 'tracebacks'],
            rows,
        ),
        seeds=f'sim_publisher --seed {sorted(set(seeds))}',
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
