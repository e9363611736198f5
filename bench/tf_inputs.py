"""Issue 12, item 4: real recordings delivered as /tf and as mocap4r2 rigid bodies, with the
defects such inputs have, through ``offline_calibrate --bag`` as a user runs it.

For each real pair of ../shared/data/real (bench/cases.py: EuRoC ground truth moved to the
Vicon marker frame and 0.1 s onto another clock, a real VIO estimate) the very same poses are
written as bags in the layouts of handeye_ros.formats.bag, and each is calibrated:

- ``plain``: PoseStamped + Odometry (the reference);
- ``tf``: both streams on /tf (world -> rig moving, rig -> marker static logged after the
  first samples; the eye as the inverse link imu -> odom), mcap;
- ``tf ros1 /names``: the same in a ROS 1 bag with ROS 1 frame names (leading slashes);
- ``bodies``: the hand as one rigid body among three per mocap4r2 message, mcap;
- ``bodies humble``: the same in sqlite3 without message definitions (as Humble records);
- ``bodies lost 2%``: the body missing from one frame in 50 (occlusion);
- ``tf 2 moving``, ``tf wrong frame``, ``bodies wrong name``: selections that cannot work,
  which must end in a clear error (exit 1, no traceback) naming what the bag holds.

Figures: exit code, traceback, dt and T_HE against the plain reference (exact to rounding
where the poses are the same), the warnings, and the replay rate (messages per second) of
the /tf bag against the plain one.

Usage: python bench/tf_inputs.py [--pairs 'V1_01 openvins' 'MH_03 stereo' ...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cases
import common  # noqa: F401  (puts the repository on sys.path)
import numpy as np
from common import ROOT, emit, table

from handeye_ros.formats.bag import BagWriter, pose_messages, write_recording

sys.path.insert(0, str(ROOT / 'test'))  # the bag layouts the tests write
from bag_layouts import (
    RIGID_BODIES_TOPIC,
    TF_SELECTORS,
    write_rigid_bodies_recording,
    write_tf_recording,
)

from handeye_ros.formats.messages import transform_stamped

DEFAULT_PAIRS = ('V1_01 openvins', 'MH_03 stereo', 'V2_02 mono')
TF_ARGS = ('--hand-topic', TF_SELECTORS['hand'], '--eye-topic', TF_SELECTORS['eye'])
BODY_ARGS = ('--hand-topic', f'{RIGID_BODIES_TOPIC}:rig')


def _two_moving(path: Path, hand, eye) -> tuple[str, ...]:
    """The eye through map -> odom (moving, identity) -> imu: a SLAM's tree."""
    with BagWriter(path) as w:
        T = w.store.types
        items = []
        for t, m in pose_messages(w.store, eye, 'TFMessage', 'odom', 'imu'):
            fix = transform_stamped(
                w.store.types, t, 'map', 'odom', (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)
            )
            items.append(
                (
                    t,
                    1,
                    '/tf',
                    'tf2_msgs/msg/TFMessage',
                    T['tf2_msgs/msg/TFMessage'](transforms=[fix, *m.transforms]),
                )
            )
        items += [
            (t, 0, '/mocap/pose', 'geometry_msgs/msg/PoseStamped', m)
            for t, m in pose_messages(w.store, hand, 'PoseStamped', 'mocap', 'marker')
        ]
        items.sort(key=lambda x: (x[0], x[1]))
        for t, _, topic, mt, m in items:
            w.write(topic, mt, t, m)
    return ('--eye-topic', '/tf:map.imu')


def _sqlite_without_definitions(path: Path, hand, eye) -> tuple[str, ...]:
    import sqlite3

    write_rigid_bodies_recording(path, hand, eye, 'sqlite3')
    with sqlite3.connect(next(path.glob('*.db3'))) as con:
        con.execute('DELETE FROM message_definitions')
    return BODY_ARGS


