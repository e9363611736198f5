"""The calibrator node's answers as users get them: built with colcon, started as `ros2 run`
would, fed by a separate publisher process, queried by a separate client process, over DDS on
localhost: the live result against the truth and the bag it recorded, the one result every
output carries, the rig file, the published calibration."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from ros_support import (
    Processes,
    assert_near_truth,
    call,
    params_file,
    publisher,
    resolve_executable,
    ros_available,
    ros_env,
    start_node,
    with_interfaces,
)

from handeye_ros.ros.worker import BLAS_THREADS

pytestmark = [
    pytest.mark.ros,
    pytest.mark.skipif(not ros_available(), reason='rclpy / colcon not installed'),
]


@pytest.mark.both_platforms
def test_live_calibration_matches_truth_and_bag_replay(
    ros: Processes, install: Path, tmp_path: Path
) -> None:
    saved_path = tmp_path / 'runs' / 'today' / 'node_result.yaml'  # ~/save makes the folders
    report = tmp_path / 'report'
    # purpose extrinsic: the truth's T_HE is what is checked (for an evaluation, the simulated
    # eye's APE rotation, ~1.6 deg, is not settled to 5 % by a short recording's 0.1 deg)
    node = start_node(
        ros, install, f'output_file:={saved_path}', f'report_dir:={report}', 'purpose:=extrinsic'
    )
    bags = [
        f'{tmp_path / "rec_mcap"}:mcap',
        f'{tmp_path / "rec_sqlite"}:sqlite3',
        f'{tmp_path / "rec.bag"}:ros1',
    ]
    pub = ros.run_json(
        publisher(
            ros,
            '--seed',
            '3',
            '--level',
            '3',
            '--rate',
            '500',
            *[a for b in bags for a in ('--bag', b)],
        ),
        'publisher',
    )
    answer = call(ros, '/calibrator/calibrate', '/calibrator/save')
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
    assert_near_truth(pub['truth'], latched)
    # latched topics, saved file and service answer agree
    assert latched['time_offset'] == saved['time_offset']
    np.testing.assert_allclose(
        latched['extrinsic']['translation'], saved['extrinsic']['translation'], atol=1e-12
    )
    assert (latched['extrinsic']['parent'], latched['extrinsic']['child']) == (
        'mocap_marker',
        'imu',
    )
    assert f'time_offset {saved["time_offset"] * 1e3:+.2f} ms' in answer[0]['message']
    # the verdict goes with the answer and the file (a clean simulated rig: good)
    assert answer[0]['message'].startswith(f'{saved["quality"]["verdict"]}')
    assert saved['quality']['verdict'] == 'good', saved['quality']
    diag = latched['diagnostics']
    assert (diag['level'], diag['verdict'], diag['reasons']) == (0, 'good', '')
    # the offset with its stamp and frames: eye clock minus hand clock, to the nanosecond
    ref = latched['time_reference']
    assert ref['offset_ns'] == saved['time_offset_ns']
    assert (ref['frame_id'], ref['source']) == ('imu', 'mocap_marker')
    assert ref['stamp_ns'] == saved['inputs']['eye']['last_stamp_ns']
    # one quaternion sign everywhere: the service's one line, the file, the topic
    q = ', '.join(f'{v:.4f}' for v in saved['extrinsic']['rotation'])
    assert f'rotation xyzw [{q}]' in answer[0]['message']
    np.testing.assert_allclose(
        latched['extrinsic']['rotation'], saved['extrinsic']['rotation'], atol=1e-12
    )
    # the batch stage ran and its covariance went out: translation variances as in the file
    assert saved['batch']['used']
    cov6 = np.asarray(latched['covariance']).reshape(6, 6)
    np.testing.assert_allclose(np.sqrt(np.diag(cov6)[:3]), saved['std']['translation'], rtol=1e-9)
    np.testing.assert_allclose(cov6, cov6.T, atol=1e-15)
    # the bags replayed offline give the same answer as the node did live, to the bit: the same
    # stamps, order and options, and the worker's BLAS threads (docs/benchmarks.md)
    offline = resolve_executable(ros.env, 'handeye_ros', 'offline_calibrate')
    for spec in bags:
        path = spec.rsplit(':', 1)[0]
        proc = subprocess.run(
            [str(offline), '--bag', path, '--json', '--config', str(params_file(install))],
            env={**ros.env, **BLAS_THREADS},
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
        assert proc.returncode == 0, proc.stderr
        d = json.loads(proc.stdout)
        assert d['time_offset'] == saved['time_offset'], spec
        assert d['extrinsic'] == saved['extrinsic'], spec
        assert d['evaluation'] == saved['evaluation'], spec
    assert ros.stop(node) == 0


def test_one_result_published_consistently(ros: Processes, install: Path, tmp_path: Path) -> None:
    """Every calibrate, successful or not, updates every output together: a result without a
    batch stage replaces the covariance by 'unknown'; a failure turns the diagnostics to
    ERROR and names the latched outputs stale; ~/save writes where output_file now says."""
    first, second = tmp_path / 'first.yaml', tmp_path / 'second.yaml'
    start_node(ros, install, f'output_file:={first}')
    ros.run_json(publisher(ros, '--seed', '4', '--level', '3', '--rate', '1000'), 'publisher')
    assert call(ros, '/calibrator/calibrate', '/calibrator/save', name='with_batch')[1]['success']
    with_batch = yaml.safe_load(first.read_text())
    assert with_batch['batch']['used']

    set_ = ros.run_json(
        ros.script('ros_client.py', 'param', 'batch:=false', f'output_file:={second}'), 'param'
    )
    assert all(r['success'] for r in set_), set_
    answer = call(ros, '/calibrator/calibrate', '/calibrator/save', name='linear')
    assert answer[0]['success'] and answer[1]['success'], answer
    assert str(second) in answer[1]['message']
    linear = yaml.safe_load(second.read_text())
    assert not linear['batch']['used'] and linear['extrinsic'] != with_batch['extrinsic']
    latched = ros.run_json(ros.script('ros_client.py', 'latched'), 'latched_linear')
    np.testing.assert_allclose(
        latched['extrinsic']['translation'], linear['extrinsic']['translation'], atol=1e-12
    )
    assert latched['covariance'][0] == -1.0 and not any(latched['covariance'][1:])
    assert latched['time_offset'] == linear['time_offset']
    assert latched['time_reference']['offset_ns'] == linear['time_offset_ns']
    assert latched['diagnostics']['values']['time_offset_s'] == str(linear['time_offset'])

    # with a scale (and a drift, when the recording is long enough to show one) the batch
    # covariance is 8x8 or 9x9: T_HE's 6x6 block is published (the whole matrix once made the
    # message fail and the calibrate call never answered)
    third = tmp_path / 'third.yaml'
    set_ = ros.run_json(
        ros.script(
            'ros_client.py',
            'param',
            'batch:=true',
            'clock_drift:=true',
            'estimate_scale:=true',
            f'output_file:={third}',
        ),
        'param_drift',
    )
    assert all(r['success'] for r in set_), set_
    answer = call(ros, '/calibrator/calibrate', '/calibrator/save', name='drift')
    assert answer[0]['success'] and answer[1]['success'], answer
    drift = yaml.safe_load(third.read_text())
    assert drift['covariance']['order'][-1] == 'scale', drift['covariance']['order']
    latched = ros.run_json(ros.script('ros_client.py', 'latched'), 'latched_drift')
    assert len(latched['covariance']) == 36 and latched['covariance'][0] > 0.0

    # a failed calibration: ERROR with its reason, no numbers of the old result, 'stale'
    failed = call(
        ros, '/calibrator/reset', '/calibrator/calibrate', '/calibrator/save', name='failed'
    )
    assert not failed[1]['success'] and '0 pose(s) buffered' in failed[1]['message']
    diag = ros.run_json(ros.script('ros_client.py', 'latched'), 'latched_failed')['diagnostics']
    assert diag['level'] == 2 and '0 pose(s) buffered' in diag['message'], diag
    assert list(diag['values']) == ['latched_outputs'], diag
    assert diag['values']['latched_outputs'].startswith('stale: from the calibration of')
    assert failed[2]['success'] and 'the latest calibration failed' in failed[2]['message']


def test_rig_file_gathers_sessions(ros: Processes, install: Path, tmp_path: Path) -> None:
    """With rig_file, each ~/calibrate adds the session (the buffers since ~/reset) to the rig
    file: the second session of the same marker (the same truth, another motion) makes the
    latched extrinsic the rig's of two recordings, and the diagnostics say so."""
    rig = tmp_path / 'rig.yaml'
    start_node(ros, install, f'rig_file:={rig}')
    ros.run_json(publisher(ros, '--seed', '4', '--level', '3', '--rate', '1000'), 'first')
    first = call(ros, '/calibrator/calibrate', name='calibrate_first')[0]
    assert first['success'] and 'T_HE of the rig of 1 recording(s)' in first['message'], first
    reset = call(ros, '/calibrator/reset', name='reset')[0]
    assert reset['success'], reset
    # the same seed draws the same truth first, then another motion for another duration
    truth = ros.run_json(
        publisher(ros, '--seed', '4', '--level', '3', '--rate', '1000', '--duration', '30'),
        'second',
    )['truth']
    second = call(ros, '/calibrator/calibrate', name='calibrate_second')[0]
    assert second['success'] and 'T_HE of the rig of 2 recording(s)' in second['message'], second
    saved = yaml.safe_load(rig.read_text())
    assert len(saved['recordings']) == 2 and len(saved['rig']['used']) == 2
    latched = ros.run_json(ros.script('ros_client.py', 'latched'), 'latched')
    t = latched['extrinsic']['translation']
    np.testing.assert_allclose(t, saved['rig']['extrinsic']['translation'], atol=1e-9)
    assert latched['diagnostics']['values']['rig_recordings'] == '2'
    assert latched['diagnostics']['values']['rig_part'] == 'used'
    assert_near_truth(
        truth,
        {
            'time_offset': latched['time_offset'],
            'extrinsic': {'translation': t, 'rotation': latched['extrinsic']['rotation']},
        },
    )


