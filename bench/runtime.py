"""Runtime and peak memory of the core on long recordings, one core.

For 1, 10 and 60 minutes of a 200 Hz hand and a 30 Hz eye (simulated, noise level 5), each in
a fresh child process pinned to one CPU with single-threaded BLAS: the time to read the two
TUM files, of time alignment, of the linear stage (association, keyframes, RANSAC) and of the
world alignment + metrics; the peak of numpy/Python allocations during calibrate()
(tracemalloc) and the process's peak resident memory.

``--joint`` also times the joint batch solve (control poses free) and reports the process's
peak resident memory right after it.

Usage: python bench/runtime.py [--minutes 1 10 60] [--joint]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import common
from common import emit, table

SINGLE_THREAD = {k: '1' for k in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS')}


def child(minutes: float, joint: bool = False) -> dict[str, float]:
    """Runs inside the pinned child process."""
    import resource
    import time
    import tracemalloc

    import numpy as np

    from handeye_ros.core.association import associate
    from handeye_ros.core.config import CalibrationConfig
    from handeye_ros.core.linear import build_motions, calibrate_linear
    from handeye_ros.core.pipeline import calibrate
    from handeye_ros.core.simulate import noise_level, simulate
    from handeye_ros.core.time_align import align_time
    from handeye_ros.core.world import align_worlds, evaluate
    from handeye_ros.formats import read_trajectory, write_tum

    noise_m, noise_deg = noise_level(5)
    rec = simulate(1, duration_s=minutes * 60, hand_rate_hz=200, eye_rate_hz=30,
                   noise_m=noise_m, noise_deg=noise_deg)
    out: dict[str, float] = {'hand_poses': len(rec.hand), 'eye_poses': len(rec.eye)}
    with tempfile.TemporaryDirectory() as tmp:
        h, e = Path(tmp) / 'h.txt', Path(tmp) / 'e.txt'
        write_tum(h, rec.hand)
        write_tum(e, rec.eye)
        t0 = time.perf_counter()
        hand, eye = read_trajectory(h), read_trajectory(e)
        out['read_s'] = time.perf_counter() - t0
    cfg = CalibrationConfig()
    t0 = time.perf_counter()
    ta = align_time(hand, eye)
    t1 = time.perf_counter()
    pairs = associate(hand, eye, ta.time_offset_s)
    lin = calibrate_linear(build_motions(pairs), rng=np.random.default_rng(cfg.seed))
    t2 = time.perf_counter()
    evaluate(pairs, lin.q_HE, lin.p_HE, align_worlds(pairs, lin.q_HE, lin.p_HE))
    t3 = time.perf_counter()
    out.update(time_align_s=t1 - t0, linear_s=t2 - t1, metrics_s=t3 - t2)
    from handeye_ros.core.batch import refine
    t0 = time.perf_counter()
    refine(hand, eye, ta.time_offset_s, lin.q_HE, lin.p_HE)
    out['batch_s'] = time.perf_counter() - t0
    if joint:
        t0 = time.perf_counter()
        sol = refine(hand, eye, ta.time_offset_s, lin.q_HE, lin.p_HE, joint=True)
        out['batch_joint_s'] = time.perf_counter() - t0
        out['joint_rss_mb'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        out['joint_iterations'] = sol.iterations
    t0 = time.perf_counter()
    res = calibrate(hand, eye, cfg)
    out['calibrate_s'] = time.perf_counter() - t0
    tracemalloc.start()  # a second run for the memory: tracing slows numpy down
    calibrate(hand, eye, cfg)
    out['calibrate_peak_mb'] = tracemalloc.get_traced_memory()[1] / 2 ** 20
    tracemalloc.stop()
    out['max_rss_mb'] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out['dt_err_ms'] = abs(res.time_offset_s - rec.truth.time_offset_s) * 1e3
    out['motions'] = lin.n_motions
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--minutes', type=float, nargs='+', default=[1, 10, 60])
    p.add_argument('--joint', action='store_true', help='also time the joint batch solve')
    p.add_argument('--child', type=float, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child is not None:
        os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})
        print(json.dumps(child(args.child, args.joint)))
        return
    rows = []
    for minutes in args.minutes:
        env = dict(os.environ, **SINGLE_THREAD,
                   PYTHONPATH=str(common.ROOT) + os.pathsep + os.environ.get('PYTHONPATH', ''))
        cmd = [sys.executable, __file__, '--child', str(minutes)] + ['--joint'] * args.joint
        proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
        r = json.loads(proc.stdout.strip().splitlines()[-1])
        rows.append([f'{minutes:g}', f'{r["hand_poses"]:.0f} + {r["eye_poses"]:.0f}',
                     r['read_s'], r['time_align_s'], r['linear_s'],
                     r['time_align_s'] + r['linear_s'], r['batch_s'], r['metrics_s'],
                     r['calibrate_s'],
                     r['calibrate_peak_mb'], r['max_rss_mb'], f'{r["motions"]:.0f}']
                    + ([r['batch_joint_s'], r['joint_rss_mb']] if args.joint else []))
    emit('runtime', table(
        'Runtime on one core (200 Hz hand + 30 Hz eye, noise level 5); targets for 10 min: time '
        'alignment + linear < 1 s, batch < 10 s and < 2 GB',
        ['minutes', 'poses', 'read files s', 'time align s', 'linear s', 'align+linear s',
         'batch s', 'world+metrics s', 'calibrate() s (all stages)', 'calibrate peak MB',
         'max RSS MB', 'motions'] + (['joint batch s', 'RSS after joint MB'] if args.joint else []),
        rows))


if __name__ == '__main__':
    main()
