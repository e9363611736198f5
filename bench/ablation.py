"""The paper's ablations on its simulation protocol (Section IV-A), 20 seeds per noise level.

(1) Time alignment: |dt error| vs noise level, quadratic peak fit vs integer peak.
(2) Linear calibration on the true offset: extrinsic error vs noise level for the global,
    inter-frame and rotation-constrained (eta 1, 5, 10 deg) relative poses, each with and
    without the screw-congruence kernel, each with the paper's dual-quaternion solution and
    with our decoupled refit of rotation and translation on the same consensus.
(3) The whole linear pipeline (offset estimated, then stages 1-2 with every check, no batch
    stage: ``CalibrationConfig(batch=False)``); bench/simulated.py measures the batch stage.

Every configuration is spelled out here (LINEAR, the keyword arguments of calibrate_linear),
so a change of a default does not silently change what a row measures. Every (level, k) is its
own recording (cases.protocol_seed).

Usage: python bench/ablation.py [--seeds 20] [--levels 0 1 ... 10]
"""

from __future__ import annotations

import argparse
import time

import cases
import common  # noqa: F401  (puts the package on sys.path)
import numpy as np
from cases import PROTOCOL_SEEDS
from common import emit, pyplot, save_plot, table

from handeye_ros.core.association import associate
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.linear.axxb import build_motions
from handeye_ros.core.linear.robust import calibrate_linear
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import calibration_error, noise_level
from handeye_ros.core.time.align import align_time

#: The whole linear pipeline: stages 1 and 2 with the defaults otherwise.
LINEAR = CalibrationConfig(batch=False)
#: The paper's values for the linear stage (Section III-B): mu 5, RANSAC 200, 0.5 deg / 2 cm.
PAPER = {
    'mu': 5.0,
    'ransac_iterations': 200,
    'inlier_rotation_rad': np.deg2rad(0.5),
    'inlier_translation_m': 0.02,
}

