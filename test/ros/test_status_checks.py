"""The readiness status's own schedule, on real buffers and their snapshots' calibrations without a node: a
check decided on as `done` only when its own snapshot held full buffers. (Live, the same runs in
test_node_guidance.py; auto mode's policy alone in test_status.py.)"""

from __future__ import annotations

import time

import numpy as np
import pytest

pytest.importorskip('rclpy')

from rclpy.clock import Clock
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.logging import get_logger
from rclpy.task import Future

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.simulate import noise_level, simulate
from handeye_ros.ros.auto_mode import State
from handeye_ros.ros.host import Job
from handeye_ros.ros.status import ReadinessStatus
from handeye_ros.stream import Recorder
from handeye_ros.stream.config import StreamConfig
from handeye_ros.stream.recorder import Snapshot


class Host:
    """What the status reads of a node (ros/host.py's StatusHost), over a real Recorder whose
    buffers the test fills; its calibrations are the test's to run."""

    def __init__(self, buffer_s: float) -> None:
        self.calib_cfg = CalibrationConfig()
        self.recorder = Recorder(StreamConfig(buffer_duration=buffer_s))
        self.last_seen: dict[str, float] = {}
        self.last_ticked: dict[str, float] = {}
        self.last_received: dict[str, float] = {}
        self.taken_late: dict[str, float] = {}
        self.checks: list[Snapshot] = []  # the snapshots the status asked to calibrate
        self.closing = False
        self.busy = False
        self.poses = self

    def why_no_data(self) -> str | None:
        return None

    def calibrate(self, job: Job = Job.CALL) -> Future | None:
        self.checks.append(self.recorder.snapshot())
        self.busy = True
        return Future()

    def get_clock(self) -> Clock:
        return Clock()

    def get_logger(self) -> RcutilsLogger:
        return get_logger('test_status_checks')

    def get_fully_qualified_name(self) -> str:
        return '/calibrator'


def test_done_only_for_a_check_of_full_buffers() -> None:
    """A check of 17 s of 20-s buffers that fill while it runs is not `done`: the full buffers
    are checked next, and that check is."""
    nm, nd = noise_level(3.0)
    rec = simulate(1, duration_s=30.0, noise_m=nm, noise_deg=nd)
    host = Host(20.0)
    status = ReadinessStatus(host, True, lambda _: None)
    buffers = host.recorder.buffers

    def feed(until_s: float) -> None:
        """Both streams' poses up to ``until_s`` of the recording, not yet buffered."""
        for stream, traj in (('hand', rec.hand), ('eye', rec.eye)):
            t = (traj.t_ns - traj.t_ns[0]) * 1e-9
            newest = buffers[stream].newest_ns or -1
            for k in np.flatnonzero((traj.t_ns > newest) & (t <= until_s)):
                buffers[stream].add((int(traj.t_ns[k]), *traj.p_xyz[k], *traj.q_xyzw[k]))
            now = time.monotonic()  # both streams flow
            for seen in (host.last_seen, host.last_ticked, host.last_received):
                seen[stream] = now
            host.taken_late[stream] = 0.0

    def run_check() -> None:
        snap = host.checks[-1]
        result = snap.result(host.calib_cfg)
        host.busy = False
        status.took(result, None, Job.CHECK, snap.span_s, 0.0)

    feed(17.0)
    status.tick()
    full = lambda: any(b.dropped for b in buffers.values())
    assert len(host.checks) == 1 and not full()
    feed(25.0)  # the buffers fill (and drop) while the check runs
    assert full()
    run_check()
    assert status.auto.state is not State.DONE, status.auto
    status.tick()  # the full buffers span more than the check did: checked again
    assert len(host.checks) == 2
    run_check()
    assert status.auto.state in (State.DONE, State.CONVERGED, State.STALLED), status.auto
