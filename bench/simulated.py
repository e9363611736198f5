"""Simulated recordings with a known truth: the batch stage against the linear one, whether the
truth lies inside what the result reports, and recordings turning about one axis.

The paper's protocol (hand 100 Hz, eye 20 Hz, 60 s), each (level, seed) its own recording
(cases.protocol), calibrated once by stage 1+2 alone and once by default:

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

- ``purpose_one_axis``: a ground robot (``planar``: yaw only) and a turntable (``one_axis``),
  60 and 300 s, the paper's noise levels 2 and 5 with a MoCap of 0.2 mm / 0.02 deg: the share of
  seeds whose batch stage ran with the held direction named, whose figures have error bars, that
  are ``good`` for evaluation, and whose APE at the true calibration lies within 3 of its
  reported calibration 1-sigmas of the reported APE.

``--hand-noise`` gives the protocol's MoCap white noise per axis (m and rad; the paper's has none).

Usage: python bench/simulated.py [--seeds 20] [--levels 0 1 ... 10] [--hand-noise 1e-4]
    [--only protocol one_axis]
"""

from __future__ import annotations

import argparse
import time
from types import SimpleNamespace

import cases
import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
from common import covered, emit, pyplot, save_plot, table
from real import judged, truth_within

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.result import CalibrationResult
from handeye_ros.core.simulate import Recording, Truth, calibration_error
from handeye_ros.evaluation import error_bars
from handeye_ros.evaluation.metrics import POSE_ERRORS

UNCERTAINTY_LEVELS = (2, 5, 8, 10)
ERROR_BAR_LEVELS = (2, 5, 8)
MOTIONS = ('planar', 'one_axis')
DURATIONS = (60.0, 300.0)
ONE_AXIS_LEVELS = (2, 5)


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


def protocol(seeds: int, levels: list[float], hand_noise: float) -> None:
    rows, cov_rows, unc_rows, bar_rows, curves, all_cov = [], [], [], [], [], []
    t0 = time.perf_counter()
    for level in levels:
        lin, bat, cov, secs, sig, before, ratios, zs, costs = ([] for _ in range(9))
        for seed in range(seeds):
            rec = cases.protocol(
                level, seed, hand_noise_m=hand_noise, hand_noise_deg=float(np.degrees(hand_noise))
            )
            r0 = calibrate(rec.hand, rec.eye, CalibrationConfig(batch=False))
            r1, c_cal = calibrated(rec)
            e0 = calibration_error(rec.truth, r0.time_offset_s, r0.q_HE, r0.p_HE)
            e1 = calibration_error(rec.truth, r1.time_offset_s, r1.q_HE, r1.p_HE)
            lin.append((e0.time_offset_s, e0.translation_m, e0.rotation_deg))
            bat.append((e1.time_offset_s, e1.translation_m, e1.rotation_deg))
            if r1.batch is not None:
                u = r1.batch.uncertainty
                cov.append(covered(r1, rec.truth))
                before.append(covered(_with(r1, u.long_run), rec.truth))
                ratios.append(np.sqrt(np.diag(u.covariance)[:7] / np.diag(u.long_run)[:7]))
                secs.append(r1.batch.seconds)
                sig.append(r1.batch.std[0])
            if level in ERROR_BAR_LEVELS:
                z, c_bars = figures_z(r1, rec.truth)
                zs.append(z)
                costs.append((c_cal, c_bars))
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
                f'{len(cov)}/{seeds}',
                float(np.mean(secs)) if secs else float('nan'),
            ]
        )
        cov_rows.append([f'{level:g}', *(np.mean(cov, axis=0) * 100 if cov else [np.nan] * 3)])
        all_cov += cov
        curves.append((level, lin_m, bat_m))
        if level in UNCERTAINTY_LEVELS and cov:
            r = np.array(ratios)
            unc_rows.append(
                [
                    f'{level:g}',
                    seeds,
                    ' '.join(f'{v:.0%}' for v in np.mean(before, 0)),
                    ' '.join(f'{v:.0%}' for v in np.mean(cov, 0)),
                    ' '.join(f'{v:.2f}' for v in np.median(r, 0)[[0, 1, 4]]),
                    ' '.join(f'{v:.2f}' for v in r.max(0)[[0, 1, 4]]),
                ]
            )
        if zs:
            z, c = np.array(zs), np.array(costs)
            bar_rows.append(
                [
                    f'{level:g} (60 s, 100 + 20 Hz)',
                    seeds,
                    ' '.join(f'{v:.0%}' for v in np.mean(np.abs(z) <= 3.0, 0)),
                    ' '.join(f'{v:.2f}' for v in np.sqrt(np.mean(z**2, 0))),
                    f'{np.median(c[:, 0]):.2f} / {np.median(c[:, 1]):.2f}',
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
    if bar_rows:
        rec = cases.recording(1, 5, duration_s=600.0, hand_rate_hz=200.0, eye_rate_hz=30.0)
        res, c_cal = calibrated(rec)
        z, c_bars = figures_z(res, rec.truth)
        bar_rows.append(
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
                bar_rows,
            ),
            seeds=f'protocol_seed(level, 0..{seeds - 1}); 600-s case seed 1',
        )
    print(f'({time.perf_counter() - t0:.0f} s)')
    _plot(curves)


def _with(res, cov):
    """The result as :func:`common.covered` reads it, with another covariance."""
    return SimpleNamespace(
        batch=SimpleNamespace(covariance=cov),
        time_offset_s=res.time_offset_s,
        p_HE=res.p_HE,
        q_HE=res.q_HE,
    )


def _plot(curves: list) -> None:
    plt = pyplot()
    if plt is None:
        return
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
                    within = truth_within(r, t.time_offset_s, t.q_HE, t.p_HE, 'ape_translation')
                    r, _ = judged(r)
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
