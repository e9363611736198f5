"""The README's ROS 2 commands, typed as a ROS user types them.

Each command runs in bash, in a colcon workspace whose ``install/setup.bash`` is sourced, with
the real ``ros2`` command line (ros2cli, launch and launch_ros from their Jazzy sources:
scripts/ros2cli; composition_interfaces, which launch_ros imports: scripts/interfaces) and the
real rosdep on rosdistro's own files. The underlay stands in for ``/opt/ros/jazzy``: this venv
(rclpy and the messages from PyPI, the ``ros2`` command) and ``.interfaces/install`` (the message
packages PyPI lacks). Two departures, both forced by the machine: the clone is a link to this
checkout, and ``rosdep install`` is simulated for Ubuntu noble (apt here is Debian's, without
ROS). The tests wait on what the processes say, never for a fixed time.
"""

from __future__ import annotations

import ast
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from conftest import ROOT
from ros_support import (
    INTERFACES,
    assert_near_truth,
    build_workspace,
    ros_available,
    running,
    wait_for,
    with_interfaces,
)

#: The commands, exactly as the README's ROS 2 section writes them.
ROSDEP = 'rosdep install --from-paths src -y --ignore-src'
BUILD = 'colcon build'
SOURCE = 'source install/setup.bash'
LAUNCH_SIM = 'ros2 launch handeye_ros calibrator.launch.py sim:=true auto_calibrate:=true'
LAUNCH_RIG = (
    'ros2 launch handeye_ros calibrator.launch.py hand_topic:=/vicon/rig/pose eye_topic:=/vio/odom'
)
RUN_NODE = (
    'ros2 run handeye_ros calibrator --ros-args '
    '--params-file install/handeye_ros/share/handeye_ros/config/calibrator.yaml'
)
RUN_SIM = 'ros2 run handeye_ros sim_publisher'
ECHO_STATUS = 'ros2 topic echo --once /calibrator/status diagnostic_msgs/msg/DiagnosticStatus'
CALIBRATE = 'ros2 service call /calibrator/calibrate std_srvs/srv/Trigger'
SET_OUTPUT = 'ros2 param set /calibrator output_file calibration.yaml'
SAVE = 'ros2 service call /calibrator/save std_srvs/srv/Trigger'
#: The README's lines that set the workspace up (done here by the workspace fixture).
SETUP_LINES = (
    'mkdir -p ~/ros2_ws/src && cd ~/ros2_ws/src',
    "git clone <this repository's URL> handeye_ros",
    'cd ~/ros2_ws',
)
#: Every command the tests below run as typed.
RUN_HERE = (
    ROSDEP,
    BUILD,
    SOURCE,
    LAUNCH_SIM,
    LAUNCH_RIG,
    RUN_NODE,
    RUN_SIM,
    ECHO_STATUS,
    CALIBRATE,
    SET_OUTPUT,
    SAVE,
)

# only a ROS install has the ros2 command, on Jazzy's numpy: .ci/run runs these in the Jazzy
# suite (setup.cfg's markers)
pytestmark = pytest.mark.ros2_command

ROSDISTRO = ROOT.parent / 'shared' / 'data' / 'rosdistro'
VENDOR = ROOT.parent / 'shared' / 'vendor' / 'ros2-jazzy'
BIN = Path(sys.prefix) / 'bin'


def _readme_section() -> str:
    text = (ROOT / 'README.md').read_text()
    start = text.index('## In a ROS 2 Jazzy workspace (Ubuntu 24.04)')
    return text[start : text.index('Without ROS installed', start)]


def test_every_ros_command_of_the_readme_is_run_here() -> None:
    """The README's ROS 2 section holds these commands and no other: none is untested."""
    blocks = re.findall(r'```sh\n(.*?)```', _readme_section(), flags=re.DOTALL)
    # a command continued with a backslash is one command (the README wraps at 100 characters)
    blocks = [re.sub(r'\s*\\\n\s*', ' ', b) for b in blocks]
    lines = [ln.strip() for b in blocks for ln in b.splitlines() if ln.strip()]
    assert set(lines) == {*SETUP_LINES, *RUN_HERE}, lines


def _why_not() -> str | None:
    """Why the ros2 command tests cannot run here, or None."""
    if not VENDOR.is_dir():
        return f'the ros2 command line sources are not present at {VENDOR}'
    if not ros_available():
        return 'rclpy / colcon not installed'
    if not (BIN / 'ros2').is_file():
        return f'ros2 is not installed in {sys.prefix}: scripts/ros2cli installs it'
    return None


