"""Real ROS 2 processes for the tests: a colcon build, `ros2 run`-style executables, cleanup.

The package is built with colcon into a throw-away workspace once per session; executables
are resolved exactly as `ros2 run` does (ament_index_python's package prefix + lib/<pkg>/,
walked for the one executable of that name) and started as separate processes on a random
ROS_DOMAIN_ID with discovery kept on localhost. Every process is stopped at the end.
"""

from __future__ import annotations

import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT

from handeye_ros.core.simulate import Truth, calibration_error

SCRIPTS = Path(__file__).resolve().parent / 'ros_scripts'


def ros_available() -> bool:
    try:
        import rclpy  # noqa: F401
    except ImportError:
        return False
    return shutil.which('colcon', path=str(Path(sys.prefix) / 'bin')) is not None


def build_workspace(ws: Path, env: dict[str, str] | None = None) -> Path:
    """`colcon build` of this repository linked into ``ws/src``; returns the install folder.

    Builds are serialised across processes (a file lock): colcon writes the package's
    egg-info into the source folder, which the suites of both environments share."""
    import fcntl

    (ws / 'src').mkdir(parents=True)
    (ws / 'src' / 'handeye_ros').symlink_to(ROOT)
    if env is None:
        env = dict(
            os.environ,
            AMENT_PREFIX_PATH=sys.prefix,
            PATH=str(Path(sys.prefix) / 'bin') + os.pathsep + os.environ['PATH'],
        )
    with open(ROOT / '.colcon.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        proc = subprocess.run(
            [
                str(Path(sys.prefix) / 'bin' / 'colcon'),
                'build',
                '--event-handlers',
                'console_direct-',
            ],
            cwd=ws,
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
            check=False,
        )
    if proc.returncode:
        raise RuntimeError(f'colcon build failed:\n{proc.stdout}\n{proc.stderr}')
    # the bytecode setuptools writes at install on a user's machine, skipped where Python may
    # not write it (PYTHONDONTWRITEBYTECODE): without it every node, worker and publisher the
    # tests start compiles the package again (0.13 s of CPU each, some 200 a suite)
    subprocess.run(
        [sys.executable, '-m', 'compileall', '-q', str(ws / 'install')],
        capture_output=True,
        check=True,
    )
    return ws / 'install'


def ros_env(install: Path) -> dict[str, str]:
    """The environment `source install/setup.bash` gives, plus safe discovery settings."""
    prefix = install / 'handeye_ros'
    site = next((prefix / 'lib').glob('python3*/site-packages'))
    env = dict(os.environ)
    env.pop('ROS_LOCALHOST_ONLY', None)
    env.update(
        AMENT_PREFIX_PATH=os.pathsep.join([str(prefix), sys.prefix]),
        # the venv's python3 first, as an activated venv has it: ros2 run's executables start
        # with /usr/bin/env python3
        PATH=os.pathsep.join([str(prefix / 'bin'), str(Path(sys.prefix) / 'bin'), env['PATH']]),
        PYTHONPATH=str(site),
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', str(random.randint(1, 101))),
        PYTHONUNBUFFERED='1',
    )
    return env


#: tf2_msgs and mocap4r2_msgs built by scripts/interfaces (not on PyPI).
INTERFACES = ROOT / '.interfaces' / 'install'


def with_interfaces(env: dict[str, str]) -> dict[str, str] | None:
    """``env`` with the message packages of scripts/interfaces on the paths, as sourcing their
    install/setup.bash would put them; None when they were not built."""
    site = (
        INTERFACES
        / 'lib'
        / f'python{sys.version_info.major}.{sys.version_info.minor}'
        / 'site-packages'
    )
    if not (site / 'tf2_msgs').is_dir() or not (site / 'mocap4r2_msgs').is_dir():
        return None
    out = dict(env)
    out['PYTHONPATH'] = os.pathsep.join(filter(None, [env.get('PYTHONPATH'), str(site)]))
    out['LD_LIBRARY_PATH'] = os.pathsep.join(
        filter(None, [str(INTERFACES / 'lib'), env.get('LD_LIBRARY_PATH')])
    )
    out['AMENT_PREFIX_PATH'] = os.pathsep.join([env['AMENT_PREFIX_PATH'], str(INTERFACES)])
    return out


