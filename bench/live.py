"""What the live benchmarks share: the environment of every rclpy process they start (localhost
discovery on a random domain), processes started and stopped as a terminal does, their CPU and
memory, and rclpy nodes of the benchmark's own process (:class:`Spun`, :class:`Probe`).
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import common

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(1, 101)))
ENV = dict(
    os.environ,
    PYTHONPATH=str(common.ROOT) + os.pathsep + os.environ.get('PYTHONPATH', ''),
    PYTHONUNBUFFERED='1',
)


def cpu_s(pid: int) -> float:
    """User + system CPU time of a process so far [s] (0 once it is gone)."""
    try:
        fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def children(pid: int) -> list[int]:
    out = subprocess.run(
        ['ps', '-o', 'pid=', '--ppid', str(pid)], capture_output=True, text=True, check=False
    )
    return [int(x) for x in out.stdout.split()]


def rss_mb(pid: int) -> float:
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
    return float('nan')


class Spun:
    """An rclpy node of this process, ``name``, spun in a thread from :meth:`spin` on (once its
    subscriptions are made)."""

    def __init__(self, name: str) -> None:
        import rclpy
        from rclpy.node import Node

        rclpy.init()
        self.rclpy = rclpy
        self.node = Node(name)

    def spin(self) -> None:
        from rclpy.executors import SingleThreadedExecutor

        self.executor = SingleThreadedExecutor()
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.executor.shutdown()
        self.thread.join(timeout=5.0)
        self.node.destroy_node()
        self.rclpy.try_shutdown()


class Probe(Spun):
    """An rclpy node in this process: latest /diagnostics and Trigger calls."""

    def __init__(self) -> None:
        from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
        from std_srvs.srv import Trigger

        super().__init__('bench_probe')
        self.Trigger = Trigger
        #: the latest status of each (node, 'hand stream' | 'eye stream' | ...), names as
        #: /diagnostics gives them ('calibrator: hand stream' -> ('calibrator', 'hand stream'))
        self.diag: dict[tuple[str, str], dict[str, str]] = {}
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 10)
        #: when each computed ~/status came (monotonic s; the ones with figures, not "waiting")
        self.status_t: list[float] = []
        self.node.create_subscription(DiagnosticStatus, '/calibrator/status', self._on_status, 10)
        self.client = self.node.create_client(Trigger, '/calibrator/calibrate')
        self.spin()

    def _on_diag(self, msg) -> None:
        for st in msg.status:
            node, _, what = st.name.rpartition(': ')
            self.diag[node.strip('/ '), what] = {kv.key: kv.value for kv in st.values}

    def _on_status(self, msg) -> None:
        if any(kv.key == 'span_s' for kv in msg.values):
            self.status_t.append(time.monotonic())

    def stream(self, name: str, node: str = 'calibrator') -> dict[str, str]:
        """The latest diagnostics of a node's stream ('hand' or 'eye')."""
        return self.diag.get((node, f'{name} stream'), {})

    def calibrate(self) -> tuple[float, bool, str]:
        self.client.wait_for_service(timeout_sec=30.0)
        t0 = time.perf_counter()
        fut = self.client.call_async(self.Trigger.Request())
        while not fut.done():
            time.sleep(0.001)
        return time.perf_counter() - t0, fut.result().success, fut.result().message


def start(module: str, *args: str, log: Path | None = None) -> subprocess.Popen:
    """``python -m module args`` in its own session; its output piped, or into ``log`` (a
    long-running node's log must not fill a pipe nobody reads)."""
    out = subprocess.PIPE if log is None else log.open('w')
    try:
        return subprocess.Popen(
            [sys.executable, '-m', module, *args],
            env=ENV,
            stdout=out,
            stderr=subprocess.PIPE if log is None else subprocess.STDOUT,
            text=True,
            start_new_session=True,
        )
    finally:
        if log is not None:
            out.close()  # the child has its own copy


def stop(p: subprocess.Popen) -> None:
    if p.poll() is None:
        p.send_signal(signal.SIGINT)
        try:
            p.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
