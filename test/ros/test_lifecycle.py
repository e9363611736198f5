"""calibrator.main under a signal at the moments the start is most fragile: it exits 0,
quietly, and leaves no process behind."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytest.importorskip('rclpy')
pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]

#: Runs calibrator.main with a SIGINT sent to itself as soon as ``{target}`` has returned,
#: checks that the signal was noted (by the node's handler: rclpy's are not installed), then
#: prints the exit code and the number of child processes left (the worker,
#: multiprocessing's resource tracker).
SCRIPT = """
import multiprocessing, os, signal, time
import rclpy
from handeye_ros.ros import calibrator, lifecycle, node

owner, name = {target}
real = getattr(owner, name)

def signalled(*args, **kwargs):
    out = real(*args, **kwargs)
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.05)
    assert lifecycle.stop_requested() and rclpy.ok()
    return out

setattr(owner, name, signalled)
code = calibrator.main([])
print(code, len(multiprocessing.active_children()))
"""

TARGETS = {'init': "rclpy, 'init'", 'node': "node.CalibratorNode, '__init__'"}


@pytest.mark.parametrize('where', sorted(TARGETS))
def test_a_signal_during_the_start_exits_quietly_and_stops_the_worker(where: str) -> None:
    """A Ctrl-C just after rclpy.init (the node not made yet: main stops the worker) or just
    after the node is made (not spun: its close() stops the worker). Before the worker's stop ran in every path, the node hung on the worker's
    resource tracker in 1 of 100 stops of bench/node_lifecycle.py. Run in a fresh interpreter:
    rclpy's state is per process."""
    env = dict(
        os.environ,
        PYTHONPATH=str(ROOT),
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
    )
    proc = subprocess.run(
        [sys.executable, '-c', textwrap.dedent(SCRIPT.format(target=TARGETS[where]))],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ['0', '0'], proc.stdout + proc.stderr
    assert 'Traceback' not in proc.stderr, proc.stderr
