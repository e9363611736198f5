"""How the calibrator node starts and stops: refused and unknown parameters, a misnamed params
section, the command line and its help, signals, the simulated publisher's own stop (built
with colcon, separate processes, DDS on localhost)."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
from pathlib import Path

import pytest
from ros_support import (
    Processes,
    publisher,
    resolve_executable,
    ros_available,
    ros_env,
    running,
    start_node,
    wait_for,
    wait_started,
)

from handeye_ros.app.commands import path_name

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(not ros_available(), reason='rclpy / colcon not installed'),
]


@pytest.mark.parametrize(
    ('param', 'fragment'),
    [
        ('eta:=-1.0', 'eta'),
        ('eta:=five', 'eta'),
        ('qos_reliability:=sometimes', 'qos_reliability'),
        ('hand_type:=Imu', 'hand_type'),
        ('buffer_size:=1', 'buffer_size'),
        ('status_period:=1e9', 'status_period out of range'),
        ('hand_topic:=/tf:world', 'PARENT.CHILD'),
        (
            'hand_topic:=/mocap pose',
            "hand_topic /mocap pose: '/mocap pose' is no valid topic name",
        ),
        ('eye_topic:=/vio/1odom', 'must not start with a number'),
        ('eta:=5', 'write a float with its point: 5.0, not 5'),
        ('hand_topic:=/vio/odom|eye_topic:=/vio/odom', 'eye_topic both read /vio/odom'),
        ('output_file:=../evil.yaml', 'output_file ../evil.yaml: ".." is not allowed'),
        ('auto_calibrate:=true|status_period:=0.0', 'which status_period 0 turns off'),
        pytest.param(
            'hand_topic:=/tf:world.marker',
            'tf2_msgs/msg/TFMessage cannot be imported',
            marks=pytest.mark.skipif(
                importlib.util.find_spec('tf2_msgs') is not None,
                reason='tf2_msgs is importable here: the node subscribes to /tf',
            ),
        ),
    ],
)
def test_invalid_parameters_are_refused_at_start(
    ros: Processes, install: Path, param: str, fragment: str
) -> None:
    # an explicit type subscribes at start: a bad topic name is caught before rclpy sees it
    typed = (
        ('hand_type:=PoseStamped', 'eye_type:=Odometry') if ' ' in param or '1' in param else ()
    )
    node = start_node(ros, install, *typed, *param.split('|'))
    node.wait(timeout=30)
    out, err = ros.output(node)
    assert node.returncode == 1, (out, err)
    assert fragment in err and 'Traceback' not in err, err
    # the hint on how to write a float is said for a float given as another type alone
    assert ('with its point' in err) == (param in ('eta:=5', 'eta:=five')), err


@pytest.mark.parametrize('how', ['ctrl-c', 'sigterm'])
def test_signals_stop_the_node_cleanly(ros: Processes, install: Path, how: str) -> None:
    """Ctrl-C (SIGINT to the process group, as a terminal sends it) and SIGTERM (to the node,
    as a process manager sends it), while the node idles, receives and calibrates:
    exit code 0, no traceback, no process of the node left (the worker is stopped and joined),
    and the caller of the abandoned calibration answered "aborted: shutting down"."""
    import os
    import signal

    def stop(p: subprocess.Popen) -> None:
        if how == 'ctrl-c':
            os.killpg(p.pid, signal.SIGINT)
        else:
            p.send_signal(signal.SIGTERM)
        p.wait(timeout=30)

    def left(p: subprocess.Popen) -> list[str]:
        """The node's processes still running (its session), once they have had 5 s to go."""
        wait_for(lambda: not running('sid', p.pid), 5.0, 0.1)
        return running('sid', p.pid)

    def says(p: subprocess.Popen, *words: str, timeout: float = 60.0) -> None:
        assert wait_for(lambda: all(w in ros.output(p)[1] for w in words), timeout, 0.05), (
            words,
            ros.output(p),
        )

    # idle, its subscriptions made (its start, at the moments it is most fragile, is
    # test_lifecycle's)
    runs = []
    node = start_node(ros, install, name='idle')
    wait_started(ros, node)
    stop(node)
    runs.append(('idle', node, left(node)))
    # while it receives: the publisher under way, the node's streams typed by their publishers
    node = start_node(ros, install, name='receiving')
    wait_started(ros, node)
    pub = ros.start(
        publisher(ros, '--seed', '5', '--level', '2', '--rate', '2000', '--duration', '20'),
        'publisher',
    )
    says(pub, 'publishing')
    says(node, 'hand: /mocap/pose is', 'eye: /vio/odom is')
    stop(node)
    runs.append(('receiving', node, left(node)))
    ros.stop(pub)
    # while a calibration runs in the worker (many RANSAC hypotheses make it last): its
    # caller is answered before the node goes. The caller asks ~/save first: a client that
    # joined the graph moments ago may not be matched by the node's response writer yet, and
    # rmw_fastrtps drops a response it cannot match within 100 ms (1 stop in 6 under load)
    node = start_node(ros, install, 'ransac_iterations:=100000', name='busy')
    ros.run_json(publisher(ros, '--seed', '5', '--level', '2', '--rate', '2000'), 'publisher')
    client = ros.start(
        ros.script('ros_client.py', 'call', '/calibrator/save', '/calibrator/calibrate'), 'client'
    )
    says(client, 'sent /calibrator/calibrate')
    # the node took the call: its calibration started, or it waits for the status's check of
    # READY that runs (whose own "calibrating ... (checking READY)" is no sign of the call)
    from handeye_ros.ros.calls import QUEUED  # rclpy's: imported where the test runs

    taken = re.compile(
        rf'calibrating \d+ MoCap and \d+ device poses$|{re.escape(QUEUED)}', re.MULTILINE
    )
    assert wait_for(lambda: taken.search(ros.output(node)[1]) is not None, 60.0, 0.05), ros.output(
        node
    )
    stop(node)
    runs.append(('calibrating', node, left(node)))
    assert "1 ~/calibrate caller(s) answered 'aborted: shutting down'" in ros.output(node)[1]
    try:
        client.wait(timeout=30)
    except subprocess.TimeoutExpired:
        pytest.fail(f'no answer after the stop: {ros.output(client)}\n{ros.output(node)[1]}')
    answer = json.loads(ros.output(client)[0].strip().splitlines()[-1])
    assert answer[-1] == {'success': False, 'message': 'aborted: shutting down'}, answer
    for label, p, rest in runs:
        err = ros.output(p)[1]
        assert p.returncode == 0, (label, p.returncode, err)
        assert 'Traceback' not in err and 'Error' not in err, (label, err)
        assert not rest, (label, rest)


