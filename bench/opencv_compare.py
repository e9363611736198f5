"""Ours vs OpenCV's calibrateHandEye on the paper's protocol (Section IV-A).

Ours estimates the time offset itself; OpenCV (Tsai, Park, Horaud, Andreff, Daniilidis) gets
the pose pairs at the TRUE offset, fed two ways: the rotation-constrained keyframe poses that
our linear stage uses (consecutive keyframes >= 5 deg apart), and the poses every 0.5 s. OpenCV
forms motions between all pairs of the poses it is given, so long-range motions carry the VIO's
accumulated drift; which input suits each method best differs, so the best of the two counts.

Usage: python bench/opencv_compare.py [--seeds 20] [--levels 0 5 10]
"""

from __future__ import annotations

import argparse
import time

import cases
import common  # noqa: F401
import numpy as np
from cases import PROTOCOL_SEEDS
from common import emit, table

from handeye_ros.core.association import PosePairs, associate
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.geometry import inverse, quat_from_matrix
from handeye_ros.core.linear.keyframes import rotation_keyframes
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import Truth, calibration_error

try:
    import cv2
except ImportError:  # benchmark-only extra
    cv2 = None

METHODS = ('TSAI', 'PARK', 'HORAUD', 'ANDREFF', 'DANIILIDIS')


def opencv_hand_eye(
    pairs: PosePairs, idx: np.ndarray, method: str
) -> tuple[np.ndarray, np.ndarray]:
    """T_HE by cv2.calibrateHandEye from the pairs at ``idx``.

    OpenCV's eye-in-hand names: gripper = H in base = G (our hand pose T_GH); target = W seen
    from cam = E (T_EW = T_WE^-1); the result cam2gripper is T_HE.
    """
    R_EW, p_EW = inverse((pairs.R_WE[idx], pairs.p_WE[idx]))
    R, t = cv2.calibrateHandEye(
        list(pairs.R_GH[idx]),
        list(pairs.p_GH[idx]),
        list(R_EW),
        list(p_EW),
        method=getattr(cv2, f'CALIB_HAND_EYE_{method}'),
    )
    if not (np.isfinite(R).all() and np.isfinite(t).all()):  # a failed method: NaN result
        return np.array([0.0, 0.0, 0.0, 1.0]), np.full(3, np.inf)
    return quat_from_matrix(R), t.ravel()


def input_sets(pairs: PosePairs) -> dict[str, np.ndarray]:
    i, j = rotation_keyframes(pairs.R_GH, np.deg2rad(5.0))
    step = max(1, round(0.5 / np.median(np.diff(pairs.t_eye_s))))
    return {
        'keyframes': np.unique(np.concatenate((i, j))),
        'every 0.5 s': np.arange(0, pairs.t_eye_s.size, step),
    }


#: Our configurations, spelled out: linear means stages 1-2 without the batch stage.
OURS = {
    'ours linear (dt estimated)': CalibrationConfig(batch=False),
    'ours with batch (dt estimated)': CalibrationConfig(batch=True),
}


def run(seeds: range, level: float) -> dict[str, np.ndarray]:
    """Per method and input: errors (seeds, 3) = |dt| s, translation m, rotation deg."""
    out: dict[str, list] = {}
    for seed in seeds:
        rec = cases.protocol(level, seed)
        t: Truth = rec.truth
        for name, cfg in OURS.items():
            res = calibrate(rec.hand, rec.eye, cfg)
            e = calibration_error(t, res.time_offset_s, res.q_HE, res.p_HE)
            out.setdefault(name, []).append((e.time_offset_s, e.translation_m, e.rotation_deg))
        if cv2 is None:
            continue
        pairs = associate(rec.hand, rec.eye, t.time_offset_s)
        for name, idx in input_sets(pairs).items():
            for method in METHODS:
                q, p = opencv_hand_eye(pairs, idx, method)
                e = calibration_error(t, t.time_offset_s, q, p)
                out.setdefault(f'OpenCV {method} / {name}', []).append(
                    (0.0, e.translation_m, e.rotation_deg)
                )
    return {k: np.asarray(v) for k, v in out.items()}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--seeds', type=int, default=20)
    p.add_argument('--levels', type=float, nargs='+', default=[0.0, 5.0, 10.0])
    args = p.parse_args()
    if cv2 is None:
        print('opencv-python-headless is not installed (pip install .[bench]): ours only')
    for level in args.levels:
        t0 = time.perf_counter()
        errs = run(range(args.seeds), level)
        rows = [
            [k, v[:, 1].mean() * 1e3, v[:, 2].mean(), np.median(v[:, 1]) * 1e3, np.median(v[:, 2])]
            for k, v in errs.items()
        ]
        cv_rows = [r for r in rows if r[0].startswith('OpenCV')]
        lines = table(
            f'Noise level {level:g} ({args.seeds} seeds): extrinsic error; OpenCV '
            'given the true offset',
            ['method / input', 'trans mm', 'rot deg', 'median mm', 'median deg'],
            rows,
        )
        if cv_rows:
            bt = min(cv_rows, key=lambda r: r[1])
            br = min(cv_rows, key=lambda r: r[2])

            def ratio(a: float, b: float) -> str:
                return f'{a / b:.2f}' if b > 1e-6 else 'n/a (OpenCV exact)'

            lines += (
                f'\nbest OpenCV: translation {bt[1]:.1f} mm ({bt[0]}), rotation '
                f'{br[2]:.3f} deg ({br[0]})'
            )
            for name in OURS:
                ours = errs[name]
                lines += (
                    f'\n{name} / best OpenCV: translation '
                    f'{ratio(ours[:, 1].mean() * 1e3, bt[1])}, rotation '
                    f'{ratio(ours[:, 2].mean(), br[2])} (target <= 0.5 at level 10); '
                    f'|dt| {ours[:, 0].mean() * 1e3:.3f} ms'
                )
        emit(
            f'opencv_level{level:g}',
            lines + f'\n({time.perf_counter() - t0:.1f} s)',
            PROTOCOL_SEEDS,
        )


if __name__ == '__main__':
    main()
