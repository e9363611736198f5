"""Issue 12's figures: many recordings on Dask, the report's cost, and evo against our APE.

1. ``--runs`` simulated recordings of ``--seconds`` each (the paper's protocol: MoCap 100 Hz,
   VIO 20 Hz at noise level 5, seeds 1000 + k) written as TUM files with a manifest, then
   ``python -m handeye_ros.evaluate`` run as a user runs it, with single-threaded BLAS:
   sequentially in one process, and on a LocalCluster of ``--workers`` workers. Figures: the
   speed-up of the whole command's wall time and of its runs phase (``-v`` timings); the
   scheduler overhead, the runs phase less the runs' own seconds / workers, as a share of
   those seconds (it holds the per-task scheduling, the workers' first imports and the idle
   tail; the cluster's start and stop are shown apart); each worker's resident memory after
   its first and its last runs. Beside them, the machine's own ceiling: the throughput of
   ``--workers`` processes running the same vectorised numpy kernel at once against one alone
   (on a VM whose vCPUs share a core's vector units or memory bandwidth it is well below
   ``--workers``, and no scheduler can beat it).
2. The report of a ``--report-minutes`` recording at 1 kHz + 200 Hz: the time of the evaluation,
   exports and report beyond the calibration itself.
3. evo_ape on that recording's exports against our APE, and on the 12 real pairs of
   ../shared/data/real (bench/cases.py: EuRoC ground truth moved to the Vicon marker frame
   and 0.1 s onto another clock, real VIO estimates), with our APE with and without the
   calibration.

Usage: python bench/evaluate.py [--runs 100] [--seconds 60] [--workers 2] [--report-minutes 10]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np
from common import ROOT, emit, table

SINGLE_THREAD = {k: '1' for k in ('OMP_NUM_THREADS', 'OPENBLAS_NUM_THREADS', 'MKL_NUM_THREADS')}
SEED0 = 1000


def _env() -> dict[str, str]:
    return dict(
        os.environ,
        PYTHONPATH=str(ROOT),
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        **SINGLE_THREAD,
    )


def write_runs(folder: Path, n: int, seconds: float) -> Path:
    from handeye_ros.core.simulate import noise_level, simulate
    from handeye_ros.formats import write_tum

    nm, nd = noise_level(5.0)
    runs = []
    for k in range(n):
        rec = simulate(SEED0 + k, duration_s=seconds, noise_m=nm, noise_deg=nd)
        h, e = folder / f'h{k:03d}.txt', folder / f'e{k:03d}.txt'
        write_tum(h, rec.hand)
        write_tum(e, rec.eye)
        runs.append(
            {
                'algorithm': f'alg{k % 4}',
                'sequence': f'seq{k % 5}',
                'trial': k,
                'hand': h.name,
                'eye': e.name,
            }
        )
    import yaml

    path = folder / 'manifest.yaml'
    path.write_text(yaml.safe_dump({'runs': runs}))
    return path


def evaluate(manifest: Path, out: Path, *extra: str) -> tuple[float, dict, list[dict]]:
    """Wall time, the -v phase timings and the rows of one evaluate command."""
    t0 = time.perf_counter()
    proc = subprocess.run(
        [
            sys.executable,
            '-m',
            'handeye_ros.evaluate',
            str(manifest),
            '-o',
            str(out),
            '--no-cache',
            '--no-progress',
            '-v',
            *extra,
        ],
        env=_env(),
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f'evaluate failed ({proc.returncode}): {proc.stderr[-2000:]}')
    phases = {
        m.group(1): float(m.group(2))
        for m in re.finditer(r'timing: ([a-z ]+?) ([\d.]+) s', proc.stderr)
    }
    with (out / 'results.csv').open() as f:
        return wall, phases, list(csv.DictReader(f))


KERNEL = """
import time, numpy as np
a = np.random.default_rng(0).random((2000, 3, 3)); b = np.random.default_rng(1).random((2000, 3, 3))
t = time.perf_counter()
for _ in range(2000):
    c = np.matmul(a, b); d = np.sin(c).sum()