def test_publish_calibration_latched_or_as_a_bag(install: Path, tmp_path: Path) -> None:
    """A saved result back into ROS: into a bag (latched /tf_static) where tf2_msgs cannot be
    imported; published latched on /tf_static where it can; a file that is no result is
    refused in one line."""
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import QosDurability

    from handeye_ros.core.config import CalibrationConfig
    from handeye_ros.core.pipeline import calibrate
    from handeye_ros.core.simulate import simulate
    from handeye_ros.formats.result_file import write_result

    rec = simulate(2, duration_s=30.0)
    result = calibrate(rec.hand, rec.eye, CalibrationConfig(batch=False)).to_dict(
        hand_frame='marker', eye_frame='body'
    )
    saved = tmp_path / 'calibration.yaml'
    write_result(saved, result)
    env = ros_env(install)
    exe = str(resolve_executable(env, 'handeye_ros', 'publish_calibration'))
    bad = tmp_path / 'bad.yaml'
    bad.write_text('extrinsic: 3\n')
    proc = subprocess.run(
        [exe, str(bad)], env=env, capture_output=True, text=True, timeout=60, check=False
    )
    assert proc.returncode == 1 and 'not a handeye_ros result' in proc.stderr, proc.stderr
    assert 'Traceback' not in proc.stderr

    proc = subprocess.run(
        [exe, str(saved)], env=env, capture_output=True, text=True, timeout=60, check=False
    )
    assert proc.returncode == 0, proc.stderr
    assert 'tf2_msgs cannot be imported' in proc.stderr
    with AnyReader([tmp_path / 'calibration_calibration']) as reader:
        conns = {c.topic: c for c in reader.connections}
        assert [q.durability for q in conns['/tf_static'].ext.offered_qos_profiles] == [
            QosDurability.TRANSIENT_LOCAL
        ]
        msgs = {c.topic: reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()}
    tf = msgs['/tf_static'].transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ('marker', 'body')
    assert msgs['/calibrator/time_offset'].data == result['time_offset']

    live = with_interfaces(env)
    if live is None:
        pytest.skip('tf2_msgs not built (scripts/interfaces): the live /tf_static not tested')
    ros = Processes(live, tmp_path)
    try:
        pub = ros.start([exe, str(saved)], 'publish_calibration')
        got = ros.run_json(ros.script('ros_client.py', 'tf_static'), 'tf_static')
        assert got and (got[0]['parent'], got[0]['child']) == ('marker', 'body'), got
        np.testing.assert_allclose(
            got[0]['translation'], result['extrinsic']['translation'], atol=1e-12
        )
        assert ros.stop(pub) == 0
        assert 'Traceback' not in ros.output(pub)[1]
    finally:
        ros.stop_all()
