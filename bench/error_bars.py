"""The APE/RPE's error bars from the calibration (issue 45, item 3) against the truth.

For simulated recordings (the paper's protocol: noise levels 2, 5 and 8, 60 s, eye 20 Hz; and at
level 5, 10 minutes at 200 Hz + 30 Hz for the cost), each figure of the evaluation (APE and RPE,
translation and rotation, RMSE) is computed with the calibration found and with the true one
(dt, T_HE; the world T_WG fitted for each as the calibration fits it), on the same eye poses.
The figure: how often the true calibration's figure lies within 3 of the reported calibration
sigmas of the reported figure (target: >= 90 % of seeds), and the root-mean-square of that
difference over its sigma (1 when the sigmas are right). The cost: the error bars' seconds
beside the calibration's, one core.

Usage: python bench/error_bars.py [--seeds N]
"""

from __future__ import annotations

import argparse
import time

import cases
import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
from common import emit, table

from handeye_ros.core.pipeline import calibrate
from handeye_ros.evaluation import error_bars
from handeye_ros.evaluation.metrics import POSE_ERRORS

LEVELS = (2, 5, 8)


def case(rec) -> tuple[np.ndarray, float, float]:
    """(per figure: (true-calibration figure - reported) / its sigma; calibration s; bars s)."""
    t0 = time.process_time()
    res = calibrate(rec.hand, rec.eye)
    t1 = time.process_time()
    bars, why = error_bars.calibration_sigmas(res, 1.0, 1.0)
    t2 = time.process_time()
    assert bars is not None, why
    t = rec.truth
    moved = error_bars.figures_at(res, t.time_offset_s, t.q_HE, t.p_HE)
    assert moved is not None
    z = np.array([moved[n]['rmse'] / bars.sigmas[n]['rmse'] for n in POSE_ERRORS])
    return z, t1 - t0, t2 - t1


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--seeds', type=int, default=20, help='simulations a level (default 20)')
    a = p.parse_args()
    rows = []
    for level in LEVELS:
        zs, costs = [], []
        for k in range(a.seeds):
            z, c_cal, c_bars = case(cases.protocol(level, k))
            zs.append(z)
            costs.append((c_cal, c_bars))
        zs, costs = np.array(zs), np.array(costs)
        rows.append(
            [
                f'{level} (60 s, 100 + 20 Hz)',
                a.seeds,
                ' '.join(f'{v:.0%}' for v in np.mean(np.abs(zs) <= 3.0, 0)),
                ' '.join(f'{v:.2f}' for v in np.sqrt(np.mean(zs**2, 0))),
                f'{np.median(costs[:, 0]):.2f} / {np.median(costs[:, 1]):.2f}',
            ]
        )
        print(rows[-1], flush=True)
    rec = cases.recording(1, 5, duration_s=600.0, hand_rate_hz=200.0, eye_rate_hz=30.0)
    z, c_cal, c_bars = case(rec)
    rows.append(
        [
            '5 (600 s, 200 + 30 Hz)',
            1,
            ' '.join(f'{v:.0f}' for v in np.abs(z) <= 3),
            ' '.join(f'{v:.2f}' for v in np.abs(z)),
            f'{c_cal:.2f} / {c_bars:.2f}',
        ]
    )
    emit(
        'error_bars',
        table(
            'The evaluation with the true calibration against the reported one, over the '
            f'calibration 1-sigma of each figure ({error_bars.DRAWS} draws; RMSE of APE '
            'translation, rotation, RPE per 1 s, per 1 m)',
            [
                'level',
                'seeds',
                'within 3 sigma',
                'rms (true - reported) / sigma',
                'CPU s: calibration / error bars (median)',
            ],
            rows,
        ),
        seeds=f'protocol_seed(level, 0..{a.seeds - 1}); 600-s case seed 1',
    )


if __name__ == '__main__':
    main()
