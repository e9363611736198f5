"""Readiness and auto_calibrate live, through sim_publisher over DDS (issue 28's figures;
printed, not asserted).

bench/readiness.py measures the readiness function on prefixes of recordings, without ROS.
This runs what a user runs: for each seed, a calibrator node (auto_calibrate true, the
defaults otherwise) and a sim_publisher that sends a recording in real time, planar for its
first third and rich after (``--motion planar_start``). A probe in this process takes every
``~/status`` and every new result (the latched ``~/time_offset``), and after each result calls
``~/save`` and reads the saved file (the result, its reported 1-sigmas). Counted:
- results (each one made because the status said READY) further from the truth than 3x the
  targets (precision_*: 1 ms, 10 mm, 0.5 deg): must be 0;
- the first result: the status's predicted 1-sigmas at the READY that started it, over the
  result's reported ones (target: within a factor 2);
- wall time from that READY status to the result (target: within 2 s);
- auto mode's later results, on longer rich recordings (``--long-seeds``, 240 s): each
  published one's reported sigmas (none may be larger than the one's before: a result that
  does not improve is computed but not published), and whether the status said "converged"
  (or "done": the buffers are full).

The recording is bench/readiness.py's: hand 200 Hz with 0.1 mm / 0.006 deg MoCap noise, eye
30 Hz at noise level 5, 90 s.

Usage: python bench/readiness_live.py [--seeds 20]
"""

from __future__ import annotations

import argparse
import itertools
import json
import pickle
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import common  # first: puts the project on sys.path
import numpy as np
import yaml
from common import emit, table
from node_ingest import start, stop

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.simulate import Truth, calibration_error

DURATION_S = 90.0
#: After the recording: how long results may still come (a calibration started at its end).
GRACE_S = 4.0
PUBLISHER = (
    '--level', '5', '--hand-rate', '200', '--eye-rate', '30', '--mocap-noise', '0.1', '0.006',
    '--rate', '230',  # messages per second, both streams: real time
)  # fmt: skip
#: The recordings for auto mode's later results: rich from the start, longer.
LONG_S = 240.0
#: Recordings that stay planar or one-axis are sent this much faster than real time: "never
#: READY" needs statuses on growing buffers, not the real-time latency.
POOR_SPEEDUP = 4.0


class LiveProbe:
    """An rclpy node in this process: /calibrator's statuses and results, and ~/save."""

    def __init__(self) -> None:
        import rclpy
        from diagnostic_msgs.msg import DiagnosticStatus
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import Float64
        from std_srvs.srv import Trigger

        rclpy.init()
        self.rclpy, self.Trigger = rclpy, Trigger
        self.node = Node('bench_readiness_probe')
        self.lock = threading.Lock()
        self.statuses: list[tuple[float, dict]] = []
        self.results: list[float] = []
        self.node.create_subscription(DiagnosticStatus, '/calibrator/status', self._status, 50)
        latched = QoSProfile(
            depth=1,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL,
        )
        self.node.create_subscription(
            Float64, '/calibrator/time_offset', lambda _: self._stamp(self.results), latched
        )
        self.save = self.node.create_client(Trigger, '/calibrator/save')
        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _status(self, msg) -> None:
        values = {kv.key: kv.value for kv in msg.values}
        with self.lock:
            self.statuses.append((time.monotonic(), {'message': msg.message, **values}))

    def _stamp(self, into: list) -> None:
        with self.lock:
            into.append(time.monotonic())

    def clear(self) -> None:
        with self.lock:
            self.statuses, self.results = [], []

    def call_save(self) -> tuple[bool, str]:
        self.save.wait_for_service(timeout_sec=30.0)
        fut = self.save.call_async(self.Trigger.Request())
        end = time.monotonic() + 30.0
        while not fut.done() and time.monotonic() < end:
            time.sleep(0.005)
        return (fut.result().success, fut.result().message) if fut.done() else (False, 'timeout')

    def results_until(self, pub: subprocess.Popen, saved: Path, grace_s: float) -> list:
        """Until ``grace_s`` after the publisher ``pub`` ends: (when, the file ``~/save`` wrote,
        or why not) of every new result."""
        docs, seen, grace = [], 0, None
        while grace is None or time.monotonic() < grace:
            if grace is None and pub.poll() is not None:
                grace = time.monotonic() + grace_s
            with self.lock:
                n = len(self.results)
            if n > seen:
                seen = n
                ok, msg = self.call_save()
                docs.append(
                    (self.results[n - 1], yaml.safe_load(saved.read_text()) if ok else msg)
                )
            time.sleep(0.05)
        return docs

    def close(self) -> None:
        self.executor.shutdown()
        self.thread.join(timeout=5.0)
        self.node.destroy_node()
        self.rclpy.try_shutdown()


