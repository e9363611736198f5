"""The drift fitted in the default run when the offset along the recording clearly drifts
(auto_drift): how often it is fitted on constant clocks (target: in at most 1 % of seeds), how
often on drifting ones, and the offset's error either way.

Simulated recordings (hand 100 Hz, eye 20 Hz), the default options; the offset error is taken
at the result's reference stamp (the truth's linear clock there).

Usage: python bench/auto_drift.py [--seeds N]
"""

from __future__ import annotations

import argparse

import cases
import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
from common import emit, table

from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.pipeline import calibrate

#: (duration s, noise level, drift s/s): constant clocks on the paper's protocol and longer,
#: then clocks drifting by a crystal's typical tens of ppm.
CASES = (
    (60.0, 2.0, 0.0),
    (60.0, 5.0, 0.0),
    (60.0, 10.0, 0.0),
    (300.0, 5.0, 0.0),
    (300.0, 5.0, 20e-6),
    (300.0, 5.0, 50e-6),
)


def run_case(duration_s: float, level: float, drift: float, seeds: int) -> list:
    fitted, errors, refused = 0, [], 0
    for k in range(seeds):
        rec = cases.recording(5000 + k, level, duration_s=duration_s, clock_drift=drift)
        try:
            res = calibrate(rec.hand, rec.eye)
        except HandeyeError:
            refused += 1
            continue
        fitted += res.clock_drift is not None
        stamp = res.to_dict().get('time_offset_stamp_ns') or rec.truth.time_offset_stamp_ns
        errors.append(abs(res.time_offset_s - float(rec.truth.time_offset_at(stamp))) * 1e3)
    n = seeds - refused
    e = np.array(errors)
    return [
        f'{duration_s:.0f}',
        f'{level:g}',
        f'{drift * 1e6:g}',
        n,
        f'{fitted} ({fitted / max(n, 1):.0%})',
        f'{np.mean(e):.2f}',
        f'{np.max(e):.2f}',
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--seeds', type=int, default=100)
    a = ap.parse_args()
    rows = [run_case(*case, seeds=a.seeds if case[0] < 100 else a.seeds // 2) for case in CASES]
    header = ['duration s', 'level', 'drift ppm', 'runs', 'drift fitted', 'dt err ms', 'max']
    emit(
        'auto_drift',
        table('auto_drift: the drift fitted by the default run', header, rows),
        seeds=f'simulator seeds 5000..5000+N-1 (N = {a.seeds}, half at 300 s)',
    )


if __name__ == '__main__':
    main()
