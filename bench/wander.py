"""The correlated term of the uncertainty against a known truth (issue 45, item 1): simulations
whose time offset wanders along the recording (``simulate(wander_s=...)``: a latency that changes
with the VIO's load; the truth is its mean over the recording), at the paper's noise levels.

Per level and wander: how often the truth lies within the reported 3-sigma (dt; the translation
and the rotation by their chi^2_3 99.73 % Mahalanobis distance), the root-mean-square of the dt
error over its 1-sigma, the median reported dt 1-sigma, and how often the result notes that the
offset varies along the recording.

Usage: python bench/wander.py [--seeds N]
"""

from __future__ import annotations

import argparse

import cases
import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
from common import covered, emit, table

from handeye_ros.core.pipeline import calibrate

LEVELS = (2, 5)
WANDERS_MS = (0.0, 1.0, 3.0, 10.0)
DURATION_S = 60.0


def rows(seeds: int) -> list[list]:
    out = []
    for level in LEVELS:
        for wander in WANDERS_MS:
            now, z_now, sd, noted = [], [], [], 0
            for k in range(seeds):
                rec = cases.protocol(level, k, duration_s=DURATION_S, wander_s=wander * 1e-3)
                r = calibrate(rec.hand, rec.eye)
                u = r.batch.uncertainty
                now.append(covered(r, rec.truth))
                z_now.append(
                    (r.time_offset_s - rec.truth.time_offset_s) / np.sqrt(u.covariance[0, 0])
                )
                sd.append(np.sqrt(u.covariance[0, 0]))
                noted += 'time_offset' in u.varies
            out.append(
                [
                    level,
                    f'{wander:g}',
                    seeds,
                    ' '.join(f'{v:.0%}' for v in np.mean(now, 0)),
                    f'{np.sqrt(np.mean(np.square(z_now))):.2f}',
                    f'{np.median(sd) * 1e3:.3f}',
                    f'{noted}/{seeds}',
                ]
            )
            print(out[-1], flush=True)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--seeds', type=int, default=20, help='simulations a case (default 20)')
    a = p.parse_args()
    emit(
        'wander',
        table(
            f'A time offset that wanders along {DURATION_S:.0f}-s recordings (rms, ms; the truth '
            'its mean): truth within 3 sigma (dt t r), rms of dt error / sigma, median dt sigma, '
            'results that note it varies',
            [
                'level',
                'wander ms',
                'seeds',
                'within 3 sigma',
                'rms z dt',
                'dt sigma ms',
                'noted',
            ],
            rows(a.seeds),
        ),
        seeds=a.seeds,
    )


if __name__ == '__main__':
    main()