def resolve_executable(env: dict[str, str], package: str, executable: str) -> Path:
    """What `ros2 run package executable` would start."""
    code = (
        'import os, sys; from ament_index_python.packages import get_package_prefix; '
        'base = os.path.join(get_package_prefix(sys.argv[1]), "lib", sys.argv[1]); '
        'hits = [os.path.join(d, f) for d, ds, fs in os.walk(base) '
        'for f in fs if f == sys.argv[2] and os.access(os.path.join(d, f), os.X_OK)]; '
        'print(hits[0] if len(hits) == 1 else "")'
    )
    out = subprocess.run(
        [sys.executable, '-c', code, package, executable],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    if not out:
        raise RuntimeError(f'{package}/{executable} not found as ros2 run would')
    return Path(out)


class Processes:
    """Starts processes and guarantees none is left behind."""

    def __init__(self, env: dict[str, str], logs: Path):
        self.env, self.logs = env, logs
        self.procs: list[tuple[subprocess.Popen, Path, Path]] = []
        #: the test's client of Trigger services (:meth:`calls`) and how many calls it has had
        self._caller: subprocess.Popen | None = None
        self._asked = 0

    def start(self, cmd: list[str], name: str, stdin: int | None = None) -> subprocess.Popen:
        out, err = self.logs / f'{name}.out', self.logs / f'{name}.err'
        p = subprocess.Popen(
            cmd,
            env=self.env,
            stdin=stdin,
            stdout=out.open('w'),
            stderr=err.open('w'),
            start_new_session=True,
            cwd=self.logs,
        )
        self.procs.append((p, out, err))
        return p

    def output(self, p: subprocess.Popen) -> tuple[str, str]:
        for q, out, err in self.procs:
            if q is p:
                return out.read_text(), err.read_text()
        raise KeyError(p)

    def run_json(self, cmd: list[str], name: str, timeout: float = 120.0) -> object:
        """Run to completion and parse its last stdout line as JSON."""
        p = self.start(cmd, name)
        p.wait(timeout=timeout)
        out, err = self.output(p)
        assert p.returncode == 0, f'{name} failed ({p.returncode}):\n{out}\n{err}'
        return json.loads(out.strip().splitlines()[-1])

    def calls(self, services: tuple[str, ...], timeout: float = 120.0) -> list[dict]:
        """The Trigger ``services`` called in turn by the test's one client process
        (ros_client.py serve, started at the first call), as ``ros_client.py call`` would:
        its clients are discovered once, where a process of their own waits for DDS
        discovery at every call (0.3-3 s)."""
        if self._caller is None:
            self._caller = self.start(
                self.script('ros_client.py', 'serve'), 'caller', stdin=subprocess.PIPE
            )
        caller, self._asked = self._caller, self._asked + 1
        assert caller.stdin is not None
        caller.stdin.write((json.dumps(services) + '\n').encode())
        caller.stdin.flush()

        def answers() -> list[str]:
            return self.output(caller)[0].splitlines()

        wait_for(lambda: len(answers()) >= self._asked or caller.poll() is not None, timeout)
        assert len(answers()) >= self._asked, self.output(caller)
        return json.loads(answers()[self._asked - 1])

    def script(self, script: str, *args: str) -> list[str]:
        return [sys.executable, str(SCRIPTS / script), *args]

    def stop(self, p: subprocess.Popen, timeout: float = 10.0) -> int:
        """SIGINT (a clean rclpy shutdown), then SIGKILL if it does not exit."""
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
            try:
                p.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
        return p.returncode

    def stop_all(self) -> None:
        if self._caller is not None and self._caller.stdin is not None:
            self._caller.stdin.close()  # its input ends: it exits by itself
            try:
                self._caller.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                pass  # stopped below
        for p, _, _ in self.procs:
            self.stop(p)
        left = [p.pid for p, _, _ in self.procs if p.poll() is None]
        assert not left, f'processes left behind: {left}'


def running(column: str, ident: int) -> list[str]:
    """The processes still running (``ps`` rows) whose ``column`` ('sid' or 'pgid') is
    ``ident``. A zombie has ended and is not counted: multiprocessing's resource tracker ends
    once the node has exited, and reaping it is then init's job, which this machine's PID 1
    does not do (:mod:`handeye_ros.ros.worker`)."""
    rows = subprocess.run(
        ['ps', '-eo', f'{column}=,pid=,stat=,args='], capture_output=True, text=True, check=True
    ).stdout.splitlines()
    return [r.strip() for r in rows if r.split()[0] == str(ident) and r.split()[2][0] != 'Z']


def wait_for(predicate, timeout: float, step: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(step)
    return predicate()


# The calibrator node as the tests under test/ros run it (a plugin of test/conftest.py: its
# fixtures are every test's).


@pytest.fixture(scope='session')
def install(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The package built with colcon once per test process (``--symlink-install``)."""
    return build_workspace(tmp_path_factory.mktemp('ws'))


@pytest.fixture
def ros(install: Path, tmp_path: Path) -> Iterator[Processes]:
    """The processes a test starts, stopped when it ends."""
    procs = Processes(ros_env(install), tmp_path)
    yield procs
    procs.stop_all()


def params_file(install: Path) -> Path:
    """The params file the package installs (config/calibrator.yaml)."""
    return install / 'handeye_ros' / 'share' / 'handeye_ros' / 'config' / 'calibrator.yaml'


def start_node(ros: Processes, install: Path, *params: str, name: str = 'node'):
    """The calibrator as `ros2 run` starts it, with the installed params file, its files in the
    test's folder and ``params`` (``name:=value``) on top."""
    exe = resolve_executable(ros.env, 'handeye_ros', 'calibrator')
    args = [str(exe), '--ros-args', '--params-file', str(params_file(install))]
    args += ['-p', f'output_dir:={ros.logs}']  # the test's folder: every file it names is in it
    for p in params:
        args += ['-p', p]
    return ros.start(args, name)


def wait_started(ros: Processes, node) -> None:
    """Until the node says it buffers (its subscriptions made), with a deadline."""
    assert wait_for(
        lambda: 'buffering hand' in ros.output(node)[1] or node.poll() is not None, 60, 0.1
    ), ros.output(node)
    assert node.poll() is None, ros.output(node)


def publisher(ros: Processes, *args: str) -> list[str]:
    """The command line of the package's simulated publisher with ``args``."""
    return [str(resolve_executable(ros.env, 'handeye_ros', 'sim_publisher')), *args]


def assert_near_truth(t: dict, result: dict) -> None:
    """A result (saved file or latched topics) within the noise of sim_publisher's truth: its
    level 3 gives errors well inside 3 ms / 2 cm / 0.5 deg (see test_pipeline)."""
    truth = Truth(t['time_offset'], np.array(t['q_HE']), np.array(t['p_HE']), None, None)
    err = calibration_error(
        truth,
        result['time_offset'],
        result['extrinsic']['rotation'],
        result['extrinsic']['translation'],
    )
    assert err.time_offset_s < 3e-3 and err.translation_m < 0.02 and err.rotation_deg < 0.5


def call(ros: Processes, *services: str, mode: str = 'call', name: str = 'client'):
    """ros_scripts/ros_client.py calling (or reading) ``services``: its JSON. The calls in
    turn are the test's one client's (:meth:`Processes.calls`); each other mode runs in a
    process of its own (named ``name``)."""
    if mode == 'call':
        return ros.calls(services)
    return ros.run_json(ros.script('ros_client.py', mode, *services), name)
