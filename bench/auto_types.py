"""What the node receives of a publisher that appears after it, with auto-typed topics (issue 13:
"type discovery that loses nothing"). Printed, not asserted.

A calibrator node, started as users start it, then a publisher process that appears after it.
The publisher sends the ``likeliest`` types (PoseStamped hand, Odometry eye: what an
auto-typed node subscribes at start) or ``others`` (TransformStamped, PoseWithCovarianceStamped:
what only the type probes can receive before the graph names them). The node is one of
``typed`` (hand_type and eye_type set to the published types: subscribed at start, the
reference), ``probed`` (auto, the default; see handeye_ros/ros/type_probes.py) or
``unprobed`` (auto with type_probes false). The publisher sends a 1 kHz hand and a 200 Hz eye
in real time (6 s), either as soon as a subscriber has matched it (``waits``: sim_publisher's
default, 0.3 s after the first match) or 0.3 s after it appears, whoever listens (``does not
wait``: as ros2 bag play or a MoCap driver started on its own). Both sides are reliable, so that what is lost
is lost to discovery, not to a queue (bench/node_ingest.py measures ingest under load). The
node's received counts are read from its /diagnostics.

Usage: python bench/auto_types.py [--runs 5]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time

import common  # noqa: F401  (puts the repository on sys.path)
from common import emit, table
from node_ingest import Probe, start  # sets the LOCALHOST discovery range and a random domain

NODES = ('typed', 'probed', 'unprobed')
#: The published (hand, eye) types.
TYPES = {
    'likeliest': ('PoseStamped', 'Odometry'),
    'others': ('TransformStamped', 'PoseWithCovarianceStamped'),
}
PUBLISHER = ['--level', '2', '--duration', '6', '--hand-rate', '1000', '--eye-rate', '200']
RATE = '1200'


def stop(p: subprocess.Popen) -> str:
    if p.poll() is None:
        p.send_signal(signal.SIGINT)
    try:
        _, err = p.communicate(timeout=15)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        _, err = p.communicate()
    return err


def node_args(name: str, hand_type: str, eye_type: str) -> list[str]:
    if name == 'typed':
        return ['-p', f'hand_type:={hand_type}', '-p', f'eye_type:={eye_type}']
    return ['-p', 'type_probes:=false'] if name == 'unprobed' else []


def one_run(probe: Probe, name: str, seed: int, waits: bool, types: str) -> dict:
    """Received and sent counts of one node and one publisher run, and its log's findings."""
    probe.diag.clear()
    node = start(
        'handeye_ros.ros.calibrator',
        '--ros-args',
        '-r',
        f'__node:={name}',
        '-p',
        'qos_reliability:=reliable',
        *node_args(name, *TYPES[types]),
    )
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not all(
        'received' in probe.stream(s, name) for s in ('hand', 'eye')
    ):
        time.sleep(0.1)
    pub = start(
        'handeye_ros.ros.sim_publisher',
        '--seed',
        str(seed),
        *PUBLISHER,
        '--rate',
        RATE,
        '--reliable',
        '--hand-type',
        TYPES[types][0],
        '--eye-type',
        TYPES[types][1],
        *([] if waits else ['--wait-subscribers', '0']),
    )
    out, _ = pub.communicate(timeout=300)
    sent = json.loads(out.strip().splitlines()[-1])['sent']
    time.sleep(2.5)  # two diagnostics periods
    log = stop(node)
    return {
        'node': name,
        'waits': waits,
        'types': types,
        'sent': sent,
        'received': {s: int(probe.stream(s, name).get('received', 0)) for s in sent},
        'traceback': 'Traceback' in log,
        'handovers': log.count('handed over from the type probe'),
        'not earlier': log.count('matched its publisher no earlier'),
        'confirmed': log.count('as subscribed from the start'),
        'timeouts': log.count('the type probe held none'),
    }


def mode_rows(probe: Probe, waits: bool, types: str, n: int, seeds: list[int]) -> list[tuple]:
    """The table rows of one publisher mode and type set: each node over ``n`` runs."""
    runs: dict[str, list[dict]] = {name: [] for name in NODES}
    for k in range(n):
        seeds.append(100 + k)
        for name in NODES:
            r = one_run(probe, name, 100 + k, waits, types)
            runs[name].append(r)
            print(json.dumps(r), flush=True)
    rows = []
    for name, rs in runs.items():
        sent = {s: sum(r['sent'][s] for r in rs) for s in ('hand', 'eye')}
        got = {s: sum(r['received'][s] for r in rs) for s in ('hand', 'eye')}
        ends = ('confirmed', 'handovers', 'not earlier', 'timeouts')
        rows.append(
            (
                'waits' if waits else 'does not wait',
                types,
                name,
                f'{got["hand"]} / {sent["hand"]}',
                f'{got["eye"]} / {sent["eye"]}',
                f'{sum(r["received"] != r["sent"] for r in rs)} / {len(rs)}',
                ' / '.join(str(sum(r[k] for r in rs)) for k in ends),
                sum(r['traceback'] for r in rs),
            )
        )
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--runs', type=int, default=5, help='publisher runs per mode (default: 5)')
    args = ap.parse_args()
    probe = Probe()
    rows = []
    seeds = []
    try:
        for waits in (True, False):
            for types in TYPES:
                rows += mode_rows(probe, waits, types, args.runs, seeds)
    finally:
        probe.close()
    emit(
        'auto_types',
        table(
            f'auto_types: received / sent over {args.runs} runs a node and mode (1 kHz hand + '
            f'200 Hz eye in real time, 6 s, reliable)',
            [
                'publisher',
                'types',
                'node',
                'hand',
                'eye',
                'runs with loss',
                'first sub confirmed / probe handed over / not earlier / timed out',
                'tracebacks',
            ],
            rows,
        ),
        seeds=f'sim_publisher --seed {sorted(set(seeds))}',
    )
    return 0


if __name__ == '__main__':
    sys.exit(main())
