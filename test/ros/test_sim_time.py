"""The calibrator under simulated time (``use_sim_time``), as ``ros2 bag play --clock`` drives
it: its status goes on and says when /clock stands still, and a signal stops it (and its
workers) whatever /clock does."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from ros_support import (
    Processes,
    resolve_executable,
    ros_available,
    running,
    wait_for,
)

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(not ros_available(), reason='rclpy / colcon not installed'),
]

#: A /clock publisher at 100 Hz of simulated time for ``seconds`` of wall time once the node
#: subscribes, then silent (a bag paused or ended) until it is stopped.
CLOCK = """
import sys, time, rclpy
from rosgraph_msgs.msg import Clock
rclpy.init()
node = rclpy.create_node('clock_player')
pub = node.create_publisher(Clock, '/clock', 10)
deadline = time.monotonic() + 30.0  # the node's subscription first: on a loaded machine
while pub.get_subscription_count() == 0 and time.monotonic() < deadline:  # discovery takes s
    time.sleep(0.05)
end, t = time.monotonic() + float(sys.argv[1]), 1_700_000_000_000_000_000
while time.monotonic() < end:
    t += 10_000_000
    pub.publish(Clock(clock=rclpy.time.Time(nanoseconds=t).to_msg()))
    time.sleep(0.01)
print('paused', flush=True)
try:
    while True:
        time.sleep(0.1)
except KeyboardInterrupt:
    pass
"""


def _start(ros: Processes, install: Path) -> subprocess.Popen:
    exe = resolve_executable(ros.env, 'handeye_ros', 'calibrator')
    params = install / 'handeye_ros' / 'share' / 'handeye_ros' / 'config' / 'calibrator.yaml'
    args = ['--ros-args', '--params-file', str(params), '-p', 'use_sim_time:=true']
    return ros.start([str(exe), *args], 'node')


def _says(ros: Processes, p: subprocess.Popen, words: str, timeout: float = 60.0) -> None:
    assert wait_for(lambda: words in ros.output(p)[1] or p.poll() is not None, timeout), (
        words,
        ros.output(p),
    )
    assert p.poll() is None, ros.output(p)


def _stopped_cleanly(ros: Processes, p: subprocess.Popen) -> None:
    """Exit code 0, no traceback, and none of the node's processes (its workers) left."""
    p.wait(timeout=10)
    assert p.returncode == 0, ros.output(p)
    assert 'Traceback' not in ros.output(p)[1], ros.output(p)
    assert wait_for(lambda: not running('sid', p.pid), 5.0, 0.1), running('sid', p.pid)


def test_no_clock_yet_the_status_says_so_and_ctrl_c_stops_it(ros: Processes, install) -> None:
    node = _start(ros, install)
    _says(ros, node, 'no /clock message has come yet')
    os.killpg(node.pid, signal.SIGINT)
    _stopped_cleanly(ros, node)


def test_a_paused_clock_is_said_and_sigterm_stops_it(ros: Processes, install) -> None:
    node = _start(ros, install)
    _says(ros, node, 'buffering hand')
    player = ros.start([sys.executable, '-c', CLOCK, '3'], 'clock')
    assert wait_for(lambda: 'paused' in ros.output(player)[0], 30), ros.output(player)
    _says(ros, node, '/clock has stood still')
    node.send_signal(signal.SIGTERM)
    _stopped_cleanly(ros, node)