def _underlay() -> dict[str, str]:
    """What `source /opt/ros/jazzy/setup.bash` gives a ROS user, from this venv and the
    message packages of scripts/interfaces; discovery kept on this host."""
    env = dict(os.environ)
    env.pop('ROS_LOCALHOST_ONLY', None)
    env.update(
        PATH=f'{BIN}{os.pathsep}{env["PATH"]}',
        AMENT_PREFIX_PATH=sys.prefix,
        ROS_DISTRO='jazzy',
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', '42'),
        PYTHONUNBUFFERED='1',  # the logs reach the files as they are said
    )
    env.pop('PYTHONPATH', None)
    return with_interfaces(env) or env


class Shell:
    """Commands typed in a shell of the workspace, each in its own process group (a terminal's
    Ctrl-C goes to the whole group)."""

    def __init__(self, ws: Path, logs: Path) -> None:
        # ROS_HOME of its own: the node's output_dir ($ROS_HOME/handeye_ros) under the test's
        self.ws, self.logs, self.env = ws, logs, {**_underlay(), 'ROS_HOME': str(logs / 'ros')}
        self.procs: list[tuple[subprocess.Popen, Path]] = []

    def start(self, command: str, name: str) -> subprocess.Popen:
        log = self.logs / f'{name}.log'
        script = f'cd {self.ws} && set +u && {SOURCE} && exec {command}'
        proc = subprocess.Popen(
            ['bash', '-c', script],
            env=self.env,
            stdout=log.open('w'),
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        self.procs.append((proc, log))
        return proc

    def log(self, proc: subprocess.Popen) -> str:
        return next(log for p, log in self.procs if p is proc).read_text(errors='replace')

    def run(self, command: str, name: str, timeout: float = 60.0) -> tuple[int, str]:
        proc = self.start(command, name)
        try:
            proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
            raise AssertionError(f'{command!r} still running after {timeout} s:\n{self.log(proc)}')
        return proc.returncode, self.log(proc)

    def ctrl_c(self, proc: subprocess.Popen, timeout: float = 30.0) -> int:
        """Ctrl-C in the command's terminal; its exit code, once every process of its group has
        ended (a process left is an error)."""
        os.killpg(proc.pid, signal.SIGINT)
        code = proc.wait(timeout=timeout)
        assert wait_for(lambda: not _group_alive(proc.pid), timeout), 'processes left behind'
        return code

    def close(self) -> None:
        for proc, _ in self.procs:
            if _group_alive(proc.pid):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        # the ros2 daemon that `ros2 topic` and `ros2 param` start, as for a user
        subprocess.run(
            ['bash', '-c', f'cd {self.ws} && set +u && {SOURCE} && ros2 daemon stop'],
            env=self.env,
            capture_output=True,
            timeout=60,
            check=False,
        )


def _group_alive(pgid: int) -> bool:
    """Whether a process of the group still runs (a zombie has ended: see ``running``)."""
    return bool(running('pgid', pgid))


@pytest.fixture(scope='module')
def ws(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """~/ros2_ws with the package in src/ (a link for the clone), built by `colcon build`."""
    why = _why_not()
    if why:
        pytest.skip(why)
    root = tmp_path_factory.mktemp('ros2_ws')
    build_workspace(root, _underlay())  # `colcon build`, as BUILD
    return root


@pytest.fixture
def shell(ws: Path, tmp_path: Path):
    sh = Shell(ws, tmp_path)
    yield sh
    sh.close()


def _answer(out: str) -> tuple[bool, str]:
    """(success, message) of a Trigger answer as `ros2 service call` prints it."""
    m = re.search(r'Trigger_Response\(success=(True|False), message=(.*)\)\s*$', out, re.DOTALL)
    assert m, out
    return m.group(1) == 'True', ast.literal_eval(m.group(2))


@pytest.mark.ros
def test_ros2_run_status_calibrate_param_set_and_save_as_typed(shell: Shell, ws: Path) -> None:
    """`ros2 run` the node and the simulated rig, then the status, the calibration, a parameter
    set and the save, each as typed; a call before any data is answered with what is missing;
    Ctrl-C ends the node with exit code 0."""
    node = shell.start(RUN_NODE, 'node')
    assert wait_for(lambda: 'buffering hand' in shell.log(node) or node.poll() is not None, 60)
    code, out = shell.run(CALIBRATE, 'early_call')
    ok, message = _answer(out)
    assert code == 0 and not ok and 'no publisher' in message, out

    code, out = shell.run(RUN_SIM, 'sim', timeout=120)
    assert code == 0 and 'Traceback' not in out, out
    truth = yaml.safe_load(out.strip().splitlines()[-1])['truth']

    # 60 s of rich motion: READY, once neither stream is the last one still flowing (the
    # device's ends first, and for a moment 'has sent nothing' is true): echoed again until then
    said = []

    def ready() -> bool:
        code, out = shell.run(ECHO_STATUS, f'status{len(said)}')
        status = yaml.safe_load(out.split('\n---')[0])
        assert code == 0 and status['name'] == '/calibrator: readiness', out
        said.append(status['message'])
        return status['message'] == 'READY'

    assert wait_for(ready, 30, 0.0), said

    code, out = shell.run(CALIBRATE, 'calibrate')
    ok, message = _answer(out)
    assert code == 0 and ok and message.startswith('good: '), out

    code, out = shell.run(SET_OUTPUT, 'param')
    assert code == 0 and 'Set parameter successful' in out, out
    code, out = shell.run(SAVE, 'save')
    ok, message = _answer(out)
    saved = Path(shell.env['ROS_HOME']) / 'handeye_ros' / 'calibration.yaml'
    assert code == 0 and ok and message == f'wrote {saved}', out
    assert_near_truth(truth, yaml.safe_load(saved.read_text()))

    assert shell.ctrl_c(node) == 0, shell.log(node)
    assert 'Traceback' not in shell.log(node), shell.log(node)


@pytest.mark.ros
def test_a_misspelt_parameter_on_ros2_run_is_refused_in_one_line(shell: Shell) -> None:
    code, out = shell.run(f'{RUN_NODE} -p eye_topik:=/vio/odom', 'typo')
    assert code == 1, out
    assert (
        "calibrator: error: unknown parameter 'eye_topik' (did you mean 'eye_topic'?); "
        'calibrator --help lists them' in out
    ), out
    assert 'Traceback' not in out, out


LAUNCH = pytest.mark.skipif(
    not any((INTERFACES / 'lib').glob('python3*/site-packages/composition_interfaces')),
    reason='composition_interfaces (which launch_ros imports) not built: scripts/interfaces '
    'builds it from ../shared/vendor/ros2-jazzy',
)


@pytest.mark.ros
@LAUNCH
def test_ros2_launch_with_the_simulated_rig_calibrates_and_stops_on_ctrl_c(shell: Shell) -> None:
    """The node and the simulated rig start, auto mode calibrates as the recording grows (for
    an evaluation its first calibration is the check of READY) until a result is good, and
    Ctrl-C on the launch stops both with exit code 0 and no traceback."""
    launch = shell.start(LAUNCH_SIM, 'launch')
    good = r'\[calibrator-1\].*calibrated in [\d.]+ s: good: '
    assert wait_for(
        lambda: re.search(good, shell.log(launch)) or launch.poll() is not None, 150, 0.2
    ), shell.log(launch)
    log = shell.log(launch)
    assert re.search(good, log), log
    assert 'sim_publisher: publishing' in log, log
    assert shell.ctrl_c(launch) == 0, shell.log(launch)
    assert 'Traceback' not in shell.log(launch), shell.log(launch)


@pytest.mark.ros
@LAUNCH
def test_ros2_launch_on_a_rig_with_its_topics_then_the_service_call(shell: Shell) -> None:
    """The launch arguments name the rig's topics; the README's service call calibrates."""
    launch = shell.start(LAUNCH_RIG, 'launch')
    assert wait_for(lambda: 'buffering hand /vicon/rig/pose' in shell.log(launch), 60, 0.2), (
        shell.log(launch)
    )
    code, out = shell.run(f'{RUN_SIM} --hand-topic /vicon/rig/pose', 'sim', timeout=120)
    assert code == 0, out
    code, out = shell.run(CALIBRATE, 'calibrate')
    ok, message = _answer(out)
    assert code == 0 and ok and message.startswith('good: '), out
    assert shell.ctrl_c(launch) == 0, shell.log(launch)


@pytest.mark.ros
@LAUNCH
@pytest.mark.parametrize('how', ['ctrl-c', 'sigterm'])
def test_a_launch_on_simulated_time_without_clock_stops(shell: Shell, how: str) -> None:
    """use_sim_time:=true and no /clock: the status says so, and Ctrl-C (exit code 0) or a
    SIGTERM to `ros2 launch` (which ends at once and leaves its processes to themselves: the
    calibrator stops with its parent) leave no process running."""
    launch = shell.start('ros2 launch handeye_ros calibrator.launch.py use_sim_time:=true', 'l')
    assert wait_for(lambda: 'waiting for /clock' in shell.log(launch), 60, 0.1), shell.log(launch)
    if how == 'ctrl-c':
        assert shell.ctrl_c(launch) == 0, shell.log(launch)
    else:
        launch.send_signal(signal.SIGTERM)
        launch.wait(timeout=10)
        assert wait_for(lambda: not _group_alive(launch.pid), 10), running('pgid', launch.pid)
    assert 'Traceback' not in shell.log(launch), shell.log(launch)


@pytest.mark.ros
@LAUNCH
@pytest.mark.parametrize(
    ('args', 'said'),
    [
        ('params_file:=mine.yaml', 'params_file mine.yaml is not a file: give the path of your '),
        ('sim:=yes', "sim is true or false, not 'yes'"),
        ('rviz:=on', "rviz is true or false, not 'on'"),
        ('sim:=true use_sim_time:=maybe', "use_sim_time is true or false, not 'maybe'"),
        ('rviz:=true', 'rviz:=true needs rviz2, which is not installed'),
    ],
)
def test_a_refused_launch_argument_starts_nothing(shell: Shell, args: str, said: str) -> None:
    """One line naming the argument and the fix, exit code 1, no process started (none left:
    the launch's process group is empty once it has exited)."""
    prefixes = shell.env.get('AMENT_PREFIX_PATH', '').split(os.pathsep)
    index = 'share/ament_index/resource_index/packages/rviz2'
    if 'rviz2' in said and any((Path(p) / index).exists() for p in prefixes if p):
        pytest.skip('rviz2 is installed here: rviz:=true is no mistake')
    launch = shell.start(f'ros2 launch handeye_ros calibrator.launch.py {args}', 'launch')
    launch.wait(timeout=60)
    out = shell.log(launch)
    assert launch.returncode == 1, out
    assert said in out, out
    assert 'process started' not in out and 'Traceback' not in out, out
    assert not _group_alive(launch.pid), running('pgid', launch.pid)


@pytest.mark.slow
def test_rosdep_resolves_every_key_of_package_xml_for_jazzy_on_noble(
    tmp_path: Path,
) -> None:
    """`rosdep install --from-paths src -y --ignore-src` on rosdistro's own files, simulated
    for Ubuntu noble: every key resolves (python3-rosbags, the key the package once declared,
    did not: rosdep's key for it is python3-rosbags-pip)."""
    if not (ROSDISTRO / 'jazzy' / 'distribution.yaml').is_file():
        pytest.skip(f'rosdistro files not present at {ROSDISTRO}')
    if not (BIN / 'rosdep').is_file():
        pytest.skip(f'rosdep is not installed in {sys.prefix} (requirements.txt pins it)')
    sources = tmp_path / 'sources.list.d'
    sources.mkdir()
    (sources / '20-default.list').write_text(
        ''.join(f'yaml file://{ROSDISTRO}/rosdep/{db}\n' for db in ('base.yaml', 'python.yaml'))
    )
    (tmp_path / 'index.yaml').write_text(
        yaml.safe_dump(
            {
                'type': 'index',
                'version': 4,
                'distributions': {
                    'jazzy': {
                        'distribution': [f'file://{ROSDISTRO}/jazzy/distribution.yaml'],
                        'distribution_status': 'active',
                        'distribution_type': 'ros2',
                        'python_version': 3,
                    }
                },
            }
        )
    )
    (tmp_path / 'ws' / 'src').mkdir(parents=True)
    (tmp_path / 'ws' / 'src' / 'handeye_ros').symlink_to(ROOT)
    # a machine before `rosdep install`: no underlay (colcon test on a Jazzy install runs with
    # /opt/ros/jazzy on AMENT_PREFIX_PATH, and --ignore-src leaves out every package it holds)
    underlay = ('AMENT_PREFIX_PATH', 'CMAKE_PREFIX_PATH', 'COLCON_PREFIX_PATH', 'ROS_PACKAGE_PATH')
    env = dict(
        {k: v for k, v in os.environ.items() if k not in underlay},
        PATH=f'{BIN}{os.pathsep}{os.environ["PATH"]}',
        ROS_DISTRO='jazzy',
        ROS_HOME=str(tmp_path / 'ros_home'),
        ROSDEP_SOURCE_PATH=str(sources),
        ROSDISTRO_INDEX_URL=f'file://{tmp_path / "index.yaml"}',
    )

    def rosdep(command: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            ['bash', '-c', f'cd {tmp_path / "ws"} && {command}'],
            env=env,
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )

    update = rosdep('rosdep update')
    assert update.returncode == 0, update.stdout + update.stderr
    res = rosdep(f'{ROSDEP} --simulate --os=ubuntu:noble')
    assert res.returncode == 0, res.stdout + res.stderr
    # what it would install (what this machine already has, it leaves out)
    for wanted in ('python3-scipy', 'ros-jazzy-rclpy', 'ros-jazzy-launch-ros'):
        assert f'apt-get install -y {wanted}\n' in res.stdout, res.stdout
    keys = rosdep('rosdep keys --from-paths src --ignore-src').stdout.split()
    assert 'python3-rosbags-pip' in keys and 'rclpy' in keys, keys
    pip = rosdep('rosdep resolve python3-rosbags-pip --os=ubuntu:noble')
    assert pip.returncode == 0 and pip.stdout.split() == ['#pip', 'rosbags'], pip.stdout
    old = rosdep('rosdep resolve python3-rosbags --os=ubuntu:noble')
    assert old.returncode != 0 and 'python3-rosbags' in old.stderr, old.stdout + old.stderr