def test_help_and_command_line(install: Path, tmp_path: Path) -> None:
    """--help on every executable, as ros2 run starts it and by its name on the install's
    PATH, without starting anything; a stray argument is named."""
    env = ros_env(install)
    for exe in (
        'calibrator',
        'sim_publisher',
        'offline_calibrate',
        'evaluate',
        'demo',
        'publish_calibration',
    ):
        on_path = install / 'handeye_ros' / 'bin' / path_name(exe)
        for cmd, name in (
            (resolve_executable(env, 'handeye_ros', exe), exe),
            (on_path, on_path.name),
        ):
            proc = subprocess.run(
                [str(cmd), '--help'],
                env=env,
                capture_output=True,
                text=True,
                timeout=60,
                check=False,
            )
            assert proc.returncode == 0, (cmd, proc.stderr)
            assert proc.stdout.startswith(f'usage: {name} '), (cmd, proc.stdout[:200])
    helped = subprocess.run(
        [str(resolve_executable(env, 'handeye_ros', 'calibrator')), '-h'],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    ).stdout
    assert 'time_reference' in helped and '  output_file * (default' in helped
    stray = subprocess.run(
        [str(resolve_executable(env, 'handeye_ros', 'calibrator')), 'eta:=3'],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert stray.returncode == 2 and "unknown argument 'eta:=3'" in stray.stderr
    # sim_publisher's absurd values: argparse's exit 2 and what is wrong, no traceback
    for bad, said in (
        (['--rate', '-5'], '--rate must be a positive number'),
        (['--duration', '1'], 'holds no eye poses'),
        (['--mocap-noise', '-1', '0'], 'the noise amounts are numbers >= 0'),
        (['--seed', '-1'], 'the seed is an integer >= 0'),
        (['--level', '11'], "the noise level is one of the paper's"),
        (['--mocap-dropout', 'nan', '2'], '--mocap-dropout takes two times >= 0'),
        (['--speed', '0'], '--speed must be a positive number, not 0'),
        (['--hand-type', 'Bogus'], "--hand-type Bogus: message type 'Bogus' carries no pose"),
        (['--replay', 'nowhere.csv', 'nowhere.txt'], 'nowhere.csv'),
    ):
        proc = subprocess.run(
            [str(resolve_executable(env, 'handeye_ros', 'sim_publisher')), *bad],
            env=env,
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert proc.returncode == 2 and said in proc.stderr, (bad, proc.stderr)
        assert 'Traceback' not in proc.stderr, (bad, proc.stderr)


def test_unknown_parameters_are_refused_naming_the_one_meant(
    ros: Processes, install: Path
) -> None:
    """A misspelt name after -p (or in a params file) would leave its value at the default:
    the node refuses to start, in one line naming the parameter meant."""
    node = start_node(ros, install, 'etaa:=3.0', 'qos_relability:=reliable')
    assert node.wait(timeout=60) == 1, ros.output(node)
    err = ros.output(node)[1]
    assert err.strip().splitlines()[-1] == (
        "calibrator: error: unknown parameters 'etaa' (did you mean 'eta'?), "
        "'qos_relability' (did you mean 'qos_reliability'?); calibrator --help lists them"
    ), err
    assert 'Traceback' not in err


def test_misnamed_params_section_and_remapped_topics_are_said(
    ros: Processes, install: Path, tmp_path: Path
) -> None:
    """A params file whose section names another node is said (rclpy ignores it silently),
    and the logs name the remapped topic a stream is read from."""
    bad = tmp_path / 'params.yaml'
    bad.write_text('calibratr:\n  ros__parameters:\n    eta: 4.0\n')
    exe = resolve_executable(ros.env, 'handeye_ros', 'calibrator')
    node = ros.start(
        [str(exe), '--ros-args', '--params-file', str(bad), '-r', '/mocap/pose:=/vicon/rig'],
        'node',
    )
    assert wait_for(lambda: 'buffering hand' in ros.output(node)[1], timeout=30.0, step=0.2)
    assert ros.stop(node) == 0
    err = ros.output(node)[1]
    assert 'no section for this node (/calibrator); its sections calibratr were ignored' in err
    assert "(rename 'calibratr' to 'calibrator'?)" in err
    assert 'buffering hand /vicon/rig (remapped from /mocap/pose)' in err


@pytest.mark.parametrize('how', ['ctrl-c', 'sigterm'])
def test_sim_publisher_stops_quietly(ros: Processes, install: Path, how: str) -> None:
    """Ctrl-C or SIGTERM while sim_publisher publishes: exit code 0, no traceback (it printed
    an RCLError 'publisher's context is invalid' traceback and exited 1). Its truth prints the
    quaternion with w >= 0, as every output of the package does."""
    import os
    import signal

    pub = ros.start(
        publisher(ros, '--duration', '60', '--rate', '500', '--wait-subscribers', '0'),
        f'quiet_pub_{how}',
    )
    # publishing under way: it says so
    assert wait_for(lambda: 'publishing' in ros.output(pub)[1] or pub.poll() is not None, 60)
    assert pub.poll() is None, ros.output(pub)
    if how == 'ctrl-c':
        os.killpg(pub.pid, signal.SIGINT)
    else:
        pub.send_signal(signal.SIGTERM)
    pub.wait(timeout=30)
    out, err = ros.output(pub)
    assert pub.returncode == 0, (out, err)
    assert 'Traceback' not in err, err
    short = ros.run_json(publisher(ros, '--duration', '3', '--wait-subscribers', '0'), 'w_pub')
    assert short['truth']['q_HE'][3] >= 0.0
