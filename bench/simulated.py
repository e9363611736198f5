"""Simulated recordings with a known truth: the paper's protocol (Section IV-A) and its
ablations, OpenCV beside ours, the batch stage and whether the truth lies inside what the
result reports; recordings turning about one axis.

The paper's protocol (hand 100 Hz, eye 20 Hz, 60 s), each (level, seed) its own recording
(cases.protocol), calibrated once by stages 1-2 alone (``batch=False``) and once by default;
every table below reads those two results or the recording itself:

- ``ablation_time_alignment``: stage 1 alone, |dt error| with the quadratic peak fit and with
  the integer peak.
- ``ablation_linear_translation``, ``ablation_linear_rotation``: stage 2 on the true offset,
  for the global, inter-frame and rotation-constrained (eta 1, 5, 10 deg) relative poses, each
  with and without the screw-congruence kernel, with the paper's dual-quaternion solution and
  with our decoupled refit on the same consensus, and the paper's Algorithm 1 exactly. Every
  configuration is spelled out (LINEAR_VARIANTS, PAPER), so a change of a default does not
  silently change what a row measures.
- ``ablation_pipeline``: stages 1-2 with every check, the offset estimated.
- ``opencv_level{0,5,10}``: ours (offset estimated) against OpenCV's five calibrateHandEye
  methods given the pose pairs at the TRUE offset, fed two ways: the rotation-constrained
  keyframe poses our linear stage uses, and the poses every 0.5 s (OpenCV forms motions between
  all pairs it is given, so long-range motions carry the VIO's drift; the best input counts).
  ``pip install opencv-python-headless`` (the ``bench`` extra); without it, ours only.
- ``batch_accuracy``: the mean errors of the linear result and of the batch refinement.
- ``batch_coverage``: the truth inside the reported 3-sigma: |dt error| <= 3 sigma_dt, and for
  translation and rotation the Mahalanobis distance of the 3-vector error within chi2(3)'s
  99.73 % quantile (14.16; common.covered).
- ``uncertainty_sim`` (levels 2, 5, 8, 10): the same with the long-run covariance alone
  (before) and the reported one (now), and how much larger the reported sigma is.
- ``error_bars`` (levels 2, 5, 8, and one 10-minute recording at 200 + 30 Hz for the cost):
  each figure of the evaluation (APE and RPE, translation and rotation, RMSE) computed with the
  true calibration against the reported one, in its calibration 1-sigmas (target: within 3 in
  >= 90 % of seeds; rms 1 when the sigmas are right), and the error bars' CPU seconds beside the
  calibration's.

And ``purpose_one_axis``: a ground robot (``planar``: yaw only) and a turntable (``one_axis``),
60 and 300 s, the paper's noise levels 2 and 5 with a MoCap of 0.2 mm / 0.02 deg: the share of
seeds whose batch stage ran with the held direction named, whose figures have error bars, that
are ``good`` for evaluation, and whose APE at the true calibration lies within 3 of its reported
calibration 1-sigmas of the reported APE.

``--hand-noise`` gives the protocol's MoCap white noise per axis (m and rad; the paper's has none).

Usage: python bench/simulated.py [--seeds 20] [--levels 0 1 ... 10] [--hand-noise 1e-4]
    [--only protocol one_axis]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from types import SimpleNamespace

import cases
import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
from cases import PROTOCOL_SEEDS
from common import (
    OPENCV_METHODS,
    covered,
    cv2,
    emit,
    judged,
    opencv_hand_eye,
    opencv_inputs,
    pyplot,
    save_plot,
    table,
    truth_within,
)

from handeye_ros.core.association import associate
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.linear.axxb import build_motions
from handeye_ros.core.linear.robust import calibrate_linear
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.result import CalibrationResult
from handeye_ros.core.simulate import Recording, Truth, calibration_error, noise_level
from handeye_ros.core.time.align import align_time
from handeye_ros.evaluation import error_bars
from handeye_ros.evaluation.metrics import POSE_ERRORS

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
OPENCV_LEVELS = (0, 5, 10)
UNCERTAINTY_LEVELS = (2, 5, 8, 10)
ERROR_BAR_LEVELS = (2, 5, 8)
MOTIONS = ('planar', 'one_axis')
DURATIONS = (60.0, 300.0)
ONE_AXIS_LEVELS = (2, 5)


@dataclass(frozen=True)
class Measured:
    """What one recording of the protocol gives: errors against its truth (dt s, translation
    m, rotation deg) and what the default result reports."""

    dt_quadratic: float  # stage 1 alone, |dt error|
    dt_integer: float
    variants: np.ndarray  # (LINEAR_VARIANTS, 2): translation, rotation; nan where one failed
    opencv: dict[str, tuple[float, float]]  # method / input -> translation, rotation
    linear: tuple[float, float, float]  # stages 1-2
    batch: tuple[float, float, float]  # the default result
    reported: CalibrationResult
    covered: tuple[bool, bool, bool] | None  # the truth inside the reported 3-sigma
    long_run_covered: tuple[bool, bool, bool] | None  # ... inside the long-run one's
    figures: tuple[np.ndarray, float, float] | None  # error_bars' z, calibration s, bars s


def measure(rec: Recording, level: float) -> Measured:
    truth = rec.truth
    dt = [
        abs(align_time(rec.hand, rec.eye, peak_fit=fit).time_offset_s - truth.time_offset_s)
        for fit in ('quadratic', 'none')
    ]
    pairs = associate(rec.hand, rec.eye, truth.time_offset_s)
    variants = np.full((len(LINEAR_VARIANTS), 2), np.nan)
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
        variants[c] = e.translation_m, e.rotation_deg
    opencv = {}
    if cv2 is not None and level in OPENCV_LEVELS:
        for name, idx in opencv_inputs(pairs).items():
            for method in OPENCV_METHODS:
                q, p = opencv_hand_eye(pairs, idx, method)
                e = calibration_error(truth, truth.time_offset_s, q, p)
                opencv[f'OpenCV {method} / {name}'] = (e.translation_m, e.rotation_deg)
    r0 = calibrate(rec.hand, rec.eye, LINEAR)
    r1, seconds = calibrated(rec)
    e0 = calibration_error(truth, r0.time_offset_s, r0.q_HE, r0.p_HE)
    e1 = calibration_error(truth, r1.time_offset_s, r1.q_HE, r1.p_HE)
    figures = None
    if level in ERROR_BAR_LEVELS:
        z, bars_s = figures_z(r1, truth)
        figures = (z, seconds, bars_s)
    return Measured(
        dt[0],
        dt[1],
        variants,
        opencv,
        (e0.time_offset_s, e0.translation_m, e0.rotation_deg),
        (e1.time_offset_s, e1.translation_m, e1.rotation_deg),
        r1,
        None if r1.batch is None else covered(r1, truth),
        None if r1.batch is None else covered(_with(r1, r1.batch.uncertainty.long_run), truth),
        figures,
    )


def calibrated(rec: Recording) -> tuple[CalibrationResult, float]:
    """The default calibration of a recording and its CPU seconds."""
    t0 = time.process_time()
    res = calibrate(rec.hand, rec.eye)
    return res, time.process_time() - t0


def figures_z(res: CalibrationResult, t: Truth) -> tuple[np.ndarray, float]:
    """Per figure, (its value at the true calibration - the reported) / its calibration sigma;
    the error bars' CPU seconds."""
    t0 = time.process_time()
    bars, why = error_bars.calibration_sigmas(res, 1.0, 1.0)
    seconds = time.process_time() - t0
    assert bars is not None, why
    moved = error_bars.figures_at(res, t.time_offset_s, t.q_HE, t.p_HE)
    assert moved is not None
    return np.array([moved[n]['rmse'] / bars.sigmas[n]['rmse'] for n in POSE_ERRORS]), seconds


