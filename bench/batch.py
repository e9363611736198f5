"""The batch stage against the linear stage on the paper's protocol, and its uncertainty.

For each noise level, 20 seeds: the errors of the linear result (stage 1 offset + stage 2
extrinsic) and of the batch refinement, and whether the truth lies inside the reported
3-sigma: |dt error| <= 3 sigma_dt, and for translation and rotation the Mahalanobis distance
of the 3-vector error within the 99.73 % quantile of chi2(3) (14.16), the 3-sigma of a
3-vector. Every (level, seed) is its own recording (seed 1000 * level + s): the same seed at
two levels would be the same noise draw scaled, and its coverage the same event counted twice.

``--hand-noise`` gives the MoCap white noise per axis (m and rad; the paper's protocol has
none).

Usage: python bench/batch.py [--seeds 20] [--levels 0 1 ... 10] [--hand-noise 1e-4]
"""

from __future__ import annotations

import argparse
import time

import cases
import common  # noqa: F401
import numpy as np
from common import covered, emit, pyplot, save_plot, table

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import calibration_error


def recording(level: float, seed: int, hand_noise: float):
    """The paper protocol at ``level``, its own draw per (level, seed), MoCap noise per axis
    ``hand_noise`` (m and rad)."""
    return cases.protocol(
        level,
        seed,
        hand_noise_m=hand_noise,
        hand_noise_deg=float(np.degrees(hand_noise)),
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--seeds', type=int, default=20)
    p.add_argument('--levels', type=float, nargs='+', default=list(range(11)))
    p.add_argument('--hand-noise', type=float, default=0.0, help='MoCap noise per axis [m, rad]')
    args = p.parse_args()
    rows, cov_rows, curves = [], [], []
    t0 = time.perf_counter()
    all_cov = []
    for level in args.levels:
        lin, bat, cov, secs, sig = [], [], [], [], []
        for seed in range(args.seeds):
            rec = recording(level, seed, args.hand_noise)
            r0 = calibrate(rec.hand, rec.eye, CalibrationConfig(batch=False))
            r1 = calibrate(rec.hand, rec.eye)
            e0 = calibration_error(rec.truth, r0.time_offset_s, r0.q_HE, r0.p_HE)
            e1 = calibration_error(rec.truth, r1.time_offset_s, r1.q_HE, r1.p_HE)
            lin.append((e0.time_offset_s, e0.translation_m, e0.rotation_deg))
            bat.append((e1.time_offset_s, e1.translation_m, e1.rotation_deg))
            if r1.batch is not None:
                cov.append(covered(r1, rec.truth))
                secs.append(r1.batch.seconds)
                sig.append(r1.batch.std[0])
        lin_m, bat_m = np.mean(lin, axis=0), np.mean(bat, axis=0)
        rows.append(
            [
                f'{level:g}',
                lin_m[0] * 1e3,
                bat_m[0] * 1e3,
                lin_m[1] * 1e3,
                bat_m[1] * 1e3,
                lin_m[2],
                bat_m[2],
                float(np.mean(sig)) * 1e3 if sig else float('nan'),
                f'{len(cov)}/{args.seeds}',
                float(np.mean(secs)) if secs else float('nan'),
            ]
        )
        c = np.mean(cov, axis=0) * 100 if cov else [np.nan] * 3
        cov_rows.append([f'{level:g}', *c])
        all_cov += cov
        curves.append((level, lin_m, bat_m))
    emit(
        'batch_accuracy',
        table(
            f'Linear vs batch on the paper protocol, mean over {args.seeds} seeds (hand 100 Hz, '
            'eye 20 Hz, 60 s)',
            [
                'level',
                'dt lin ms',
                'dt batch ms',
                'trans lin mm',
                'trans batch mm',
                'rot lin deg',
                'rot batch deg',
                'reported 1-sigma dt ms',
                'batch used',
                'batch s',
            ],
            rows,
        ),
    )
    c = np.mean(all_cov, axis=0) * 100
    emit(
        'batch_coverage',
        table(
            'Truth inside the reported 3-sigma [% of seeds] (target >= 95)',
            ['level', 'dt', 'translation', 'rotation'],
            cov_rows + [['all', *c]],
        ),
    )
    print(f'({time.perf_counter() - t0:.0f} s)')
    plt = pyplot()
    if plt is not None:
        fig, ax = plt.subplots(1, 3, figsize=(15, 4))
        lv = [c[0] for c in curves]
        for k, (name, scale) in enumerate(
            (('|dt error| [ms]', 1e3), ('translation [mm]', 1e3), ('rotation [deg]', 1.0))
        ):
            ax[k].plot(lv, [c[1][k] * scale for c in curves], 'o-', label='linear')
            ax[k].plot(lv, [c[2][k] * scale for c in curves], 's-', label='batch')
            ax[k].set(xlabel='noise level', ylabel=name)
            ax[k].legend()
        print('plot:', save_plot(fig, 'batch'))


if __name__ == '__main__':
    main()
