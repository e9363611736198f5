"""The node's lifecycle under real signals (issue 13's figure; printed, not asserted).

Each cycle starts the calibrator node as a separate process in its own session, as a terminal
or a process manager does, then stops it at one of four moments:
- while it starts (0.25-1.5 s after the exec: importing rclpy and scipy, starting the worker,
  setting up the node);
- while a publisher sends it a recording;
- while a calibration runs in its worker (ransac_iterations 100000 makes one last seconds);
- idle, after a calibration answered.
Half of the cycles stop it with Ctrl-C (SIGINT to the process group, as a terminal sends it),
half with SIGTERM to the node alone (as systemd or `kill` do).

Counted per cycle: the exit code, tracebacks and warnings (a leaked semaphore, ...) on stderr,
the processes of the session still there 0.5 s after the node exited (the worker,
multiprocessing's resource tracker, zombies), and, when stopped while calibrating, whether the
pending ``~/calibrate`` call was answered (issue 28: "aborted: shutting down") by the time the
node had exited.

A last row sends Ctrl-C 0.05 s after the exec, before the interpreter has run any code of the
package (it is still importing site and the ROS wheels' .pth bootstrapper): what CPython does
there is outside the package's reach, and the row shows it.

Usage: python bench/node_lifecycle.py [--cycles 100] [--seed 0] [--early 10]
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import time

import common  # noqa: F401  (puts the repository on sys.path)
from common import emit, table
from live import Probe, start

MOMENTS = ('starting', 'receiving', 'calibrating', 'idle')


def session_processes(sid: int) -> list[str]:
    rows = subprocess.run(
        ['ps', '-eo', 'sid=,pid=,stat=,args='], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    # a zombie has ended: the resource tracker ends after the node, and this machine's PID 1
    # does not reap it (handeye_ros.ros.worker)
    return [r.strip() for r in rows if r.split()[0] == str(sid) and r.split()[2][0] != 'Z']


def cycle(probe: Probe, moment: str, how: str, rng: random.Random) -> dict:
    node = start('handeye_ros.ros.calibrator', '--ros-args', '-p', 'ransac_iterations:=100000')
    pub = None
    pending = None
    if moment == 'starting':
        time.sleep(rng.uniform(0.25, 1.5))
    elif moment == 'interpreter start':
        time.sleep(0.05)
    else:
        pub = start(
            'handeye_ros.ros.sim_publisher',
            '--duration',
            '20',
            '--rate',
            '3000',
            '--seed',
            str(rng.randrange(1000)),
            '--level',
            '2',
        )
        if moment == 'receiving':
            time.sleep(rng.uniform(1.5, 2.5))
        else:
            pub.wait(timeout=120)
            if moment == 'calibrating':
                probe.client.wait_for_service(timeout_sec=30.0)
                pending = probe.client.call_async(probe.Trigger.Request())
                time.sleep(rng.uniform(0.5, 1.5))
            else:
                probe.calibrate()
                time.sleep(0.2)
    t0 = time.perf_counter()
    if how == 'ctrl-c':
        os.killpg(node.pid, signal.SIGINT)
    else:
        node.send_signal(signal.SIGTERM)
    try:
        _, err = node.communicate(timeout=60)
        stop_s = time.perf_counter() - t0
    except subprocess.TimeoutExpired:
        os.killpg(node.pid, signal.SIGKILL)
        _, err = node.communicate()
        stop_s = float('inf')
    if pub is not None and pub.poll() is None:
        pub.kill()
        pub.wait()
    time.sleep(0.5)  # also: an answer sent just before the exit arrives (the probe spins)
    return {
        'rc': node.returncode,
        'tracebacks': err.count('Traceback'),
        # e.g. the resource tracker's "leaked semaphore objects": a stop that is not clean
        'warnings': err.count('Warning:'),
        'left': session_processes(node.pid),
        'stop_s': stop_s,
        'err': err,
        'pending': pending is not None,
        'answered': pending is not None and pending.done(),
        'answer': pending.result().message if pending is not None and pending.done() else '',
    }


def answered(rs: list[dict]) -> str:
    """'answered of pending' for the cycles that left a ~/calibrate call pending, with the
    answers given ('' when none was pending)."""
    pending = [r for r in rs if r['pending']]
    if not pending:
        return ''
    said = sorted({r['answer'] for r in pending if r['answered']})
    got = sum(r['answered'] for r in pending)
    return f'{got} of {len(pending)}' + (f' ({"; ".join(said)})' if said else '')


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--cycles', type=int, default=100)
    p.add_argument('--seed', type=int, default=0)
    p.add_argument(
        '--early', type=int, default=10, help='cycles stopped 0.05 s after the exec (the last row)'
    )
    args = p.parse_args()
    rng = random.Random(args.seed)
    probe = Probe()
    results: dict[tuple[str, str], list[dict]] = {}
    try:
        for k in range(args.cycles):
            how = ('ctrl-c', 'sigterm')[k % 2]
            moment = MOMENTS[(k // 2) % len(MOMENTS)]
            r = cycle(probe, moment, how, rng)
            results.setdefault((how, moment), []).append(r)
            if r['rc'] != 0 or r['tracebacks'] or r['warnings'] or r['left']:
                print(
                    f'cycle {k} ({how}, {moment}): rc {r["rc"]}, left {r["left"]}\n'
                    f'{r["err"][-2000:]}',
                    flush=True,
                )
        for _ in range(args.early):
            results.setdefault(('ctrl-c', 'interpreter start'), []).append(
                cycle(probe, 'interpreter start', 'ctrl-c', rng)
            )
    finally:
        probe.close()
    rows = []
    for (how, moment), rs in sorted(results.items()):
        rows.append(
            [
                how,
                moment,
                len(rs),
                sum(r['rc'] != 0 for r in rs),
                sum(r['tracebacks'] for r in rs),
                sum(r['warnings'] for r in rs),
                sum(len(r['left']) for r in rs),
                answered(rs),
                max(r['stop_s'] for r in rs),
            ]
        )
    total = [r for (_, m), rs in results.items() if m in MOMENTS for r in rs]
    rows.append(
        [
            'all four moments',
            '',
            len(total),
            sum(r['rc'] != 0 for r in total),
            sum(r['tracebacks'] for r in total),
            sum(r['warnings'] for r in total),
            sum(len(r['left']) for r in total),
            answered(total),
            max(r['stop_s'] for r in total),
        ]
    )
    emit(
        'node_lifecycle',
        table(
            f'Calibrator node: {args.cycles} start/stop cycles under real signals',
            [
                'signal',
                'stopped while',
                'cycles',
                'exit code != 0',
                'tracebacks',
                'warnings',
                'processes left',
                'pending call answered',
                'longest stop s',
            ],
            rows,
        ),
        seeds=args.seed,
    )


if __name__ == '__main__':
    main()