def _with(res, cov):
    """The result as :func:`common.covered` reads it, with another covariance."""
    return SimpleNamespace(
        batch=SimpleNamespace(covariance=cov),
        time_offset_s=res.time_offset_s,
        p_HE=res.p_HE,
        q_HE=res.q_HE,
    )


def _mean(v: np.ndarray) -> float:
    return float(np.nanmean(v)) if np.isfinite(v).any() else float('nan')


# --- the protocol's tables -------------------------------------------------------------------


def protocol(seeds: int, levels: list[float], hand_noise: float) -> None:
    found: list[list[Measured]] = []
    for level in levels:
        t0 = time.perf_counter()
        found.append(
            [
                measure(
                    cases.protocol(
                        level,
                        seed,
                        hand_noise_m=hand_noise,
                        hand_noise_deg=float(np.degrees(hand_noise)),
                    ),
                    level,
                )
                for seed in range(seeds)
            ]
        )
        print(f'level {level:g}: {time.perf_counter() - t0:.0f} s', flush=True)
    ablations(levels, found)
    if cv2 is None:
        print('opencv-python-headless is not installed (pip install .[bench]): ours only')
    for level, ms in zip(levels, found, strict=True):
        if level in OPENCV_LEVELS:
            versus_opencv(level, ms)
    batch_tables(levels, found)
    error_bars_table(levels, found)


