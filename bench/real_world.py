"""Real recordings as they come (issue 26): MoCap dropouts, MoCap at both ends only, keyframe-only
estimates, damaged files.

Three tables, each verdict as the front ends give it (judged for purpose evaluation with the
evaluation's own figures, common.judged):

- ``real_world_tumvi``: every TUM-VI estimate of ../shared/data/real/VSLAM-comparison (ORB-SLAM3,
  Basalt, DSO; VIO and monocular VO) against its MoCap, files as published, with the defaults
  and with ``clock_drift``. Basalt and ORB-SLAM3 VIO are in the IMU frame (reference T_HE = I,
  dt ~ 0 up to the drift); DSO and the VO runs in the camera frame (T_HE is the camera-IMU
  transform, not I; a row gives the answer or the refusal).
- ``real_world_keyframes``: keyframe-only versions of the 12 EuRoC estimates of
  bench/cases.py (each next pose 1/3 to 1/0.3 s later, seed 0), against the dense run.
- ``real_world_sim``: 10-minute simulated recordings (level 5, 100 Hz hand, 20 Hz eye): the
  continuous recording; MoCap dropouts of 0.2-5 s covering 5 % and 30 %; the two-window layout
  (60 s at each end, 50 ppm drift, clock_drift on); keyframe-only eyes at 0.3-3 Hz. Errors
  against the truth (dt at the result's reference stamp), their ratio to the continuous run's,
  and how often the truth lies within the reported 3 sigma (common.covered's rule).

Usage: python bench/real_world.py [--seeds N] [--only tumvi keyframes sim]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import cases
import common  # first: puts the project on sys.path
import numpy as np
from common import CHI2_3_9973, emit, table
from scipy.spatial.transform import Rotation

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.geometry import quat_angle
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import (
    keyframes_only,
    noise_level,
    simulate,
    two_windows,
    with_dropouts,
)

LEVEL = 5.0
DURATION_S = 600.0


def _codes(res) -> str:
    return ','.join(r.code for r in res.quality.reasons) or '-'


def _sigmas(res) -> tuple[float, float, float]:
    """1-sigma of dt [ms], T_HE translation [mm] and rotation [deg] (NaN without a batch)."""
    if res.batch is None:
        return (float('nan'),) * 3
    s = res.batch.std
    return (
        s[0] * 1e3,
        float(np.linalg.norm(s[1:4])) * 1e3,
        float(np.degrees(np.linalg.norm(s[4:7]))),
    )


def tumvi_rows() -> list[list]:
    rows = []
    for run in cases.tumvi_estimates():
        path, (hand, eye) = Path(run.eye), run.load()
        for label, cfg in (
            ('default', CalibrationConfig()),
            ('drift', CalibrationConfig(clock_drift=True)),
        ):
            t0 = time.perf_counter()
            try:
                res = common.judged(calibrate(hand, eye, cfg))[0]
            except HandeyeError as err:
                rows.append(
                    [
                        path.name,
                        label,
                        'refused',
                        str(err)[:110],
                        *[''] * 6,
                        f'{time.perf_counter() - t0:.1f}',
                    ]
                )
                continue
            drift = '' if res.clock_drift is None else f'{res.clock_drift * 1e6:+.1f}'
            sd = _sigmas(res)
            rows.append(
                [
                    path.name,
                    label,
                    res.quality.verdict,
                    _codes(res),
                    f'{res.time_offset_s * 1e3:+.2f}',
                    drift,
                    f'{np.linalg.norm(res.p_HE) * 1e3:.1f}',
                    f'{np.degrees(quat_angle(res.q_HE, np.array([0.0, 0, 0, 1]))):.2f}',
                    f'{sd[0]:.2f} / {sd[1]:.1f} / {sd[2]:.2f}',
                    f'{res.coverage.fraction:.0%}' if res.coverage is not None else '',
                    f'{time.perf_counter() - t0:.1f}',
                ]
            )
    return rows


def keyframe_rows() -> list[list]:
    rows = []
    for pair in cases.PAIRS:
        hand, eye = cases.load(pair)
        dense = calibrate(hand, eye)
        kf = keyframes_only(eye, np.random.default_rng(0))
        t0 = time.perf_counter()
        try:
            res = common.judged(calibrate(hand, kf))[0]
        except HandeyeError as err:
            rows.append([pair.name, len(kf), 'refused', str(err)[:80], '', '', '', '', ''])
            continue
        sd = _sigmas(res)
        rows.append(
            [
                pair.name,
                len(kf),
                res.quality.verdict,
                _codes(res),
                f'{(res.time_offset_s - dense.time_offset_s) * 1e3:+.2f}',
                f'{np.linalg.norm(res.p_HE - dense.p_HE) * 1e3:.1f}',
                f'{np.degrees(quat_angle(res.q_HE, dense.q_HE)):.2f}',
                f'{sd[0]:.2f} / {sd[1]:.1f} / {sd[2]:.2f}',
                f'{time.perf_counter() - t0:.1f}',
            ]
        )
    return rows


def _errors(res, truth) -> tuple[float, float, float, bool]:
    """|dt| [s] at the result's reference stamp, |t| [m], rotation [deg], and whether the truth
    is inside the reported 3 sigma (dt, and the translation and rotation 3-vectors by their
    Mahalanobis distance, as common.covered)."""
    stamp = np.array(
        [
            res.eye_model.time_offset_stamp_ns
            if res.clock_drift is not None
            else truth.time_offset_stamp_ns or 0
        ]
    )
    e_dt = float(res.time_offset_at(stamp)[0] - truth.time_offset_at(stamp)[0])
    e_t = truth.p_HE - res.p_HE
    e_r = (Rotation.from_quat(res.q_HE).inv() * Rotation.from_quat(truth.q_HE)).as_rotvec()
    inside = False
    if res.batch is not None:
        cov = res.batch.covariance
        inside = (
            abs(e_dt) <= 3 * np.sqrt(cov[0, 0])
            and float(e_t @ np.linalg.solve(cov[1:4, 1:4], e_t)) <= CHI2_3_9973
            and float(e_r @ np.linalg.solve(cov[4:7, 4:7], e_r)) <= CHI2_3_9973
        )
    return abs(e_dt), float(np.linalg.norm(e_t)), float(np.degrees(np.linalg.norm(e_r))), inside


CONDITIONS = (
    'continuous',
    'dropouts 5 %',
    'dropouts 30 %',
    'two windows, 50 ppm',
    'keyframes 0.3-3 Hz',
)


def sim_rows(seeds: int) -> list[list]:
    noise_m, noise_deg = noise_level(LEVEL)
    out: dict[str, list] = {c: [] for c in CONDITIONS}
    for seed in range(seeds):
        rec = simulate(seed, duration_s=DURATION_S, noise_m=noise_m, noise_deg=noise_deg)
        drifting = simulate(
            seed, duration_s=DURATION_S, noise_m=noise_m, noise_deg=noise_deg, clock_drift=50e-6
        )
        rng = np.random.default_rng(seed)
        variants = {
            'continuous': (rec.hand, rec.eye, rec.truth, CalibrationConfig()),
            'dropouts 5 %': (
                with_dropouts(rec.hand, rng, 0.05),
                rec.eye,
                rec.truth,
                CalibrationConfig(),
            ),
            'dropouts 30 %': (
                with_dropouts(rec.hand, rng, 0.30),
                rec.eye,
                rec.truth,
                CalibrationConfig(),
            ),
            'two windows, 50 ppm': (
                two_windows(drifting.hand, 60.0),
                drifting.eye,
                drifting.truth,
                CalibrationConfig(clock_drift=True),
            ),
            'keyframes 0.3-3 Hz': (
                rec.hand,
                keyframes_only(rec.eye, rng),
                rec.truth,
                CalibrationConfig(),
            ),
        }
        for name, (hand, eye, truth, cfg) in variants.items():
            t0 = time.perf_counter()
            try:
                res = common.judged(calibrate(hand, eye, cfg))[0]
                out[name].append(
                    (*_errors(res, truth), res.quality.verdict, time.perf_counter() - t0)
                )
            except HandeyeError as err:
                out[name].append(
                    (
                        np.inf,
                        np.inf,
                        np.inf,
                        False,
                        f'refused: {err}'[:60],
                        time.perf_counter() - t0,
                    )
                )
    base = np.array([r[:3] for r in out['continuous']], float)
    rows = []
    for name in CONDITIONS:
        e = np.array([r[:3] for r in out[name]], float)
        ratio = np.mean(e, axis=0) / np.maximum(np.mean(base, axis=0), 1e-12)
        verdicts = [r[4] for r in out[name]]
        rows.append(
            [
                name,
                len(e),
                f'{np.median(e[:, 0]) * 1e3:.2f} / {np.max(e[:, 0]) * 1e3:.2f}',
                f'{np.median(e[:, 1]) * 1e3:.1f} / {np.max(e[:, 1]) * 1e3:.1f}',
                f'{np.median(e[:, 2]):.2f} / {np.max(e[:, 2]):.2f}',
                f'{ratio[0]:.1f} / {ratio[1]:.1f} / {ratio[2]:.1f}',
                f'{np.mean([r[3] for r in out[name]]):.0%}',
                ' '.join(f'{v}:{verdicts.count(v)}' for v in sorted(set(verdicts))),
                f'{np.mean([r[5] for r in out[name]]):.1f}',
            ]
        )
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seeds', type=int, default=10, help='simulated recordings per condition')
    ap.add_argument(
        '--only',
        nargs='+',
        choices=('tumvi', 'keyframes', 'sim'),
        default=('tumvi', 'keyframes', 'sim'),
    )
    args = ap.parse_args()
    if 'tumvi' in args.only and cases.TUMVI.is_dir():
        emit(
            'real_world_tumvi',
            table(
                'TUM-VI, files as published (reference for Basalt/ORB-SLAM3 VIO: T_HE = I, dt ~ 0)',
                [
                    'file',
                    'run',
                    'verdict',
                    'codes / error',
                    'dt ms',
                    'drift ppm',
                    '|t| mm',
                    'rot deg',
                    '1-sigma ms / mm / deg',
                    'MoCap covers',
                    's',
                ],
                tumvi_rows(),
            ),
        )
    if 'keyframes' in args.only and cases.available():
        emit(
            'real_world_keyframes',
            table(
                'EuRoC estimates kept as keyframes only (0.3-3 Hz, seed 0), against the dense run',
                [
                    'pair',
                    'keyframes',
                    'verdict',
                    'codes',
                    'ddt ms',
                    'dT mm',
                    'dR deg',
                    '1-sigma ms / mm / deg',
                    's',
                ],
                keyframe_rows(),
            ),
            seeds='keyframes rng 0',
        )
    if 'sim' in args.only:
        emit(
            'real_world_sim',
            table(
                f"Simulated {DURATION_S / 60:.0f}-minute recordings at level {LEVEL:g}: error median / max, mean error over the continuous run's, truth within 3 sigma",
                [
                    'condition',
                    'runs',
                    'dt ms',
                    'T mm',
                    'R deg',
                    'x continuous (dt/T/R)',
                    'in 3 sigma',
                    'verdicts',
                    's',
                ],
                sim_rows(args.seeds),
            ),
            seeds=f'simulator 0..{args.seeds - 1}, dropouts/keyframes rng = seed',
        )


if __name__ == '__main__':
    main()
