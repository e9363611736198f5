"""The calibrator under simulated time with no /clock (before `ros2 bag play --clock` starts, on
pause, after the end): seconds from Ctrl-C or SIGTERM to its exit and to the last of its
processes (the workers) gone, started as `ros2 run` would and under `ros2 launch`.

Needs the workspace the README builds (colcon, the venv as underlay) and, for launch, the ros2
command line and .interfaces (scripts/ros2cli, scripts/interfaces); builds it in a temporary
folder.

Usage: python bench/sim_time_stop.py [--stops N]
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import common  # noqa: F401  (first: puts the project on sys.path)
from common import ROOT, emit, table

sys.path.insert(0, str(ROOT / 'test'))
from ros_support import build_workspace, ros_env, running, with_interfaces


def _stop(cmd: list[str], env: dict, how: str) -> tuple[int, float, float]:
    """(exit code, s to exit, s until no process of its session runs) of one stop."""
    p = subprocess.Popen(
        cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        start_new_session=True,
    )  # fmt: skip
    seen, deadline = '', time.monotonic() + 60
    while 'waiting for /clock' not in seen and time.monotonic() < deadline:
        seen += p.stdout.readline()
    t0 = time.monotonic()
    if how == 'Ctrl-C':
        os.killpg(p.pid, signal.SIGINT)
    else:
        p.send_signal(signal.SIGTERM)
    code = p.wait(timeout=30)
    exited = time.monotonic() - t0
    while running('sid', p.pid) and time.monotonic() - t0 < 30:
        time.sleep(0.01)
    return code, exited, time.monotonic() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--stops', type=int, default=5)
    a = ap.parse_args()
    ws = Path(tempfile.mkdtemp(prefix='sim_time_stop_'))
    install = build_workspace(ws)
    env = {**ros_env(install), 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    exe = install / 'handeye_ros' / 'lib' / 'handeye_ros' / 'calibrator'
    params = install / 'handeye_ros' / 'share' / 'handeye_ros' / 'config' / 'calibrator.yaml'
    ways = {
        'ros2 run': [
            str(exe),
            '--ros-args',
            '--params-file',
            str(params),
            '-p',
            'use_sim_time:=true',
        ]
    }
    launch_env = with_interfaces(env)
    ros2 = Path(sys.executable).parent / 'ros2'
    if launch_env is not None and ros2.exists():
        script = (
            f'set +u && . {install}/setup.bash && exec {ros2} launch handeye_ros '
            'calibrator.launch.py use_sim_time:=true'
        )
        ways['ros2 launch'] = ['bash', '-c', script]
    rows = []
    for way, cmd in ways.items():
        for how in ('Ctrl-C', 'SIGTERM'):
            runs = [
                _stop(cmd, launch_env if way == 'ros2 launch' else env, how)
                for _ in range(a.stops)
            ]
            codes = sorted({c for c, _, _ in runs})
            rows.append(
                [
                    way,
                    how,
                    len(runs),
                    ','.join(map(str, codes)),
                    f'{min(r[1] for r in runs):.2f}-{max(r[1] for r in runs):.2f}',
                    f'{max(r[2] for r in runs):.2f}',
                ]
            )
    header = ['started by', 'signal', 'stops', 'exit codes', 'to exit s', 'all gone s (max)']
    emit('sim_time_stop', table('sim_time_stop: use_sim_time, no /clock', header, rows))


if __name__ == '__main__':
    main()
