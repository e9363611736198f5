"""Clock drift and monocular scale (issue 11): the figures, on the simulator and on real pairs.

Drift: simulated 10-minute recordings (200 Hz hand, 30 Hz eye, noise level 5) whose eye clock
runs fast by 0, 50, 200 and 1000 ppm, and every real pair of ../shared/data/real with the same
drifts put into the eye's stamps (about its middle stamp; the hand in the Vicon marker frame,
clock +87.3 ms, as bench/real_cases.py). Each is calibrated with one constant offset
(``auto_drift`` off) and with ``clock_drift``: the drift error, dt at the first and the last eye
pose against the truth, T_HE against the truth, and whether the constant run named the drift
(which the default run then fits: bench/results/drift_scale.md).

Scale: the eye's positions divided by 0.3, 0.5, 2 and 5 (a monocular eye; the scale to find is
that factor), simulated (2 minutes) and real, calibrated with ``estimate_scale``: the scale
error, and T_HE against the unscaled case calibrated by default. On the unmodified real pairs
(metric VIO) ``estimate_scale`` should return 1 within its sigma; the table gives s, its sigma
and |s - 1| / sigma. The error of s on a real pair is also given against s of the unmodified
pair (the VIO's own scale error is part of the truth there). Verdicts as the front ends give
them (judged for evaluation with the evaluation's figures, common.judged).

Usage: python bench/drift_scale.py [--quick] [--no-sim] [--no-real] [--pairs NAME ...]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import cases
import common  # puts the project on the path
import numpy as np
from common import emit, sim3_scale, table

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.simulate import Truth, calibration_error, noise_level, simulate
from handeye_ros.core.trajectory import Trajectory

DRIFTS_PPM = (0.0, 50.0, 200.0, 1000.0)
SCALES = (0.3, 0.5, 2.0, 5.0)
SIM_SEEDS = (11, 12, 13)
QUICK_PAIRS = ('V2_01 stereo', 'MH_01 mono', 'V1_02 evo')


def drifted(eye: Trajectory, ppm: float) -> tuple[Trajectory, float, int]:
    """The eye on a clock running fast by ppm about its middle stamp; returns it, the true
    drift of dt(t) in the new stamps ([s/s]: ppm/(1 + ppm) per 1e6) and the middle stamp."""
    k = ppm * 1e-6
    t = eye.t_ns
    mid = int(t[(t.size - 1) // 2])
    return replace(eye, t_ns=t + np.rint((t - mid) * k).astype(np.int64)), k / (1.0 + k), mid


def _run(calibrate, hand, eye, cfg):
    """(the result judged as the front ends judge it, or the error it raised; seconds)."""
    t0 = time.perf_counter()
    try:
        return common.judged(calibrate(hand, eye, cfg))[0], time.perf_counter() - t0
    except HandeyeError as err:
        return err, time.perf_counter() - t0


def drift_rows(cases, calibrate) -> list[list]:
    """cases: (label, hand, eye, truth with clock_drift/time_offset_stamp_ns)."""
    rows = []
    for label, hand, eye, truth in cases:
        ends = eye.t_ns[[0, -1]]
        true_ends = truth.time_offset_at(ends)
        plain, _ = _run(calibrate, hand, eye, CalibrationConfig(auto_drift=False))
        res, secs = _run(calibrate, hand, eye, CalibrationConfig(clock_drift=True))
        if isinstance(res, Exception) or isinstance(plain, Exception):
            rows.append([label, 'REFUSED', str(res)[:60]] + [''] * 10)
            continue
        e = calibration_error(truth, truth.time_offset_s, res.q_HE, res.p_HE)
        e0 = calibration_error(truth, truth.time_offset_s, plain.q_HE, plain.p_HE)
        d_err = (
            (res.clock_drift - truth.clock_drift) * 1e6
            if res.clock_drift is not None
            else float('nan')
        )
        d_std = res.eye_model.drift_std * 1e6 if res.clock_drift is not None else float('nan')
        end_err = np.abs(res.time_offset_at(ends) - true_ends) * 1e3
        plain_end = np.abs(plain.time_offset_at(ends) - true_ends) * 1e3
        named = 'clock_drift' in plain.quality.codes
        rows.append(
            [
                label,
                d_err,
                d_std,
                end_err.max(),
                plain_end.max(),
                e.translation_m * 1e3,
                e.rotation_deg,
                e0.translation_m * 1e3,
                e0.rotation_deg,
                'yes' if named else 'no',
                res.quality.label(','),
                f'{secs:.1f}',
            ]
        )
    return rows


DRIFT_HEADER = [
    'case',
    'drift err ppm',
    'drift sigma ppm',
    'dt err at ends ms',
    'constant: dt err at ends ms',
    'T_HE mm',
    'T_HE deg',
    'constant: mm',
    'constant: deg',
    'constant names it',
    'verdict with --clock-drift',
    's',
]


def scale_rows(cases, calibrate) -> list[list]:
    """cases: (label, hand, eye, truth, the eye's scale to find, reference scale, the pair's
    Sim(3) scale)."""
    rows = []
    for label, hand, eye, truth, s_true, ref, sim3 in cases:
        res, secs = _run(calibrate, hand, eye, CalibrationConfig(estimate_scale=True))
        if isinstance(res, Exception):
            rows.append([label, 'REFUSED', str(res)[:60]] + [''] * 7)
            continue
        s, sd = res.scale, res.eye_model.scale_std
        e = calibration_error(truth, truth.time_offset_s, res.q_HE, res.p_HE)
        rows.append(
            [
                label,
                s,
                sd,
                100.0 * (s / s_true - 1.0),
                100.0 * (s / (s_true * ref) - 1.0) if ref is not None else float('nan'),
                abs(s - 1.0) / sd if s_true == 1.0 else float('nan'),
                sim3 if sim3 is not None else float('nan'),
                e.translation_m * 1e3,
                e.rotation_deg,
                res.quality.label(','),
                f'{secs:.1f}',
            ]
        )
    return rows


SCALE_HEADER = [
    'case',
    's',
    'sigma',
    'err % vs truth',
    'err % vs unmodified pair',
    '|s-1|/sigma',
    "VIO's own s (Sim(3))",
    'T_HE mm',
    'T_HE deg',
    'verdict',
    's',
]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument(
        '--quick',
        action='store_true',
        help=f'real pairs {", ".join(QUICK_PAIRS)}, one simulated seed',
    )
    p.add_argument('--no-sim', action='store_true')
    p.add_argument('--no-real', action='store_true')
    p.add_argument('--pairs', nargs='+')
    args = p.parse_args()
    from handeye_ros.core.pipeline import calibrate

    seeds = SIM_SEEDS[:1] if args.quick else SIM_SEEDS
    if not args.no_sim:
        nm, nd = noise_level(5)
        sims = []
        for seed in seeds:
            for ppm in DRIFTS_PPM:
                rec = simulate(
                    seed,
                    duration_s=600.0,
                    hand_rate_hz=200,
                    eye_rate_hz=30,
                    noise_m=nm,
                    noise_deg=nd,
                    clock_drift=ppm * 1e-6,
                )
                sims.append((f'sim {seed} {ppm:g} ppm', rec.hand, rec.eye, rec.truth))
        emit(
            'drift_sim',
            table(
                'Clock drift, simulated 10 min (200 Hz hand, 30 Hz eye, noise level 5): '
                'targets drift within 5 ppm, dt at the ends within 2 ms, T_HE no worse than '
                'without drift',
                DRIFT_HEADER,
                drift_rows(sims, calibrate),
            ),
            seeds,
        )
        sims = []
        for seed in seeds:
            base = simulate(seed, duration_s=120.0, noise_m=nm, noise_deg=nd)
            sims.append((f'sim {seed} unscaled', base.hand, base.eye, base.truth, 1.0, None, None))
            for s in SCALES:
                rec = simulate(seed, duration_s=120.0, noise_m=nm, noise_deg=nd, scale=s)
                sims.append(
                    (f'sim {seed} scale {s:g}', rec.hand, rec.eye, rec.truth, s, None, None)
                )
        emit(
            'scale_sim',
            table(
                'Monocular scale, simulated 2 min (100 Hz hand, 20 Hz eye, noise level 5) with '
                "--scale: targets s within 0.5 %, T_HE within the unscaled case's error + 20 %",
                SCALE_HEADER,
                scale_rows(sims, calibrate),
            ),
            seeds,
        )
    if args.no_real or not cases.available():
        if not args.no_real:
            print(f'real data not found at {cases.REAL_DATA}: real cases skipped')
        return
    names = args.pairs or (QUICK_PAIRS if args.quick else [q.name for q in cases.PAIRS])
    q, pp = cases.true_extrinsic()
    d_cases, s_cases = [], []
    for pair in cases.PAIRS:
        if pair.name not in names:
            continue
        gt, est = cases.load(pair)
        hand = cases.to_marker_frame(gt, cases.SHIFT_S)
        for ppm in DRIFTS_PPM:
            eye, k, mid = drifted(est, ppm)
            truth = Truth(cases.SHIFT_S, q, pp, q, pp, clock_drift=k, time_offset_stamp_ns=mid)
            d_cases.append((f'{pair.name} {ppm:g} ppm', hand, eye, truth))
        truth = Truth(cases.SHIFT_S, q, pp, q, pp)
        ref = calibrate(hand, est, CalibrationConfig(estimate_scale=True)).scale
        s_cases.append((f'{pair.name} metric', hand, est, truth, 1.0, None, sim3_scale(gt, est)))
        for s in SCALES:
            s_cases.append(
                (
                    f'{pair.name} scale {s:g}',
                    hand,
                    replace(est, p_xyz=est.p_xyz / s),
                    truth,
                    s,
                    ref,
                    None,
                )
            )
    emit(
        'drift_real',
        table(
            f'Clock drift put into the eye stamps of {len(names)} real pairs (durations 80-180 s): '
            "drift error, dt at the ends against the truth (the pair's own offset error "
            "included), T_HE against EuRoC's T_BS",
            DRIFT_HEADER,
            drift_rows(d_cases, calibrate),
        ),
        'no random draws',
    )
    emit(
        'scale_real',
        table(
            f'Monocular scale put into the eye positions of {len(names)} real pairs, with --scale; '
            '"metric": the published VIO as it is, whose own scale error the Sim(3) column '
            'measures independently (whole-trajectory position fit against the ground truth)',
            SCALE_HEADER,
            scale_rows(s_cases, calibrate),
        ),
        'no random draws',
    )


if __name__ == '__main__':
    main()
