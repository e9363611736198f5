"""The node under a loaded CPU: how many poses of 1 kHz + 200 Hz it loses, with and without
taking what waits in a subscription's queue after each message (``DRAIN_MAX`` in
handeye_ros/ros/subscriptions.py; printed, not asserted).

The calibrator as ``ros2 run`` starts it (reliable, keep last ``--depth``), ``--hogs`` busy
processes beside it, and sim_publisher sending 10 s of 1 kHz MoCap and 200 Hz device poses at
``--rate`` messages per second, reliable; then ``~/calibrate`` is called and the node's log says
how many poses it buffered. CPU: the node's user + system seconds while the poses came.

Usage: python bench/node_load.py [--depth 1000] [--hogs 0 8 16] [--runs 2]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path
from tempfile import TemporaryDirectory

from common import emit, table

NODE = (
    'import sys; import handeye_ros.ros.subscriptions as s; s.DRAIN_MAX = int(sys.argv[1]); '
    'from handeye_ros.ros.calibrator import main; sys.argv[1:2] = []; sys.exit(main())'
)
CALL = (
    'import rclpy; from std_srvs.srv import Trigger; rclpy.init(); '
    "n = rclpy.create_node('bench_caller'); "
    "c = n.create_client(Trigger, '/calibrator/calibrate'); c.wait_for_service(timeout_sec=30); "
    'f = c.call_async(Trigger.Request()); rclpy.spin_until_future_complete(n, f, timeout_sec=60)'
)
SENT = (10001, 1601)


def cpu_s(pid: int) -> float:
    """A process's user + system CPU seconds so far."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def wait_said(path: Path, pattern: str, timeout: float) -> re.Match[str]:
    """The first match of ``pattern`` in the node's log, waited for with a deadline."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = re.search(pattern, path.read_text())
        if found:
            return found
        time.sleep(0.1)
    raise TimeoutError(f'the node did not say {pattern!r}: {path.read_text()[-2000:]}')


def one(drain: int, depth: int, hogs: int, rate: float, domain: int) -> tuple[int, int, float]:
    """(hand poses buffered, device poses buffered, node CPU s) for one run."""
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', ROS_DOMAIN_ID=str(domain))
    with TemporaryDirectory() as tmp:
        log = Path(tmp) / 'node.log'
        args = ['-p', 'qos_reliability:=reliable', '-p', f'qos_depth:={depth}']
        with log.open('w') as out:
            node = subprocess.Popen(
                [sys.executable, '-c', NODE, str(drain), '--ros-args', *args]
                + ['-p', f'output_dir:={tmp}'],
                stdout=out,
                stderr=subprocess.STDOUT,
                env=env,
            )
        busy = [subprocess.Popen([sys.executable, '-c', 'while 1: pass']) for _ in range(hogs)]
        try:
            wait_said(log, 'buffering hand', 60)
            before = cpu_s(node.pid)
            pub = [sys.executable, '-m', 'handeye_ros.ros.sim_publisher', '--seed', '5']
            pub += ['--level', '2', '--duration', '10', '--hand-rate', '1000']
            pub += ['--eye-rate', '200', '--rate', f'{rate:g}', '--reliable']
            subprocess.run(pub, env=env, check=True, capture_output=True)
            used = cpu_s(node.pid) - before
        finally:
            for b in busy:
                b.kill()
        subprocess.run([sys.executable, '-c', CALL], env=env, check=True, timeout=120)
        said = wait_said(log, r'calibrating (\d+) MoCap and (\d+) device', 30)
        node.send_signal(2)
        node.wait(30)
    return int(said[1]), int(said[2]), used


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--depth', type=int, default=1000)
    p.add_argument('--hogs', type=int, nargs='+', default=[0, 8, 16])
    p.add_argument('--rate', type=float, default=1200.0)
    p.add_argument('--runs', type=int, default=2)
    args = p.parse_args()
    from handeye_ros.ros.subscriptions import DRAIN_MAX

    rows = []
    for hogs in args.hogs:
        for drain in (0, DRAIN_MAX):
            runs = [one(drain, args.depth, hogs, args.rate, 60 + k) for k in range(args.runs)]
            lost = [f'{SENT[0] - h} + {SENT[1] - e}' for h, e, _ in runs]
            cpu = [f'{c:.2f}' for _, _, c in runs]
            rows.append([hogs, drain, ', '.join(lost), ', '.join(cpu)])
            print(rows[-1], flush=True)
    emit(
        'node_load',
        table(
            f'The node (reliable, keep last {args.depth}) beside busy processes, while '
            f'sim_publisher sends {SENT[0]} MoCap + {SENT[1]} device poses at {args.rate:g} '
            f'messages/s; {args.runs} runs each',
            ['busy processes', 'taken after each message', 'lost (MoCap + device)', 'node CPU s'],
            rows,
        ),
    )


if __name__ == '__main__':
    main()
