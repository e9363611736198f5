"""The built-in example: simulate a recording with known truth, calibrate it, compare.

A 60 s hand-held motion is simulated with the paper's protocol (MoCap 100 Hz, VIO 20 Hz with
frame-wise cumulative error at ``--level``, a random time offset, extrinsic and world alignment),
written as a ROS 2 bag (mcap: geometry_msgs/PoseStamped on /mocap/pose, nav_msgs/Odometry on
/vio/odom; or TUM files with ``--text``), calibrated by the offline tool exactly as a user would
run it, and the result printed beside the truth.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from ..core.arrays import Floats
from ..core.errors import InputError
from ..core.simulate import Truth, calibration_error, noise_level, simulate
from ..formats import write_tum
from ..formats.bag import write_recording
from . import offline
from .commands import prog


def main(argv: list[str] | None = None) -> int:
    """Run the example; returns the exit code."""
    p = argparse.ArgumentParser(prog=prog('demo'), description=__doc__.split('\n')[0])
    p.add_argument('--seed', type=int, default=7, help='simulation seed')
    p.add_argument(
        '--level',
        type=float,
        default=5.0,
        help="eye noise level of the paper's protocol, 0-10 (0.5 mm / 0.02 deg each)",
    )
    p.add_argument('--duration', type=float, default=60.0, help='seconds of motion')
    p.add_argument('--keep', metavar='DIR', help='write the files into DIR and keep them')
    p.add_argument('--text', action='store_true', help='TUM text files instead of a bag')
    args = p.parse_args(argv)
    try:
        noise_m, noise_deg = noise_level(args.level)
        rec = simulate(args.seed, duration_s=args.duration, noise_m=noise_m, noise_deg=noise_deg)
    except InputError as err:
        p.error(str(err))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.keep or tmp)
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            p.error(f'--keep {out}: cannot make the folder there ({err.strerror})')
        res = out / 'result.json'
        what = (
            f'hand {len(rec.hand)} poses at 100 Hz, eye {len(rec.eye)} poses at 20 Hz with '
            f'noise level {args.level:g} ({noise_m * 1e3:.1f} mm / {noise_deg:.2f} deg per '
            'frame, cumulative)'
        )
        if args.text:
            hand, eye = out / 'hand_mocap.txt', out / 'eye_vio.txt'
            write_tum(hand, rec.hand)
            write_tum(eye, rec.eye)
            cmd = ['--hand', str(hand), '--eye', str(eye), '-o', str(res)]
        else:
            bag = out / 'recording'
            if bag.exists():
                shutil.rmtree(bag)
            write_recording(
                bag,
                [
                    ('/mocap/pose', 'PoseStamped', rec.hand, 'mocap', 'marker'),
                    ('/vio/odom', 'Odometry', rec.eye, 'odom', 'imu'),
                ],
                'mcap',
            )
            what += ' -> bag with /mocap/pose (PoseStamped) and /vio/odom (Odometry)'
            cmd = ['--bag', str(bag), '-o', str(res)]
        print(f'simulated {args.duration:.0f} s: {what}')
        print(f'$ offline_calibrate {" ".join(cmd)}\n')
        code = offline.main(cmd)
        if code:
            return code
        result = json.loads(res.read_text())

    _print_beside_truth(result, rec.truth)
    return 0


def _print_beside_truth(result: dict[str, Any], t: Truth) -> None:
    """The result's dt and T_HE beside the simulation's truth, their errors, the reported
    1-sigma and the verdict."""
    q = np.asarray(result['extrinsic']['rotation'])
    p_he = np.asarray(result['extrinsic']['translation'])
    err = calibration_error(t, result['time_offset'], q, p_he)
    print('\nresult beside the truth')
    print(f'  {"":22s}{"estimated":>36s}{"true":>36s}{"error":>14s}')
    print(
        f'  {"time offset [ms]":22s}{result["time_offset"] * 1e3:36.3f}'
        f'{t.time_offset_s * 1e3:36.3f}{err.time_offset_s * 1e3:11.3f} ms'
    )
    print(
        f'  {"T_HE translation [m]":22s}{_vec(p_he):>36s}{_vec(t.p_HE):>36s}'
        f'{err.translation_m * 1e3:11.1f} mm'
    )
    true_q = t.q_HE * (1.0 if np.dot(t.q_HE, q) >= 0 else -1.0)
    print(
        f'  {"T_HE rotation [xyzw]":22s}{_vec(q):>36s}{_vec(true_q):>36s}'
        f'{err.rotation_deg:10.3f} deg'
    )
    if result.get('std'):
        s = result['std']
        print(
            f'\nreported 1-sigma (batch stage): time offset {s["time_offset"] * 1e3:.3f} ms, '
            f'translation {np.linalg.norm(s["translation"]) * 1e3:.1f} mm, rotation '
            f'{np.degrees(np.linalg.norm(s["rotation"])):.3f} deg (norms over the axes)'
        )
    q = result['quality']
    print(f'verdict: {q["verdict"]}' + ''.join(f'\n  - {r["message"]}' for r in q['reasons']))


def _vec(v: Floats) -> str:
    return ' '.join(f'{x:+.4f}' for x in v)


if __name__ == '__main__':
    sys.exit(main())
