"""lifecycle.spin at the moments a signal can reach it: the clean-up always runs."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytest.importorskip('rclpy')
pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[1]


def test_a_signal_between_rclpy_init_and_spin_still_closes() -> None:
    """A Ctrl-C after rclpy.init and before the spin (the node's start) leaves a context that rclpy's handler has shut down; an executor cannot be made
    on it. spin() must still call close() (which stops the worker; before, it did not, and
    the node hung on the worker's resource tracker: 1 in 100 stops of bench/node_lifecycle.py)
    and return quietly. Run in a fresh interpreter: rclpy's state is per process."""
    code = textwrap.dedent(
        """
        import os, signal, time
        import rclpy
        from handeye_ros.ros import lifecycle
        lifecycle.quiet_start()
        rclpy.init()
        node = rclpy.create_node('lifecycle_test')
        os.kill(os.getpid(), signal.SIGINT)  # rclpy's handler shuts the context down
        deadline = time.monotonic() + 10
        while rclpy.ok() and time.monotonic() < deadline:
            time.sleep(0.01)
        assert not rclpy.ok() and lifecycle.stop_requested()
        closed = []
        lifecycle.spin(node, lambda: closed.append(True))
        print('closed' if closed else 'not closed')
        """
    )
    env = dict(
        os.environ,
        PYTHONPATH=str(ROOT),
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
    )
    proc = subprocess.run(
        [sys.executable, '-c', code],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1] == 'closed', proc.stdout
    assert 'Traceback' not in proc.stderr, proc.stderr