def ablations(levels: list[float], found: list[list[Measured]]) -> None:
    seeds = len(found[0])
    emit(
        'ablation_time_alignment',
        table(
            f'Time alignment |dt error| [ms], mean (max) over {seeds} seeds; hand 100 Hz, '
            'eye 20 Hz, 60 s',
            ['level', 'noise mm/deg', 'quadratic', 'integer peak'],
            [
                [
                    f'{lv:g}',
                    f'{noise_level(lv)[0] * 1e3:.1f}/{noise_level(lv)[1]:.2f}',
                    *(
                        f'{np.mean(v) * 1e3:.3f} ({np.max(v) * 1e3:.2f})'
                        for v in ([m.dt_quadratic for m in ms], [m.dt_integer for m in ms])
                    ),
                ]
                for lv, ms in zip(levels, found, strict=True)
            ],
        ),
        PROTOCOL_SEEDS,
    )
    lin = np.array([[m.variants for m in ms] for ms in found])  # levels, seeds, variants, 2
    for k, (label, unit, scale) in enumerate(
        (('translation', 'mm', 1e3), ('rotation', 'deg', 1.0))
    ):
        emit(
            f'ablation_linear_{label}',
            table(
                f'Linear calibration on the true offset: extrinsic {label} error [{unit}], mean '
                f'over {seeds} seeds (nan: the variant failed on every seed)',
                ['variant'] + [f'L{lv:g}' for lv in levels],
                [
                    [v[0]] + [_mean(lin[a, :, c, k]) * scale for a in range(len(levels))]
                    for c, v in enumerate(LINEAR_VARIANTS)
                ],
            ),
            PROTOCOL_SEEDS + '; RANSAC rng seed 0',
        )
    full = np.array([[m.linear for m in ms] for ms in found])
    emit(
        'ablation_pipeline',
        table(
            f'Whole linear pipeline (offset estimated; stages 1-2, batch=False), mean over '
            f'{seeds} seeds',
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
    plt = pyplot()
    if plt is None:
        return
    fig, ax = plt.subplots(1, 3, figsize=(15, 4))
    for attr, label in (('dt_quadratic', 'quadratic fit'), ('dt_integer', 'integer peak')):
        ax[0].plot(
            levels,
            [np.mean([getattr(m, attr) for m in ms]) * 1e3 for ms in found],
            'o-',
            label=label,
        )
    ax[0].set(xlabel='noise level', ylabel='|dt error| [ms]', title='time alignment')
    for k, (scale, unit) in enumerate(
        ((1e3, 'translation error [mm]'), (1.0, 'rotation error [deg]'))
    ):
        for c, v in enumerate(LINEAR_VARIANTS):
            n = v[0]
            style = (
                ('o-' if '+kernel' in n else 'x--')
                if 'refit' in n
                else '-.'
                if 'exactly' in n
                else ':'
            )
            ax[k + 1].plot(
                levels,
                [_mean(lin[a, :, c, k]) * scale for a in range(len(levels))],
                style,
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


def versus_opencv(level: float, ms: list[Measured]) -> None:
    found: dict[str, list[tuple[float, float, float]]] = {
        'ours linear (dt estimated)': [m.linear for m in ms],
        'ours with batch (dt estimated)': [m.batch for m in ms],
    }
    for m in ms:
        for name, (t, r) in m.opencv.items():
            found.setdefault(name, []).append((0.0, t, r))
    errs = {k: np.asarray(v) for k, v in found.items()}
    rows = [
        [k, v[:, 1].mean() * 1e3, v[:, 2].mean(), np.median(v[:, 1]) * 1e3, np.median(v[:, 2])]
        for k, v in errs.items()
    ]
    lines = table(
        f'Noise level {level:g} ({len(ms)} seeds): extrinsic error; OpenCV given the true offset',
        ['method / input', 'trans mm', 'rot deg', 'median mm', 'median deg'],
        rows,
    )
    cv_rows = [r for r in rows if r[0].startswith('OpenCV')]
    if cv_rows:
        bt = min(cv_rows, key=lambda r: r[1])
        br = min(cv_rows, key=lambda r: r[2])

        def ratio(a: float, b: float) -> str:
            return f'{a / b:.2f}' if b > 1e-6 else 'n/a (OpenCV exact)'

        lines += (
            f'\nbest OpenCV: translation {bt[1]:.1f} mm ({bt[0]}), rotation '
            f'{br[2]:.3f} deg ({br[0]})'
        )
        for name in ('ours linear (dt estimated)', 'ours with batch (dt estimated)'):
            ours = errs[name]
            lines += (
                f'\n{name} / best OpenCV: translation '
                f'{ratio(ours[:, 1].mean() * 1e3, bt[1])}, rotation '
                f'{ratio(ours[:, 2].mean(), br[2])} (target <= 0.5 at level 10); '
                f'|dt| {ours[:, 0].mean() * 1e3:.3f} ms'
            )
    emit(f'opencv_level{level:g}', lines, PROTOCOL_SEEDS)


def batch_tables(levels: list[float], found: list[list[Measured]]) -> None:
    seeds = len(found[0])
    rows, cov_rows, unc_rows, all_cov = [], [], [], []
    for level, ms in zip(levels, found, strict=True):
        lin_m = np.mean([m.linear for m in ms], axis=0)
        bat_m = np.mean([m.batch for m in ms], axis=0)
        used = [m for m in ms if m.covered is not None]
        cov = [m.covered for m in used]
        rows.append(
            [
                f'{level:g}',
                lin_m[0] * 1e3,
                bat_m[0] * 1e3,
                lin_m[1] * 1e3,
                bat_m[1] * 1e3,
                lin_m[2],
                bat_m[2],
                _mean(np.array([m.reported.batch.std[0] for m in used])) * 1e3,
                f'{len(used)}/{seeds}',
                _mean(np.array([m.reported.batch.seconds for m in used])),
            ]
        )
        cov_rows.append([f'{level:g}', *(np.mean(cov, axis=0) * 100 if cov else [np.nan] * 3)])
        all_cov += cov
        if level in UNCERTAINTY_LEVELS and used:
            r = np.array([_ratio(m.reported) for m in used])
            unc_rows.append(
                [
                    f'{level:g}',
                    seeds,
                    ' '.join(f'{v:.0%}' for v in np.mean([m.long_run_covered for m in used], 0)),
                    ' '.join(f'{v:.0%}' for v in np.mean(cov, 0)),
                    ' '.join(f'{v:.2f}' for v in np.median(r, 0)[[0, 1, 4]]),
                    ' '.join(f'{v:.2f}' for v in r.max(0)[[0, 1, 4]]),
                ]
            )
    emit(
        'batch_accuracy',
        table(
            f'Linear vs batch on the paper protocol, mean over {seeds} seeds (hand 100 Hz, '
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
    emit(
        'batch_coverage',
        table(
            'Truth inside the reported 3-sigma [% of seeds] (target >= 95)',
            ['level', 'dt', 'translation', 'rotation'],
            cov_rows + [['all', *(np.mean(all_cov, axis=0) * 100)]],
        ),
    )
    if unc_rows:
        emit(
            'uncertainty_sim',
            table(
                "The paper's protocol, white noise: truth within 3 sigma (dt, translation, "
                'rotation) with the long-run covariance (before) and the reported one (now); '
                'reported over long-run 1-sigma (dt, x, rotation x), median and largest',
                ['level', 'seeds', 'covered before', 'covered now', 'ratio median', 'ratio max'],
                unc_rows,
            ),
            seeds=f'protocol_seed(level, 0..{seeds - 1})',
        )
    plt = pyplot()
    if plt is None:
        return
    fig, ax = plt.subplots(1, 3, figsize=(15, 4))
    for k, (name, scale) in enumerate(
        (('|dt error| [ms]', 1e3), ('translation [mm]', 1e3), ('rotation [deg]', 1.0))
    ):
        for attr, style in (('linear', 'o-'), ('batch', 's-')):
            mean = [np.mean([getattr(m, attr)[k] for m in ms]) * scale for ms in found]
            ax[k].plot(levels, mean, style, label=attr)
        ax[k].set(xlabel='noise level', ylabel=name)
        ax[k].legend()
    print('plot:', save_plot(fig, 'batch'))


def _ratio(r: CalibrationResult) -> np.ndarray:
    """The reported 1-sigmas over the long-run ones (dt, T_HE)."""
    u = r.batch.uncertainty
    return np.sqrt(np.diag(u.covariance)[:7] / np.diag(u.long_run)[:7])


def error_bars_table(levels: list[float], found: list[list[Measured]]) -> None:
    seeds = len(found[0])
    rows = []
    for level, ms in zip(levels, found, strict=True):
        if level not in ERROR_BAR_LEVELS:
            continue
        z = np.array([m.figures[0] for m in ms])
        c = np.array([m.figures[1:] for m in ms])
        rows.append(
            [
                f'{level:g} (60 s, 100 + 20 Hz)',
                seeds,
                ' '.join(f'{v:.0%}' for v in np.mean(np.abs(z) <= 3.0, 0)),
                ' '.join(f'{v:.2f}' for v in np.sqrt(np.mean(z**2, 0))),
                f'{np.median(c[:, 0]):.2f} / {np.median(c[:, 1]):.2f}',
            ]
        )
    if not rows:
        return
    rec = cases.recording(1, 5, duration_s=600.0, hand_rate_hz=200.0, eye_rate_hz=30.0)
    res, c_cal = calibrated(rec)
    z, c_bars = figures_z(res, rec.truth)
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
        seeds=f'protocol_seed(level, 0..{seeds - 1}); 600-s case seed 1',
    )


# --- one rotation axis -----------------------------------------------------------------------


def one_axis(seeds: int) -> None:
    rows: list[list[object]] = []
    for motion in MOTIONS:
        for duration in DURATIONS:
            for level in ONE_AXIS_LEVELS:
                counts = np.zeros(4)
                for seed in range(seeds):
                    rec = cases.recording(
                        seed,
                        level,
                        duration_s=duration,
                        hand_noise_m=2e-4,
                        hand_noise_deg=0.02,
                        motion=motion,
                    )
                    r = calibrate(rec.hand, rec.eye, CalibrationConfig())
                    held = r.batch is not None and r.batch.held_axis is not None
                    named = held and any('rotation axis' in u for u in r.linear.unobservable)
                    t = rec.truth
                    judged_r, ev = judged(r)
                    within = truth_within(r, ev, t.time_offset_s, t.q_HE, t.p_HE)[0]
                    r = judged_r
                    counts += [
                        named,
                        within is not None,
                        r.quality.verdict == 'good',
                        within is not None and within <= 3.0,
                    ]
                share = counts / seeds
                rows.append([motion, f'{duration:.0f}', level, *(f'{s:.0%}' for s in share)])
    emit(
        'purpose_one_axis',
        table(
            f'One rotation axis, {seeds} seeds a case: batch stage with the held '
            'direction named, figures with error bars, good for evaluation, APE at the '
            'truth within 3 calibration sigmas of the reported APE',
            ['motion', 'duration s', 'level', 'held named', 'error bars', 'good', 'truth'],
            rows,
        ),
        seeds=f'0..{seeds - 1}',
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--seeds', type=int, default=20)
    p.add_argument('--levels', type=float, nargs='+', default=list(range(11)))
    p.add_argument('--hand-noise', type=float, default=0.0, help='MoCap noise per axis [m, rad]')
    p.add_argument('--only', nargs='+', choices=('protocol', 'one_axis'))
    a = p.parse_args()
    if a.only is None or 'protocol' in a.only:
        protocol(a.seeds, a.levels, a.hand_noise)
    if a.only is None or 'one_axis' in a.only:
        one_axis(a.seeds)


if __name__ == '__main__':
    main()