#: (label, relative poses, eta deg, robust kernel, adaptive inliers, decoupled refit)
LINEAR_VARIANTS = [
    (f'{name} {"+" if kernel else "-"}kernel{suffix}', strategy, eta, kernel, adaptive, refit)
    for name, strategy, eta in (
        ('global', 'global', 5.0),
        ('interframe', 'interframe', 5.0),
        ('rot eta=1', 'rotation', 1.0),
        ('rot eta=5', 'rotation', 5.0),
        ('rot eta=10', 'rotation', 10.0),
    )
    for kernel in (True, False)
    for adaptive, refit, suffix in (
        (True, False, ' (dual quaternion)'),
        (True, True, ' +refit'),
    )
] + [
    # the paper's Algorithm 1 exactly: fixed thresholds, the dual-quaternion solution
    (
        f'rot eta=5 {"+" if kernel else "-"}kernel (paper exactly)',
        'rotation',
        5.0,
        kernel,
        False,
        False,
    )
    for kernel in (True, False)
]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--seeds', type=int, default=20)
    p.add_argument('--levels', type=float, nargs='+', default=list(range(11)))
    args = p.parse_args()
    seeds, levels = range(args.seeds), args.levels
    dt_err = {fit: np.zeros((len(levels), len(seeds))) for fit in ('quadratic', 'none')}
    names = [v[0] for v in LINEAR_VARIANTS]
    lin = np.full((len(names), len(levels), len(seeds), 2), np.nan)
    full = np.zeros((len(levels), len(seeds), 3))
    t0 = time.perf_counter()
    for a, level in enumerate(levels):
        for b, seed in enumerate(seeds):
            rec = cases.protocol(level, seed)
            truth = rec.truth
            for fit, err in dt_err.items():
                ta = align_time(rec.hand, rec.eye, peak_fit=fit)
                err[a, b] = abs(ta.time_offset_s - truth.time_offset_s)
            pairs = associate(rec.hand, rec.eye, truth.time_offset_s)
            motions = {}
            for c, (_, strategy, eta, kernel, adaptive, refit) in enumerate(LINEAR_VARIANTS):
                if (strategy, eta) not in motions:
                    motions[strategy, eta] = build_motions(pairs, strategy, np.deg2rad(eta))
                try:
                    s = calibrate_linear(
                        motions[strategy, eta],
                        robust_kernel=kernel,
                        adaptive_inliers=adaptive,
                        decoupled_refit=refit,
                        rng=np.random.default_rng(0),
                        **PAPER,
                    )
                except HandeyeError:  # a failed variant counts as missing
                    continue
                e = calibration_error(truth, truth.time_offset_s, s.q_HE, s.p_HE)
                lin[c, a, b] = e.translation_m, e.rotation_deg
            res = calibrate(rec.hand, rec.eye, LINEAR)
            e = calibration_error(truth, res.time_offset_s, res.q_HE, res.p_HE)
            full[a, b] = e.time_offset_s, e.translation_m, e.rotation_deg
    elapsed = time.perf_counter() - t0

    emit(
        'ablation_time_alignment',
        table(
            f'Time alignment |dt error| [ms], mean (max) over {len(seeds)} seeds; hand 100 Hz, '
            'eye 20 Hz, 60 s',
            ['level', 'noise mm/deg', 'quadratic', 'integer peak'],
            [
                [
                    f'{lv:g}',
                    f'{noise_level(lv)[0] * 1e3:.1f}/{noise_level(lv)[1]:.2f}',
                    f'{dt_err["quadratic"][a].mean() * 1e3:.3f} ({dt_err["quadratic"][a].max() * 1e3:.2f})',
                    f'{dt_err["none"][a].mean() * 1e3:.3f} ({dt_err["none"][a].max() * 1e3:.2f})',
                ]
                for a, lv in enumerate(levels)
            ],
        ),
        PROTOCOL_SEEDS,
    )
    for k, (unit, scale) in enumerate((('mm', 1e3), ('deg', 1.0))):
        emit(
            f'ablation_linear_{"translation" if k == 0 else "rotation"}',
            table(
                f'Linear calibration on the true offset: extrinsic '
                f'{"translation" if k == 0 else "rotation"} error [{unit}], mean over {len(seeds)} '
                'seeds (nan: the variant failed on every seed)',
                ['variant'] + [f'L{lv:g}' for lv in levels],
                [
                    [n] + [_mean(lin[c, a, :, k]) * scale for a in range(len(levels))]
                    for c, n in enumerate(names)
                ],
            ),
            PROTOCOL_SEEDS + '; RANSAC rng seed 0',
        )
    emit(
        'ablation_pipeline',
        table(
            f'Whole linear pipeline (offset estimated; stages 1-2, batch=False), mean over '
            f'{len(seeds)} seeds',
            [
                'level',
                '|dt| ms',
                'trans mm',
                'rot deg',
                'max |dt| ms',
                'max trans mm',
                'max rot deg',
            ],
            [
                [
                    f'{lv:g}',
                    *(full[a].mean(axis=0) * [1e3, 1e3, 1]),
                    *(full[a].max(axis=0) * [1e3, 1e3, 1]),
                ]
                for a, lv in enumerate(levels)
            ],
        ),
        PROTOCOL_SEEDS + f'; RANSAC seed {LINEAR.seed}',
    )
    print(f'({elapsed:.1f} s)')

    plt = pyplot()
    if plt is not None:
        fig, ax = plt.subplots(1, 3, figsize=(15, 4))
        for fit, label in (('quadratic', 'quadratic fit'), ('none', 'integer peak')):
            ax[0].plot(levels, dt_err[fit].mean(axis=1) * 1e3, 'o-', label=label)
        ax[0].set(xlabel='noise level', ylabel='|dt error| [ms]', title='time alignment')
        for k, (scale, unit) in enumerate(
            ((1e3, 'translation error [mm]'), (1.0, 'rotation error [deg]'))
        ):
            for c, n in enumerate(names):
                ax[k + 1].plot(
                    levels,
                    [_mean(lin[c, a, :, k]) * scale for a in range(len(levels))],
                    ('o-' if '+kernel' in n else 'x--')
                    if 'refit' in n
                    else '-.'
                    if 'exactly' in n
                    else ':',
                    label=n,
                )
            ax[k + 1].set(
                xlabel='noise level',
                ylabel=unit,
                yscale='log',
                title='linear calibration (true offset)',
            )
        ax[0].legend()
        ax[2].legend(fontsize=7, ncol=2)
        print('plot:', save_plot(fig, 'ablation'))


def _mean(v: np.ndarray) -> float:
    return float(np.nanmean(v)) if np.isfinite(v).any() else float('nan')


if __name__ == '__main__':
    main()
