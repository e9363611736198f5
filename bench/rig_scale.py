"""One rig of many recordings on the LocalCluster (issue 36): time and memory against the count.

``--runs`` simulated recordings of 2 minutes (MoCap 100 Hz, VIO 20 Hz, noise level 5, one
marker, each its own clock and world; seeds 5000 + k) written as TUM files once; manifests of
the first 25, 50, ... of them; ``evaluate MANIFEST --shared-extrinsic --workers 2`` run as a
user runs it, with single-threaded BLAS. Figures: the whole command's wall time and its time per
recording (linear in the count when it stays flat), the peak resident memory of the calling
process (it holds each recording's small summary and result dictionary, never its poses: flat
when it holds no poses), the rig's verdict and how many recordings it used.

Usage: python bench/rig_scale.py [--runs 100] [--workers 2]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
import yaml
from common import ROOT, emit, table

from handeye_ros.core.simulate import noise_level, random_truth, simulate
from handeye_ros.formats import write_tum

#: Runs evaluate's main and prints the calling process's own peak RSS (kB) at its end.
WRAPPER = (
    'import resource, sys; from handeye_ros.app.evaluate import main; code = main(sys.argv[1:]); '
    'print("PEAK_KB", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss); sys.exit(code)'
)


def write_rig(folder: Path, n: int) -> list[dict]:
    base = random_truth(np.random.default_rng(5000))
    nm, nd = noise_level(5.0)
    runs = []
    for k in range(n):
        truth = replace(
            random_truth(np.random.default_rng([5000, k])), q_HE=base.q_HE, p_HE=base.p_HE
        )
        rec = simulate(5000 + k, duration_s=120.0, noise_m=nm, noise_deg=nd, truth=truth)
        write_tum(folder / f'hand{k}.txt', rec.hand)
        write_tum(folder / f'eye{k}.txt', rec.eye)
        runs.append({'name': f'rec{k:03d}', 'hand': f'hand{k}.txt', 'eye': f'eye{k}.txt'})
    return runs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--runs', type=int, default=100)
    ap.add_argument('--workers', type=int, default=2)
    args = ap.parse_args()
    counts = sorted({c for c in (25, 50, args.runs) if c <= args.runs})
    env = dict(
        os.environ,
        PYTHONPATH=str(ROOT),
        OMP_NUM_THREADS='1',
        OPENBLAS_NUM_THREADS='1',
        MKL_NUM_THREADS='1',
    )
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        runs = write_rig(folder, args.runs)
        for n in counts:
            manifest = folder / f'rig{n}.yaml'
            manifest.write_text(yaml.safe_dump({'runs': runs[:n]}))
            out = folder / f'out{n}'
            t0 = time.perf_counter()
            proc = subprocess.run(
                [
                    sys.executable,
                    '-c',
                    WRAPPER,
                    str(manifest),
                    '-o',
                    str(out),
                    '--shared-extrinsic',
                    '--workers',
                    str(args.workers),
                ],
                capture_output=True,
                text=True,
                env=env,
                check=False,
            )
            wall = time.perf_counter() - t0
            peak = next(
                (
                    int(line.split()[1])
                    for line in proc.stdout.splitlines()
                    if line.startswith('PEAK_KB')
                ),
                None,
            )
            rig = yaml.safe_load((out / 'rig.yaml').read_text())['rig']
            rows.append(
                [
                    n,
                    wall,
                    wall / n,
                    None if peak is None else peak / 1024,
                    rig['quality']['verdict'],
                    len(rig['used']),
                    proc.returncode,
                ]
            )
    emit(
        'rig_scale',
        table(
            f'One rig on a LocalCluster of {args.workers} workers: recordings of 2 min '
            '(100 Hz + 20 Hz)',
            (
                'recordings',
                'wall s',
                's per recording',
                'caller peak MB',
                'verdict',
                'used',
                'exit',
            ),
            rows,
        ),
        seeds='5000 + k',
    )


if __name__ == '__main__':
    main()