CASES = {
    'plain': lambda p, h, e: (
        write_recording(
            p,
            [
                ('/mocap/pose', 'PoseStamped', h, 'mocap', 'marker'),
                ('/vio/odom', 'Odometry', e, 'odom', 'imu'),
            ],
        ),
        (),
    )[1],
    'tf': lambda p, h, e: (write_tf_recording(p, h, e), TF_ARGS)[1],
    'tf ros1 /names': lambda p, h, e: (
        write_tf_recording(p.with_suffix('.bag'), h, e, 'ros1', slash='/'),
        TF_ARGS,
    )[1],
    'bodies': lambda p, h, e: (write_rigid_bodies_recording(p, h, e), BODY_ARGS)[1],
    'bodies humble': _sqlite_without_definitions,
    'bodies lost 2%': lambda p, h, e: (
        write_rigid_bodies_recording(p, h, e, lost_every=50),
        BODY_ARGS,
    )[1],
    'tf 2 moving': _two_moving,
    'tf wrong frame': lambda p, h, e: (
        write_tf_recording(p, h, e),
        ('--hand-topic', '/tf:world.markr', TF_ARGS[2], TF_ARGS[3]),
    )[1],
    'bodies wrong name': lambda p, h, e: (
        write_rigid_bodies_recording(p, h, e),
        ('--hand-topic', f'{RIGID_BODIES_TOPIC}:Rig'),
    )[1],
}
#: Cases that must end in a clear error.
REFUSED = ('tf 2 moving', 'tf wrong frame', 'bodies wrong name')


def run(bag: Path, args: tuple[str, ...]) -> tuple[int, dict | None, str, float]:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    t0 = time.perf_counter()
    proc = subprocess.run(
        [
            sys.executable,
            '-m',
            'handeye_ros.offline',
            '--bag',
            str(bag),
            '--json',
            '--no-evaluation',
            *args,
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
        check=False,
    )
    seconds = time.perf_counter() - t0
    data = json.loads(proc.stdout) if proc.returncode == 0 else None
    return proc.returncode, data, proc.stderr, seconds


def replay_rate(bag: Path, args: tuple[str, ...]) -> float:
    """Messages per second of the replay alone (in this process, best of 3)."""
    from handeye_ros.app.replay import replay
    from handeye_ros.stream import StreamConfig

    cfg = StreamConfig(
        **({'hand_topic': args[1]} if args else {}),
        **({'eye_topic': args[3]} if len(args) > 2 else {}),
    )
    given = {'hand': bool(args), 'eye': len(args) > 2}
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        rec = replay(bag, cfg, given, progress=False)
        best = min(best, time.perf_counter() - t0)
    n = sum(s.received for s in rec.stats().values())
    return n / best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--pairs', nargs='*', default=list(DEFAULT_PAIRS))
    args = ap.parse_args()
    if not cases.available():
        print('real data absent (../shared/data/real): nothing to measure', file=sys.stderr)
        return
    rows, rates = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for pair in cases.PAIRS:
            if pair.name not in args.pairs:
                continue
            gt, est = cases.load(pair)
            hand = cases.to_marker_frame(gt, cases.SHIFT_S)
            ref = None
            for case, make in CASES.items():
                bag = Path(tmp) / f'{pair.name}_{case}'.replace(' ', '_').replace('/', '')
                sel = make(bag, hand, est)
                if case == 'tf ros1 /names':
                    bag = bag.with_suffix('.bag')
                code, d, err, seconds = run(bag, sel)
                tb = 'Traceback' in err
                if case == 'plain':
                    ref = d
                if d is not None and ref is not None:
                    ddt = abs(d['time_offset'] - ref['time_offset']) * 1e3
                    dT = np.abs(
                        np.asarray(d['extrinsic']['matrix'])
                        - np.asarray(ref['extrinsic']['matrix'])
                    ).max()
                    warn = '; '.join(w for w in d['warnings'] if 'stream' in w)[:90]
                    verdict = d['quality']['verdict']
                    what = f'{ddt:.1e} ms, {dT:.1e}'
                else:
                    verdict, what = '-', '-'
                    warn = err.strip().splitlines()[-1][:160] if err.strip() else ''
                ok = (code == 1 and not tb) if case in REFUSED else (code == 0 and not tb)
                rows.append(
                    [
                        pair.name,
                        case,
                        code,
                        'yes' if tb else 'no',
                        verdict,
                        what,
                        'ok' if ok else 'WRONG',
                        warn,
                    ]
                )
                if case in ('plain', 'tf', 'bodies'):
                    rates.append(
                        [pair.name, case, f'{replay_rate(bag, sel):,.0f}', f'{seconds:.1f}']
                    )
    text = table(
        'Real pairs as /tf and mocap4r2 bags (offline_calibrate --bag)',
        [
            'pair',
            'case',
            'exit',
            'traceback',
            'verdict',
            'vs plain: |d dt|, max |d T_HE|',
            'expected',
            'warning or error (cut)',
        ],
        rows,
    )
    text += '\n' + table(
        'Replay rate (messages/s, best of 3) and the whole command (s)',
        ['pair', 'case', 'replay msg/s', 'offline_calibrate s'],
        rates,
    )
    emit('tf_inputs', text, seeds={'clock_shift_s': cases.SHIFT_S, 'pairs': args.pairs})


if __name__ == '__main__':
    main()