def _sigmas(status: dict) -> np.ndarray:
    """A status's predicted 1-sigmas (s, m, deg) from its flattened values."""
    keys = ('sigma.time_offset_ms', 'sigma.translation_mm', 'sigma.rotation_deg')
    v = [float(status[k]) if status.get(k, 'None') != 'None' else np.nan for k in keys]
    return np.array(v) * np.array([1e-3, 1e-3, 1.0])


def _reported(doc: dict) -> np.ndarray:
    std = doc['std']
    return np.array(
        [
            std['time_offset'],
            float(np.linalg.norm(std['translation'])),
            float(np.degrees(np.linalg.norm(std['rotation']))),
        ]
    )


def run_seed(
    probe: LiveProbe, seed: int, out: Path, motion: str, duration_s: float, speedup: float = 1.0
) -> dict:
    """One recording through the node; what happened, against the truth."""
    probe.clear()
    saved = out / f'seed{seed}.yaml'  # inside output_dir: the node writes nowhere else
    node = start(
        'handeye_ros.ros.calibrator',
        *('--ros-args', '-p', 'auto_calibrate:=true', '-p', f'output_dir:={out}'),
        *('-p', f'output_file:={saved.name}'),
        log=out / f'node{seed}.log',
    )
    pub = start(
        'handeye_ros.ros.sim_publisher',
        *('--seed', str(seed), '--motion', motion, '--duration', str(duration_s)),
        *PUBLISHER,
        *('--rate', str(230 * speedup)),  # the last --rate counts
    )
    docs = probe.results_until(pub, saved, GRACE_S)
    truth_line = json.loads(pub.stdout.read().strip().splitlines()[-1])
    stop(node)
    t = truth_line['truth']
    truth = Truth(t['time_offset'], np.array(t['q_HE']), np.array(t['p_HE']), None, None)
    with probe.lock:
        statuses = list(probe.statuses)
    ready = [(w, s) for w, s in statuses if s['message'] == 'READY']
    results = []
    for when, doc in docs:
        if not isinstance(doc, dict):
            results.append({'when': when, 'error': doc})
            continue
        err = calibration_error(
            truth,
            doc['time_offset'],
            doc['extrinsic']['rotation'],
            doc['extrinsic']['translation'],
        )
        results.append(
            {
                'when': when,
                'error': np.array([err.time_offset_s, err.translation_m, err.rotation_deg]),
                'reported': _reported(doc) if doc.get('std') else None,
                'verdict': doc.get('quality', {}).get('verdict'),
            }
        )
    converged = next(
        (
            s['auto_calibrate']
            for _, s in statuses
            if s.get('auto_calibrate', '').startswith(('converged', 'done'))
        ),
        '',
    )
    log = (out / f'node{seed}.log').read_text()
    return {
        'seed': seed,
        'motion': motion,
        'ever_ready': bool(ready),
        'named_axis': any(
            s['message'].startswith('turn the device about its') for _, s in statuses
        ),
        # auto_calibrate starts at the first READY: the first result is that READY's
        'first_ready': ready[0] if ready else None,
        'results': results,
        'converged': converged,
        'not_published': log.count('not published'),
        'rc': node.returncode,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--seeds', type=int, default=20)
    p.add_argument(
        '--long-seeds', type=int, default=3, help=f'rich recordings of {LONG_S:.0f} s (default 3)'
    )
    p.add_argument(
        '--poor-seeds',
        type=int,
        default=10,
        help=f'planar and one-axis recordings each, sent {POOR_SPEEDUP:g}x real time (default 10)',
    )
    args = p.parse_args()
    cfg = CalibrationConfig()
    target = np.array(
        [cfg.precision_time_offset, cfg.precision_translation, cfg.precision_rotation]
    )
    probe = LiveProbe()
    runs, longs, poors = [], [], []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for seed in range(args.seeds):
                r = run_seed(probe, seed, Path(tmp), 'planar_start', DURATION_S)
                runs.append(r)
                print(f'seed {seed}: {len(r["results"])} result(s)', flush=True)
            for motion in ('planar', 'one_axis'):
                for seed in range(100, 100 + args.poor_seeds):
                    r = run_seed(probe, seed, Path(tmp), motion, DURATION_S, POOR_SPEEDUP)
                    poors.append(r)
                    print(f'{motion} seed {seed}: READY {r["ever_ready"]}', flush=True)
            for seed in range(200, 200 + args.long_seeds):
                r = run_seed(probe, seed, Path(tmp), 'random', LONG_S)
                longs.append(r)
                print(f'seed {seed}: {len(r["results"])} result(s)', flush=True)
    finally:
        probe.close()
        # the raw runs, kept should the summary below fail after the hour they took
        with (common.OUT / 'readiness_live_runs.pkl').open('wb') as f:
            pickle.dump({'runs': runs, 'longs': longs, 'poors': poors}, f)
    rows, ratios, latency = [], [], []
    for r in runs:
        first = next((x for x in r['results'] if 'reported' in x), None)
        ratio = after = None
        if first is not None and r['first_ready'] is not None:
            after = first['when'] - r['first_ready'][0]
            latency.append(after)
            if first['reported'] is not None:
                ratio = _sigmas(r['first_ready'][1]) / first['reported']
                ratios.append(ratio)
        rows.append(
            [
                r['seed'],
                len(r['results']),
                '-' if after is None else f'{after:.1f}',
                '-' if first is None else _fmt(first['error'] * [1e3, 1e3, 1], '.3g'),
                '-' if ratio is None else _fmt(ratio, '.2f'),
            ]
        )
    long_rows, improved, later = [], 0, 0
    for r in longs:
        res = [x for x in r['results'] if 'reported' in x]
        for a, b in itertools.pairwise(res):
            later += 1
            improved += bool(np.all(b['reported'] <= a['reported']))
        long_rows.append(
            [
                r['seed'],
                ', '.join(_fmt(x['reported'] * [1e3, 1e3, 1], '.2g') for x in res) or '-',
                r['not_published'],
                r['converged'].split(':')[0] or 'no',
            ]
        )
    every = [x for r in runs + longs for x in r['results']]
    beyond = sum(bool(np.any(x['error'] > 3 * target)) for x in every if 'reported' in x)
    ratios = np.array(ratios) if ratios else np.full((1, 3), np.nan)
    summary = [
        [f'results beyond 3x the targets (of {len(every)})', beyond, '0'],
        ['recordings with a result', sum(bool(r['results']) for r in runs), str(args.seeds)],
        [
            'first result after the READY that started it, max [s]',
            f'{max(latency):.2f}' if latency else '-',
            '2',
        ],
        [
            'predicted / reported 1-sigma at the first result (dt, translation, rotation)',
            ' '.join(
                f'{a:.2f}-{b:.2f}' for a, b in zip(ratios.min(0), ratios.max(0), strict=True)
            ),
            '0.5-2',
        ],
        [
            'later published results with no reported sigma larger than the one before',
            f'{improved} of {later}',
            'all',
        ],
        [
            f'planar and one-axis recordings ({len(poors)}, {POOR_SPEEDUP:g}x real time) ever READY',
            sum(r['ever_ready'] for r in poors),
            '0',
        ],
        [
            f'planar and one-axis recordings ({len(poors)}) whose status named the axis to add',
            sum(r['named_axis'] for r in poors),
            str(len(poors)),
        ],
        ['node exit codes != 0', sum(r['rc'] != 0 for r in runs + longs + poors), '0'],
    ]
    emit(
        'readiness_live',
        table(
            f'auto_calibrate live ({args.seeds} seeds, planar for the first 30 s of '
            f'{DURATION_S:.0f} s, in real time through sim_publisher)',
            [
                'seed',
                'results',
                'first result after READY [s]',
                'its error (ms, mm, deg)',
                'predicted / reported 1-sigma',
            ],
            rows,
        )
        + '\n\n'
        + table(
            f'auto_calibrate on {len(longs)} rich recordings of {LONG_S:.0f} s: every published '
            'result',
            [
                'seed',
                'reported 1-sigmas (ms mm deg), in order',
                'computed, not published',
                'status',
            ],
            long_rows,
        )
        + '\n\n'
        + table('Readiness live against the truth', ['figure', 'measured', 'target'], summary),
        seeds=f'0..{args.seeds - 1} (poor then rich), 100..{99 + args.poor_seeds} (planar, '
        f'one-axis), 200..{199 + args.long_seeds} (rich, long)',
    )


def _fmt(v, spec: str) -> str:
    return ' '.join(f'{x:{spec}}' for x in v)


if __name__ == '__main__':
    main()
