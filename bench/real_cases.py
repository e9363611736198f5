"""Semi-synthetic real cases (bench/cases.py): real VIO noise and drift, known truth.

For every pair in ../shared/data/real the ground truth is moved to the Vicon marker frame with
EuRoC's T_BS and its clock shifted by each of SHIFTS_S; ours estimates the offset itself,
OpenCV's five methods get the applied shift (the true offset up to the streams' own few ms).
The Vicon-room flights (V1_*, V2_*) and the Machine Hall ones (MH_*, ~80 m paths with large
drift) are reported apart. "identity" is our rotation result on the unmodified pair, whose
truth is the identity: it shows the estimate's own attitude bias against the ground truth,
which bounds what any calibration can reach on that pair.

Usage: python bench/real_cases.py [--only V1_01 ...]
"""

from __future__ import annotations

import argparse
import time

import cases
import common  # noqa: F401
import numpy as np
from common import OPENCV_METHODS, cv2, emit, opencv_hand_eye, opencv_inputs, table

from handeye_ros.core.association import associate
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import Truth, calibration_error

SHIFTS_S = (0.0873, -0.2315)


def evaluate_pair(
    pair: cases.RealPair, config: CalibrationConfig | None = None
) -> dict[str, float]:
    gt, est = cases.load(pair)
    q, p = cases.true_extrinsic()
    identity = calibrate(gt, est, CalibrationConfig(batch=False))
    dt_err, ours, best_cv, lin, lin_dt, std = [], [], [], [], [], []
    elapsed = 0.0
    for shift in SHIFTS_S:
        truth = Truth(shift, q, p, q, p)
        hand = cases.to_marker_frame(gt, shift)
        t0 = time.perf_counter()
        res = calibrate(hand, est, config)
        elapsed = max(elapsed, time.perf_counter() - t0)
        e = calibration_error(truth, res.time_offset_s, res.q_HE, res.p_HE)
        r0 = calibrate(hand, est, CalibrationConfig(batch=False))
        e0 = calibration_error(truth, r0.time_offset_s, r0.q_HE, r0.p_HE)
        lin.append((e0.translation_m, e0.rotation_deg))
        lin_dt.append(r0.time_offset_s - shift)
        std.append(res.batch.std[0] if res.batch is not None else np.nan)
        dt_err.append(res.time_offset_s - shift)
        ours.append((e.translation_m, e.rotation_deg))
        if cv2 is not None:
            pairs = associate(hand, est, shift)
            cv = [
                calibration_error(truth, shift, *opencv_hand_eye(pairs, idx, method))
                for idx in opencv_inputs(pairs).values()
                for method in OPENCV_METHODS
            ]
            best_cv.append((min(c.translation_m for c in cv), min(c.rotation_deg for c in cv)))
    ours_a, cv_a = np.asarray(ours), np.asarray(best_cv) if best_cv else np.full((1, 2), np.nan)
    lin_a = np.asarray(lin)
    return {
        'lin_dt_err_ms': float(np.max(np.abs(lin_dt)) * 1e3),
        'lin_trans_mm': float(lin_a[:, 0].mean() * 1e3),
        'lin_rot_deg': float(lin_a[:, 1].mean()),
        'std_dt_ms': float(np.mean(std) * 1e3),
        'dt_err_ms': float(np.max(np.abs(dt_err)) * 1e3),
        'dt_bias_ms': float(np.mean(dt_err) * 1e3),
        'trans_mm': float(ours_a[:, 0].mean() * 1e3),
        'rot_deg': float(ours_a[:, 1].mean()),
        'cv_trans_mm': float(cv_a[:, 0].mean() * 1e3),
        'cv_rot_deg': float(cv_a[:, 1].mean()),
        'identity_deg': float(np.degrees(2 * np.arccos(min(1.0, abs(identity.q_HE[3]))))),
        'inliers': f'{res.linear.n_inliers}/{res.linear.n_motions}',
        'seconds': elapsed,
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--only', nargs='+', help='pair names (default: all)')
    args = p.parse_args()
    config = CalibrationConfig()
    if not cases.available():
        print(f'real data not found at {cases.REAL_DATA}: nothing to do')
        return
    header = [
        'pair',
        'lin max|dt err| ms',
        'lin mm',
        'lin deg',
        'max|dt err| ms',
        'dt err mean ms',
        '1-sigma dt ms',
        'trans mm',
        'rot deg',
        'OpenCV best mm',
        'OpenCV best deg',
        'identity deg',
        'inliers',
        'time s',
    ]
    for title, room in (('Vicon room (V1_*, V2_*)', True), ('Machine Hall (MH_*)', False)):
        rows = []
        for pair in (p for p in cases.PAIRS if p.vicon_room == room):
            if args.only and pair.name not in args.only:
                continue
            r = evaluate_pair(pair, config)
            rows.append(
                [
                    pair.name,
                    r['lin_dt_err_ms'],
                    r['lin_trans_mm'],
                    r['lin_rot_deg'],
                    r['dt_err_ms'],
                    r['dt_bias_ms'],
                    r['std_dt_ms'],
                    r['trans_mm'],
                    r['rot_deg'],
                    r['cv_trans_mm'],
                    r['cv_rot_deg'],
                    r['identity_deg'],
                    r['inliers'],
                    r['seconds'],
                ]
            )
        if not rows:
            continue
        mean = (
            ['mean'] + [float(np.mean([row[k] for row in rows])) for k in range(1, 12)] + ['', '']
        )
        emit(
            f'real_{"vicon" if room else "machine_hall"}',
            table(
                f'{title}: offset estimated by us (shifts {", ".join(f"{s:+g}" for s in SHIFTS_S)} s'
                ' applied); lin = stages 1+2, then the batch stage; OpenCV given the applied shift '
                '(best method and input per column)',
                header,
                rows + [mean],
            ),
        )


if __name__ == '__main__':
    main()
