"""The calibrator node as users run it: built with colcon, started as `ros2 run` would, fed by
a separate publisher process, queried by a separate client process, over DDS on localhost."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from ros_support import (
    Processes,
    build_workspace,
    resolve_executable,
    ros_available,
    ros_env,
    wait_for,
    with_interfaces,
)

from handeye_ros.core.simulate import Truth, calibration_error

pytestmark = pytest.mark.skipif(not ros_available(), reason='rclpy / colcon not installed')


@pytest.fixture(scope='module')
def install(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_workspace(tmp_path_factory.mktemp('ws'))


@pytest.fixture
def ros(install: Path, tmp_path: Path):
    procs = Processes(ros_env(install), tmp_path)
    yield procs
    procs.stop_all()


def _params(install: Path) -> Path:
    return install / 'handeye_ros' / 'share' / 'handeye_ros' / 'config' / 'calibrator.yaml'


def _start_node(ros: Processes, install: Path, *params: str, name: str = 'node'):
    exe = resolve_executable(ros.env, 'handeye_ros', 'calibrator')
    args = [str(exe), '--ros-args', '--params-file', str(_params(install))]
    for p in params:
        args += ['-p', p]
    return ros.start(args, name)


def _publisher(ros: Processes, *args: str) -> list[str]:
    return [str(resolve_executable(ros.env, 'handeye_ros', 'sim_publisher')), *args]


def _call(ros: Processes, *services: str, mode: str = 'call', name: str = 'client'):
    return ros.run_json(ros.script('ros_client.py', mode, *services), name)


def test_live_calibration_matches_truth_and_bag_replay(ros: Processes, install: Path,
                                                       tmp_path: Path) -> None:
    saved_path = tmp_path / 'node_result.yaml'
    report = tmp_path / 'report'
    node = _start_node(ros, install, f'output_file:={saved_path}', f'report_dir:={report}')
    bags = [f'{tmp_path / "rec_mcap"}:mcap', f'{tmp_path / "rec_sqlite"}:sqlite3',
            f'{tmp_path / "rec.bag"}:ros1']
    pub = ros.run_json(_publisher(ros, '--seed', '3', '--level', '3', '--rate', '500',
                                  *[a for b in bags for a in ('--bag', b)]), 'publisher')
    answer = _call(ros, '/calibrator/calibrate', '/calibrator/save')
    assert answer[0]['success'], answer
    assert answer[1]['success'], answer
    latched = ros.run_json(ros.script('ros_client.py', 'latched'), 'latched')
    saved = yaml.safe_load(saved_path.read_text())
    # ~/save wrote the report the worker drew (report_dir), and the result holds the evaluation
    assert f'{report / "report.html"}' in answer[1]['message'], answer[1]
    assert {p.name for p in report.iterdir()} >= {'report.html', 'trajectories.png'}
    assert saved['evaluation']['calibrated']['ape_translation']['n'] > 100

    # nothing lost on the way: every published message was buffered
    for s in ('hand', 'eye'):
        assert saved['streams'][s]['received'] == pub['sent'][s]
        assert saved['streams'][s]['buffered'] == pub['sent'][s]
        assert saved['streams'][s]['type'] == pub['types'][s]
    # the truth, within the noise (level 3: see test_pipeline / test_offline_cli)
    t = pub['truth']
    truth = Truth(t['time_offset'], np.array(t['q_HE']), np.array(t['p_HE']), None, None)
    err = calibration_error(truth, latched['time_offset'], latched['extrinsic']['rotation'],
                            latched['extrinsic']['translation'])
    assert err.time_offset_s < 3e-3 and err.translation_m < 0.02 and err.rotation_deg < 0.5
    # latched topics, saved file and service answer agree
    assert latched['time_offset'] == saved['time_offset']
    np.testing.assert_allclose(latched['extrinsic']['translation'],
                               saved['extrinsic']['translation'], atol=1e-12)
    assert (latched['extrinsic']['parent'], latched['extrinsic']['child']) == \
        ('mocap_marker', 'imu')
    assert f'time_offset {saved["time_offset"] * 1e3:+.2f} ms' in answer[0]['message']
    # the verdict goes with the answer and the file (a clean simulated rig: good)
    assert answer[0]['message'].startswith(f'{saved["quality"]["verdict"]}')
    assert saved['quality']['verdict'] == 'good', saved['quality']
    assert latched['diagnostics'] == {'level': 0, 'verdict': 'good', 'reasons': ''}
    # the batch stage ran and its covariance went out: translation variances as in the file
    assert saved['batch']['used']
    cov6 = np.asarray(latched['covariance']).reshape(6, 6)
    np.testing.assert_allclose(np.sqrt(np.diag(cov6)[:3]), saved['std']['translation'],
                               rtol=1e-9)
    np.testing.assert_allclose(cov6, cov6.T, atol=1e-15)
    # the bags replayed offline give the same answer as the node did live
    offline = resolve_executable(ros.env, 'handeye_ros', 'offline_calibrate')
    for spec in bags:
        path = spec.rsplit(':', 1)[0]
        proc = subprocess.run([str(offline), '--bag', path, '--json', '--config',
                               str(_params(install))], env=ros.env, capture_output=True,
                              text=True, timeout=120, check=False)
        assert proc.returncode == 0, proc.stderr
        d = json.loads(proc.stdout)
        assert d['time_offset'] == saved['time_offset'], spec
        assert d['extrinsic'] == saved['extrinsic'], spec
        assert d['evaluation'] == saved['evaluation'], spec
    assert ros.stop(node) == 0


@pytest.mark.parametrize('inputs', ['tf', 'rigid_bodies'])
def test_live_tf_and_rigid_bodies(install: Path, tmp_path: Path, inputs: str) -> None:
    """The hand as /tf:world.marker (a moving link and a latched static one) and the eye as
    /tf:odom.imu (the inverse link) on one /tf topic; or the hand as a mocap4r2 rigid body
    among others. Needs tf2_msgs and mocap4r2_msgs (scripts/interfaces builds them from
    their published definitions: a ROS 2 install has them; PyPI has not)."""
    env = with_interfaces(ros_env(install))
    if env is None:
        pytest.skip('tf2_msgs / mocap4r2_msgs not built: run scripts/interfaces (needs cmake '
                    'and a C++ compiler)')
    ros = Processes(env, tmp_path)
    try:
        saved_path = tmp_path / 'node_result.yaml'
        if inputs == 'tf':
            topics = ('hand_topic:=/tf:world.marker', 'eye_topic:=/tf:odom.imu')
            publish = ('--hand-type', 'TFMessage', '--hand-topic', '/tf', '--eye-type',
                       'TFMessage', '--eye-topic', '/tf')
        else:
            topics = ('hand_topic:=/mocap/rigid_bodies:rig',)
            publish = ('--hand-type', 'RigidBodies', '--hand-topic', '/mocap/rigid_bodies')
        node = _start_node(ros, install, f'output_file:={saved_path}', *topics)
        pub = ros.run_json(_publisher(ros, '--seed', '3', '--level', '3', '--rate', '500',
                                      '--reliable', *publish), 'publisher')
        answer = _call(ros, '/calibrator/calibrate', '/calibrator/save')
        assert answer[0]['success'] and answer[1]['success'], answer
        saved = yaml.safe_load(saved_path.read_text())
        for s in ('hand', 'eye'):
            assert saved['streams'][s]['buffered'] == pub['sent'][s], saved['streams'][s]
        if inputs == 'tf':
            assert saved['streams']['hand']['tf_chain'] == ['world->rig (moving)',
                                                            'rig->marker (static)']
            assert saved['streams']['eye']['tf_chain'] == ['imu->odom (moving, inverted)']
        else:
            assert saved['streams']['hand']['type'] == 'mocap4r2_msgs/msg/RigidBodies'
        t = pub['truth']
        truth = Truth(t['time_offset'], np.array(t['q_HE']), np.array(t['p_HE']), None, None)
        err = calibration_error(truth, saved['time_offset'], saved['extrinsic']['rotation'],
                                saved['extrinsic']['translation'])
        assert err.time_offset_s < 3e-3 and err.translation_m < 0.02 and err.rotation_deg < 0.5
        assert ros.stop(node) == 0
    finally:
        ros.stop_all()


def test_no_data_wrong_topic_and_unsupported_type(ros: Processes, install: Path) -> None:
    _start_node(ros, install, 'hand_topic:=/wrong/pose')
    first = _call(ros, '/calibrator/calibrate', '/calibrator/save', name='before')
    assert not first[0]['success'] and 'no publisher yet' in first[0]['message']
    assert not first[1]['success'] and 'call calibrate first' in first[1]['message']
    # an Imu on the hand topic: the node says what it sees instead of waiting forever
    imu = ros.start([sys.executable, '-c', (
        'import rclpy, time; from rclpy.node import Node; from sensor_msgs.msg import Imu; '
        'rclpy.init(); n = Node("imu_pub"); p = n.create_publisher(Imu, "/wrong/pose", 10); '
        'end = time.time() + 30\n'
        'while time.time() < end: p.publish(Imu()); time.sleep(0.05)')], 'imu')
    assert wait_for(lambda: 'sensor_msgs/msg/Imu' in _call(
        ros, '/calibrator/calibrate', name='after')[0]['message'], timeout=10.0, step=0.5)
    answer = _call(ros, '/calibrator/calibrate', name='last')[0]
    assert not answer['success'] and 'carries no pose' in answer['message']
    ros.stop(imu)


def test_nan_on_the_wire_busy_refusal_and_reset(ros: Processes, install: Path,
                                                tmp_path: Path) -> None:
    # many RANSAC hypotheses make one calibration last seconds, so calls overlap for sure
    saved_path = tmp_path / 'r.yaml'
    _start_node(ros, install, 'ransac_iterations:=100000', f'output_file:={saved_path}')
    pub = ros.run_json(_publisher(ros, '--seed', '5', '--level', '2', '--rate', '500',
                                  '--nan-every', '10'), 'publisher')
    both = _call(ros, '/calibrator/calibrate', '/calibrator/calibrate', mode='staggered')
    assert both[0]['success'] and not both[1]['success'], both
    assert 'already running' in both[1]['message']
    assert _call(ros, '/calibrator/save', name='save')[0]['success']
    saved = yaml.safe_load(saved_path.read_text())
    n_nan = pub['sent']['eye'] // 10
    assert saved['streams']['eye']['rejected']['non_finite'] == n_nan
    assert saved['streams']['eye']['buffered'] == pub['sent']['eye'] - n_nan
    assert any('non finite' in w for w in saved['warnings'])
    # reset while a calibration runs (0.3 s into it): both answer, the calibration on its copy
    calib_reset = _call(ros, '/calibrator/calibrate', '/calibrator/reset', mode='staggered',
                        name='calib_reset')
    assert calib_reset[0]['success'] and calib_reset[1]['success'], calib_reset
    after = _call(ros, '/calibrator/calibrate', name='after_reset')[0]
    assert not after['success'] and '0 pose(s) buffered' in after['message']


@pytest.mark.parametrize(('param', 'fragment'), [
    ('eta:=-1.0', 'eta'), ('eta:=five', 'eta'), ('qos_reliability:=sometimes', 'qos_reliability'),
    ('hand_type:=Imu', 'hand_type'), ('buffer_size:=1', 'buffer_size'),
    ('hand_topic:=/tf:world', 'PARENT.CHILD'),
    pytest.param('hand_topic:=/tf:world.marker', 'tf2_msgs/msg/TFMessage cannot be imported',
                 marks=pytest.mark.skipif(
                     importlib.util.find_spec('tf2_msgs') is not None,
                     reason='tf2_msgs is importable here: the node subscribes to /tf'))])
def test_invalid_parameters_are_refused_at_start(ros: Processes, install: Path, param: str,
                                                 fragment: str) -> None:
    node = _start_node(ros, install, param)
    node.wait(timeout=30)
    out, err = ros.output(node)
    assert node.returncode == 1, (out, err)
    assert fragment in err and 'Traceback' not in err, err