print(time.perf_counter() - t)
"""


def ceiling(workers: int) -> float:
    """Throughput of ``workers`` concurrent numpy processes over one alone (the kernel above,
    single-threaded BLAS), best of three."""

    def batch(n: int) -> float:
        t0 = time.perf_counter()
        procs = [
            subprocess.Popen([sys.executable, '-c', KERNEL], env=_env(), stdout=subprocess.DEVNULL)
            for _ in range(n)
        ]
        for p in procs:
            p.wait()
        return time.perf_counter() - t0

    one = min(batch(1) for _ in range(3))
    many_ = min(batch(workers) for _ in range(3))
    return workers * one / many_


def many(args: argparse.Namespace, tmp: Path) -> None:
    manifest = write_runs(tmp, args.runs, args.seconds)
    seq_wall, seq_ph, seq_rows = evaluate(manifest, tmp / 'seq', '--sequential')
    par_wall, par_ph, par_rows = evaluate(manifest, tmp / 'par', '--workers', str(args.workers))
    seq_work = sum(float(r['seconds']) for r in seq_rows)
    par_work = sum(float(r['seconds']) for r in par_rows)
    overhead = (par_ph['runs'] - par_work / args.workers) / (par_work / args.workers)
    rows = [
        (
            'sequential (one process)',
            f'{seq_wall:.1f}',
            f'{seq_ph["runs"]:.1f}',
            '',
            f'{seq_work:.1f}',
            '',
            '',
            '',
        ),
        (
            f'LocalCluster, {args.workers} workers',
            f'{par_wall:.1f}',
            f'{par_ph["runs"]:.1f}',
            f'{par_ph["cluster start"] + par_ph["cluster stop"]:.1f}',
            f'{par_work:.1f}',
            f'{seq_wall / par_wall:.2f}x',
            f'{seq_ph["runs"] / par_ph["runs"]:.2f}x',
            f'{overhead * 100:.1f} %',
        ),
    ]
    text = table(
        f'{args.runs} simulated {args.seconds:g}-s runs (100 Hz + 20 Hz, level 5)',
        (
            'how',
            'wall s',
            'runs phase s',
            'cluster start+stop s',
            'sum of runs s',
            'speed-up (wall)',
            'speed-up (runs)',
            'scheduler overhead',
        ),
        rows,
    )
    by_pid: dict[str, list[float]] = {}
    for r in sorted(par_rows, key=lambda r: int(r['trial'])):
        by_pid.setdefault(r['pid'], []).append(float(r['rss_mb']))
    mem = [
        (pid, len(v), f'{np.mean(v[:5]):.0f}', f'{np.mean(v[-5:]):.0f}', f'{max(v):.0f}')
        for pid, v in by_pid.items()
    ]
    text += '\n\n' + table(
        'worker resident memory after each run (MB)',
        ('worker pid', 'runs', 'first 5', 'last 5', 'max'),
        mem,
    )
    text += '\n\nstatus: ' + ', '.join(
        f'{s} {sum(r["status"] == s for r in par_rows)}' for s in ('ok', 'failed')
    )
    limit = ceiling(args.workers)
    text += (
        f'\n\nmachine ceiling: {args.workers} processes of a vectorised numpy kernel run '
        f'{limit:.2f}x as fast as one (the most any scheduler can reach here)'
    )
    emit('evaluate_many', text, seeds=f'{SEED0}..{SEED0 + args.runs - 1}')


def report(args: argparse.Namespace, tmp: Path) -> None:
    from handeye_ros.core.pipeline import calibrate
    from handeye_ros.core.simulate import noise_level, simulate
    from handeye_ros.evaluation.outputs import evaluate_and_write

    nm, nd = noise_level(5.0)
    seed = 7
    rec = simulate(
        seed,
        duration_s=args.report_minutes * 60.0,
        hand_rate_hz=1000.0,
        eye_rate_hz=200.0,
        noise_m=nm,
        noise_deg=nd,
    )
    t0 = time.perf_counter()
    result = calibrate(rec.hand, rec.eye)
    t_cal = time.perf_counter() - t0
    out = result.to_dict()
    t0 = time.perf_counter()
    evaluate_and_write(result, {**out}, delta_s=1.0, delta_m=1.0)
    t_eval = time.perf_counter() - t0
    t0 = time.perf_counter()
    evaluate_and_write(result, out, export_dir=tmp / 'export', report_dir=tmp / 'report')
    t_all = time.perf_counter() - t0
    ours = out['evaluation']['calibrated']['ape_translation']
    evo = evo_ape(tmp / 'export', tmp / 'home')
    rows = [
        ('calibration (not counted)', f'{t_cal:.1f}'),
        ('evaluation: APE/RPE with and without the calibration', f'{t_eval:.2f}'),
        ('evaluation + exports + report (5 PNGs, report.html)', f'{t_all:.2f}'),
    ]
    text = table(
        f'report of a {args.report_minutes:g}-minute recording (1 kHz + 200 Hz, '
        f'{len(rec.eye)} eye poses)',
        ('step', 'seconds'),
        rows,
    )
    diff = [
        (k, f'{ours[k] * 1e3:.6f}', f'{evo[k] * 1e3:.6f}', f'{abs(ours[k] - evo[k]) * 1e3:.2e}')
        for k in ('rmse', 'mean', 'median', 'max')
    ]
    text += '\n\n' + table(
        'evo_ape on our exports against our APE (mm)',
        ('statistic', 'ours', 'evo', '|difference|'),
        diff,
    )
    emit('evaluate_report', text, seeds=seed)


def evo_ape(export: Path, home: Path) -> dict:
    home.mkdir(exist_ok=True)
    zip_path = export / 'ape.zip'
    subprocess.run(
        [
            str(Path(sys.executable).parent / 'evo_ape'),
            'tum',
            str(export / 'groundtruth.tum'),
            str(export / 'estimate.tum'),
            '--save_results',
            str(zip_path),
            '--no_warnings',
        ],
        env=dict(_env(), HOME=str(home), MPLBACKEND='Agg'),
        check=True,
        capture_output=True,
    )
    with zipfile.ZipFile(zip_path) as z:
        return json.loads(z.read('stats.json'))


def real(tmp: Path) -> None:
    import cases

    from handeye_ros.core.pipeline import calibrate
    from handeye_ros.evaluation.outputs import evaluate_and_write

    if not cases.available():
        print('real data not present: skipped')
        return
    shift = 0.1
    rows = []
    for k, pair in enumerate(cases.PAIRS):
        gt, est = cases.load(pair)
        result = calibrate(cases.to_marker_frame(gt, shift), est)
        out = result.to_dict()
        export = tmp / f'real{k}'
        evaluate_and_write(result, out, export_dir=export)
        evo = evo_ape(export, tmp / 'home')
        ev = out['evaluation']
        base = ev['uncalibrated']
        rows.append(
            (
                pair.name,
                out['quality']['verdict'],
                f'{ev["calibrated"]["ape_translation"]["rmse"] * 1e3:.2f}',
                f'{abs(evo["rmse"] - ev["calibrated"]["ape_translation"]["rmse"]) * 1e3:.1e}',
                f'{ev["calibrated"]["ape_rotation"]["rmse"]:.2f}',
                f'{ev["calibrated"]["rpe_time_translation"]["rmse"] * 1e3:.1f}',
                'n/a' if base is None else f'{base["ape_translation"]["rmse"] * 1e3:.1f}',
                'n/a' if base is None else f'{base["ape_rotation"]["rmse"]:.1f}',
                'n/a' if base is None else f'{base["rpe_time_translation"]["rmse"] * 1e3:.1f}',
            )
        )
    text = table(
        f'real pairs (hand in the marker frame, clocks {shift:g} s apart): APE/RPE RMSE '
        'with our calibration, and as a user would align today (dt = 0, SE(3) '
        'Umeyama, no T_HE)',
        (
            'pair',
            'verdict',
            'APE mm',
            '|evo - ours| mm',
            'APE deg',
            'RPE 1 s mm',
            'without: APE mm',
            'APE deg',
            'RPE 1 s mm',
        ),
        rows,
    )
    emit('evaluate_real', text, seeds='none (real data)')


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--runs', type=int, default=100)
    p.add_argument('--seconds', type=float, default=60.0)
    p.add_argument('--workers', type=int, default=2)
    p.add_argument('--report-minutes', type=float, default=10.0)
    p.add_argument('--skip-many', action='store_true')
    p.add_argument('--only-real', action='store_true')
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if not args.only_real:
            if not args.skip_many:
                many(args, Path(tmp))
            report(args, Path(tmp))
        real(Path(tmp))


if __name__ == '__main__':
    main()
