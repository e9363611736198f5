"""Runtime and peak memory of the whole offline run on long recordings, one core.

For 1 to 60 minutes of a 1 kHz hand and a 200 Hz eye (simulated, noise level 5; issue 11's
figure: an hour in under 60 s and 2 GB), the two TUM files are written once, then
``python -m handeye_ros.offline --hand H --eye E -o result.yaml`` runs in a fresh process
pinned to one CPU with single-threaded BLAS, as a user would run it: its wall time, its peak
resident memory (the kernel's ru_maxrss of the child), and the stage times it logs with -v.
Each length runs --repeat times (the table shows the median run and the range). The table
and a log-log plot of time and memory against the length (bench/out/runtime.png)
show how both grow.

``--motion random loops`` runs each length on both motions and gives each one's time against
the first's, measured in the same run (issue 47's figure: <= 1.3). ``--keyframes HZ`` thins
the eye to keyframes at HZ (a keyframe-only eye, stage 1 from keyframe pairs).

Usage: python bench/runtime.py [--minutes 1 5 10 30 60] [--hand-rate 1000] [--eye-rate 200]
       [--repeat 3] [--motion random loops] [--keyframes HZ] [--options --clock-drift ...]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import common
from common import emit, save_plot, table

SINGLE_THREAD = {k: '1' for k in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS')}
SEED = 1
STAGES = re.compile(
    r'stage 1 \+ conventions ([\d.]+) s, stage 2 \+ checks ([\d.]+) s, '
    r'batch ([\d.]+) s'
)


def write_recording(
    folder: Path,
    minutes: float,
    hand_hz: float,
    eye_hz: float,
    motion: str = 'random',
    keyframes_hz: float | None = None,
) -> tuple[int, int]:
    """Simulate and write h.txt / e.txt (TUM), the eye thinned to every pose ``keyframes_hz``
    apart when given (a keyframe-only eye); returns the pose counts."""
    import numpy as np

    from handeye_ros.core.simulate import noise_level, simulate
    from handeye_ros.formats import write_tum

    noise_m, noise_deg = noise_level(5)
    rec = simulate(
        SEED,
        duration_s=minutes * 60,
        hand_rate_hz=hand_hz,
        eye_rate_hz=eye_hz,
        noise_m=noise_m,
        noise_deg=noise_deg,
        motion=motion,
    )
    eye = rec.eye
    if keyframes_hz:
        eye = eye.select(np.unique(np.arange(0, len(eye), eye_hz / keyframes_hz).astype(int)))
    write_tum(folder / 'h.txt', rec.hand)
    write_tum(folder / 'e.txt', eye)
    return len(rec.hand), len(eye)


def pin_one_core() -> None:
    os.sched_setaffinity(0, {min(os.sched_getaffinity(0))})


def run_offline(folder: Path, options: list[str]) -> dict[str, float]:
    """The offline tool on the files, in a pinned child; wall time, peak RSS, stage times."""
    env = dict(
        os.environ,
        **SINGLE_THREAD,
        PYTHONPATH=str(common.ROOT) + os.pathsep + os.environ.get('PYTHONPATH', ''),
    )
    cmd = [
        sys.executable,
        '-m',
        'handeye_ros.offline',
        '--hand',
        str(folder / 'h.txt'),
        '--eye',
        str(folder / 'e.txt'),
        '-o',
        str(folder / 'result.yaml'),
        '-v',
        '--no-progress',
        *options,
    ]
    with tempfile.TemporaryFile('w+') as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            cmd,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=err,
            preexec_fn=pin_one_core,  # noqa: PLW1509 (the bench starts no threads)
        )
        # wait4: this child's own peak RSS (RUSAGE_CHILDREN would hold the largest of all)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        stderr = err.read()
    if proc.returncode not in (0, 2):
        raise RuntimeError(stderr[-2000:])
    m = STAGES.search(stderr)
    stage = [float(v) for v in m.groups()] if m else [float('nan')] * 3
    return {
        'wall_s': wall,
        'rss_mb': usage.ru_maxrss / 1024,
        'stage1_s': stage[0],
        'stage2_s': stage[1],
        'batch_s': stage[2],
    }


def _measure(
    minutes: float, motion: str, args: argparse.Namespace
) -> tuple[dict[str, float], list[dict[str, float]], int, int, float]:
    """One recording written and run --repeat times: the median run, all runs by wall time,
    the pose counts and the files' size (MB)."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        n_h, n_e = write_recording(
            folder, minutes, args.hand_rate, args.eye_rate, motion, args.keyframes
        )
        size = sum(f.stat().st_size for f in folder.iterdir()) / 2**20
        runs = sorted(
            (run_offline(folder, args.options) for _ in range(max(args.repeat, 1))),
            key=lambda run: run['wall_s'],
        )
    return runs[len(runs) // 2], runs, n_h, n_e, size


def _output_name(args: argparse.Namespace) -> str:
    """bench/out's name of the table: runtime, or runtime_motions (with the rates where they
    are not the default 1 kHz + 200 Hz) when more motions than the default run."""
    if args.keyframes:
        return f'runtime_keyframes_{args.hand_rate:g}_{args.keyframes:g}'
    if args.motion == ['random']:
        return 'runtime'
    rates = (args.hand_rate, args.eye_rate)
    return 'runtime_motions' + ('' if rates == (1000.0, 200.0) else f'_{rates[0]:g}_{rates[1]:g}')


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--minutes', type=float, nargs='+', default=[1, 5, 10, 30, 60])
    p.add_argument('--hand-rate', type=float, default=1000.0)
    p.add_argument('--eye-rate', type=float, default=200.0)
    p.add_argument(
        '--repeat',
        type=int,
        default=3,
        help='runs per length: the table gives the median run (by wall time) and '
        'the range of the wall times (the machine is shared; one run can be '
        'some 10 %% off)',
    )
    p.add_argument(
        '--motion',
        nargs='+',
        default=['random'],
        help="the simulation's motions (handeye_ros.core.simulate.MOTIONS), each at each "
        "length: 'loops' repeats a 3-minute lap, so that the correlation has runner-ups a lap "
        'away (issue 47: each costs stage 2 on a bounded excerpt)',
    )
    p.add_argument(
        '--keyframes',
        type=float,
        default=None,
        metavar='HZ',
        help='thin the eye to keyframes at this rate (a keyframe-only eye: stage 1 from the '
        "keyframe pairs' rotation angles, core/time/keyframe_only.py)",
    )
    p.add_argument(
        '--options',
        nargs=argparse.REMAINDER,
        default=[],
        help='further offline_calibrate options (e.g. --clock-drift)',
    )
    args = p.parse_args()
    rows, points, first = [], [], {}
    for minutes in sorted(args.minutes):
        for motion in args.motion:
            r, runs, n_h, n_e, size = _measure(minutes, motion, args)
            first.setdefault(minutes, r['wall_s'])
            if motion == args.motion[0]:
                points.append((minutes, r['wall_s'], r['rss_mb']))
            rows.append(
                [
                    f'{minutes:g}',
                    motion,
                    f'{n_h} + {n_e}',
                    size,
                    r['wall_s'],
                    f'{runs[0]["wall_s"]:.1f}-{runs[-1]["wall_s"]:.1f}',
                    r['wall_s'] / first[minutes],
                    r['stage1_s'],
                    r['stage2_s'],
                    r['batch_s'],
                    r['wall_s'] - r['stage1_s'] - r['stage2_s'] - r['batch_s'],
                    r['rss_mb'],
                ]
            )
            print(rows[-1], flush=True)
    opts = ' '.join(args.options) or 'defaults'
    emit(
        _output_name(args),
        table(
            f'Whole offline run on one core ({args.hand_rate:g} Hz hand + {args.eye_rate:g} Hz eye'
            + (f' thinned to {args.keyframes:g} Hz keyframes' if args.keyframes else '')
            + f', TUM files, noise level 5, {opts}); target for 60 min: < 60 s and < 2 GB',
            [
                'minutes',
                'motion',
                'poses',
                'files MB',
                'offline run s (median)',
                f'range of {args.repeat}',
                f'vs {args.motion[0]}',
                'stage 1 + conventions s',
                'stage 2 + checks s',
                'batch s',
                'reading, metrics, writing s',
                'peak RSS MB',
            ],
            rows,
        ),
        SEED,
    )
    plt = common.pyplot()
    if plt is not None and len(points) > 1 and args.motion == ['random']:
        fig, ax = plt.subplots(figsize=(6, 4))
        m = [q[0] for q in points]
        ax.loglog(m, [q[1] for q in points], 'o-', label='time (s)')
        ax.loglog(m, [q[2] for q in points], 's-', label='peak RSS (MB)')
        ax.loglog(
            m, [points[0][1] * x / m[0] for x in m], ':', color='grey', label='linear in length'
        )
        ax.axhline(60, color='C0', lw=0.5)
        ax.axhline(2048, color='C1', lw=0.5)
        ax.set_xlabel('recording length (minutes)')
        ax.set_title(f'offline run, {args.hand_rate:g} Hz + {args.eye_rate:g} Hz, one core')
        ax.legend()
        save_plot(fig, 'runtime')


if __name__ == '__main__':
    main()
