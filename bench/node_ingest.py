"""The node and the bag replay under load (issue figures; printed, not asserted).

(a) Ingest: a separate publisher process sends a 1 kHz hand and a 200 Hz eye for 10 minutes
    (issue 13's figure; --minutes) in real time; the node's received counts against the
    published ones, and its resident memory over time with buffer_duration 20 s (the buffers
    fill after 20 s, then drop the oldest; --buffer-duration 1800 is the node's default).
(b) ~/calibrate on a 5-minute buffer (200 Hz + 30 Hz) while the publisher keeps sending: the
    service round trip, and whether anything was lost meanwhile.
(c) Offline: a 10-minute mcap bag (200 Hz + 30 Hz) calibrated end to end by offline_calibrate.
(d) The readiness status's cost (issue 28): (a) again with status_period 0 (--baseline-minutes),
    and the CPU time of the node and of its worker processes over each run, against the wall
    time: the difference is what the status costs. With it, how often a status came (the
    intervals between computed ~/status messages; MAX_DUTY spaces them out as they cost more).

Every rclpy process runs with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST on a random domain.
Usage: python bench/node_ingest.py [--skip a b c] [--minutes 10]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
from common import emit, table
from live import ENV, Probe, children, cpu_s, rss_mb, start, stop

#: The node's buffer_duration in (a) and (d) [s]: the buffers fill after 20 s, then the ring
#: drops its oldest poses, the steady state of a long recording.
BUFFER_S = 20.0


def sent_counts(pub: subprocess.Popen) -> dict:
    import json

    out, _ = pub.communicate(timeout=600)
    return json.loads(out.strip().splitlines()[-1])['sent']


def ingest(probe: Probe, minutes: float, buffer_s: float, status_period: float = 1.0) -> list:
    node = start(
        'handeye_ros.ros.calibrator',
        '--ros-args',
        '-p',
        f'buffer_duration:={buffer_s}',
        '-p',
        f'status_period:={status_period}',
    )
    time.sleep(1.0)
    pub = start(
        'handeye_ros.ros.sim_publisher',
        '--hand-rate',
        '1000',
        '--eye-rate',
        '200',
        '--duration',
        str(60 * minutes),
        '--rate',
        '1200',
        '--level',
        '2',
    )
    samples = []
    probe.status_t.clear()
    t0 = time.monotonic()
    cpu0 = cpu_s(node.pid), {c: cpu_s(c) for c in children(node.pid)}
    while pub.poll() is None:
        samples.append((time.monotonic() - t0, rss_mb(node.pid)))
        time.sleep(1.0)
    wall = time.monotonic() - t0
    cpu_node = cpu_s(node.pid) - cpu0[0]
    cpu_workers = sum(cpu_s(c) - cpu0[1].get(c, 0.0) for c in children(node.pid))
    sent = sent_counts(pub)
    time.sleep(2.0)  # a diagnostics period
    rows = []
    for s in ('hand', 'eye'):
        d = probe.stream(s)
        rows.append(
            [
                s,
                sent[s],
                d.get('received'),
                sent[s] - int(d.get('received', 0)),
                d.get('buffered'),
                d.get('dropped'),
                d.get('rate_hz'),
            ]
        )
    stop(node)
    lost = sum(r[3] for r in rows)
    cost = [status_period, f'{wall / 60:.1f}', lost, 100 * cpu_node / wall]
    cost += [100 * cpu_workers / wall, 100 * (cpu_node + cpu_workers) / wall]
    gaps = np.diff(probe.status_t)
    last = np.diff([t for t in probe.status_t if t > t0 + wall - 60.0])
    cost += [
        f'{np.median(gaps):.1f} / {np.max(gaps):.1f}' if gaps.size else '-',
        f'{np.median(last):.1f}' if last.size else '-',
    ]
    if status_period == 0.0:
        return cost
    tag = '' if buffer_s == BUFFER_S else f'_buffers{buffer_s:g}s'
    emit(
        f'node_ingest{tag}',
        table(
            f'(a) Ingest 1 kHz hand + 200 Hz eye for {minutes:g} min from a separate process '
            f'(buffer_duration {buffer_s:g} s)',
            ['stream', 'published', 'received', 'lost', 'buffered', 'dropped (buffer)', 'rate Hz'],
            rows,
        ),
    )
    total = 60 * minutes
    at = sorted({2, 10, 20, 30, *(round(total * f) for f in (0.25, 0.5, 0.75, 1.0))})
    marks = [s for s in samples if int(s[0]) in at]
    emit(
        f'node_memory{tag}',
        table(
            '(a) Node resident memory during ingest',
            ['t s', 'RSS MB'],
            [[f'{t:.0f}', m] for t, m in marks],
        ),
    )
    return cost


def calibrate_while_ingesting(probe: Probe) -> None:
    node = start('handeye_ros.ros.calibrator')
    time.sleep(1.0)
    pub = start(
        'handeye_ros.ros.sim_publisher',
        '--hand-rate',
        '200',
        '--eye-rate',
        '30',
        '--duration',
        '400',
        '--rate',
        '1500',
        '--level',
        '3',
    )
    while pub.poll() is None and float(probe.stream('eye').get('buffered_span_s', 0)) < 300.0:
        time.sleep(0.2)
    before = {s: int(probe.stream(s).get('received', 0)) for s in ('hand', 'eye')}
    took, ok, message = probe.calibrate()
    time.sleep(1.5)
    during = {s: int(probe.stream(s).get('received', 0)) - before[s] for s in ('hand', 'eye')}
    sent = sent_counts(pub)
    time.sleep(2.0)
    lost = {s: sent[s] - int(probe.stream(s).get('received', 0)) for s in ('hand', 'eye')}
    stop(node)
    emit(
        'node_calibrate',
        table(
            '(b) ~/calibrate on a 5-minute buffer (200 Hz + 30 Hz) while ingest continues '
            '(1500 msg/s)',
            ['round trip s', 'success', 'msgs received meanwhile', 'lost overall', 'answer'],
            [
                [
                    took,
                    ok,
                    f'{during["hand"]} + {during["eye"]}',
                    f'{lost["hand"]} + {lost["eye"]}',
                    message[:60],
                ]
            ],
        ),
    )


def offline_bag() -> None:
    from handeye_ros.core.simulate import noise_level, simulate
    from handeye_ros.formats.bag import write_recording

    nm, nd = noise_level(3)
    rec = simulate(2, duration_s=600, hand_rate_hz=200, eye_rate_hz=30, noise_m=nm, noise_deg=nd)
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / 'ten_minutes'
        write_recording(
            bag,
            [
                ('/mocap/pose', 'PoseStamped', rec.hand, 'mocap', 'marker'),
                ('/vio/odom', 'Odometry', rec.eye, 'odom', 'imu'),
            ],
            'mcap',
        )
        size = sum(f.stat().st_size for f in bag.iterdir()) / 2**20
        t0 = time.perf_counter()
        proc = subprocess.run(
            [
                sys.executable,
                '-m',
                'handeye_ros.offline',
                '--bag',
                str(bag),
                '--json',
                '--no-progress',
            ],
            env=ENV,
            capture_output=True,
            text=True,
            check=True,
        )
        took = time.perf_counter() - t0
    import json

    d = json.loads(proc.stdout)
    emit(
        'offline_bag',
        table(
            '(c) offline_calibrate --bag on a 10-minute mcap bag (200 Hz + 30 Hz), end to end '
            '(process start to result)',
            ['messages', 'bag MB', 'wall s', '|dt error| ms'],
            [
                [
                    len(rec.hand) + len(rec.eye),
                    size,
                    took,
                    abs(d['time_offset'] - rec.truth.time_offset_s) * 1e3,
                ]
            ],
        ),
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--skip', nargs='*', default=[], choices=['a', 'b', 'c'])
    p.add_argument('--minutes', type=float, default=10.0, help='length of (a) (default: 10)')
    p.add_argument(
        '--baseline-minutes',
        type=float,
        default=3.0,
        help='length of (d), the run without the status (default: 3; 0 skips it)',
    )
    p.add_argument(
        '--buffer-duration',
        type=float,
        default=20.0,
        help="the node's buffer_duration in (a) and (d) [s] (default: 20; the node's own: 1800)",
    )
    args = p.parse_args()
    if 'c' not in args.skip:
        offline_bag()
    if {'a', 'b'} - set(args.skip):
        probe = Probe()
        try:
            if 'a' not in args.skip:
                costs = [ingest(probe, args.minutes, args.buffer_duration)]
                if args.baseline_minutes > 0:
                    costs.append(ingest(probe, args.baseline_minutes, args.buffer_duration, 0.0))
                tag = (
                    ''
                    if args.buffer_duration == BUFFER_S
                    else f'_buffers{args.buffer_duration:g}s'
                )
                emit(
                    f'node_status_cost{tag}',
                    table(
                        '(d) CPU of the node and its workers during (a), with and without the '
                        'readiness status (% of one core, over the wall time; '
                        f'buffer_duration {args.buffer_duration:g} s), and a status every',
                        [
                            'status_period s',
                            'minutes',
                            'lost',
                            'node %',
                            'workers %',
                            'total %',
                            'status every s (median / max)',
                            'in the last minute (median)',
                        ],
                        costs,
                    ),
                )
            if 'b' not in args.skip:
                calibrate_while_ingesting(probe)
        finally:
            probe.close()


if __name__ == '__main__':
    main()
