"""offline_calibrate --bag: ROS 2 (mcap, sqlite3) and ROS 1 bags written with rosbags, replayed
through the node's Recorder. No ROS processes needed here (see test/ros/test_node_results.py for those)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import recording, run_main

from handeye_ros.core.errors import InputError
from handeye_ros.formats.bag import BagWriter, pose_messages, write_recording
from handeye_ros.stream import PoseBuffer

pytestmark = pytest.mark.slow  # subprocesses, bags, evo, Dask or real data: seconds each


@pytest.fixture(scope='module')
def rec():
    return recording(seed=4, level=3.0, duration_s=40.0)


def _bag(
    tmp_path: Path,
    rec,
    storage: str = 'mcap',
    hand=('/mocap/pose', 'PoseStamped'),
    eye=('/vio/odom', 'Odometry'),
    name: str = 'rec',
) -> Path:
    path = tmp_path / (name + ('.bag' if storage == 'ros1' else ''))
    write_recording(
        path,
        [
            (hand[0], hand[1], rec.hand, 'mocap', 'marker'),
            (eye[0], eye[1], rec.eye, 'odom', 'imu'),
        ],
        storage,
    )
    return path


def _ok(res) -> dict:
    assert res.returncode == 0, res.stderr
    assert 'Traceback' not in res.stderr
    return json.loads(res.stdout)


def _fails(res, *fragments: str) -> None:
    assert res.returncode == 1, (res.stdout, res.stderr)
    assert 'Traceback' not in res.stderr
    for f in fragments:
        assert f in res.stderr, res.stderr


def test_every_storage_and_type_gives_the_same_result(tmp_path: Path, rec) -> None:
    results = []
    for storage, hand_type, eye_type in (
        ('mcap', 'PoseStamped', 'Odometry'),
        ('sqlite3', 'TransformStamped', 'PoseWithCovarianceStamped'),
        ('ros1', 'PoseStamped', 'Odometry'),
    ):
        bag = _bag(
            tmp_path,
            rec,
            storage,
            ('/mocap/pose', hand_type),
            ('/vio/odom', eye_type),
            name=storage,
        )
        d = _ok(run_main('--bag', bag, '--json'))
        assert d['streams']['hand']['received'] == len(rec.hand)
        assert d['streams']['eye']['type'].endswith(eye_type)
        results.append(d)
    # the same poses give the same numbers, to the round-off of sums whose order threaded
    # BLAS does not fix (numpy 1.26's OpenBLAS under load: 1.6e-15 apart once)
    for d in results[1:]:
        assert d['time_offset'] == pytest.approx(results[0]['time_offset'], rel=1e-12)
        for key in ('translation', 'rotation', 'matrix'):
            np.testing.assert_allclose(
                d['extrinsic'][key], results[0]['extrinsic'][key], rtol=1e-12, atol=1e-15
            )
    # the names are the messages' own: a TransformStamped names its child, a PoseStamped none
    assert [d['extrinsic']['parent'] for d in results] == [
        'mocap_marker',
        'marker',
        'mocap_marker',
    ]
    assert abs(results[0]['time_offset'] - rec.truth.time_offset_s) < 3e-3


def test_bag_equals_text_files(tmp_path: Path, rec) -> None:
    """The same poses through a bag or TUM files: the same numbers (up to the text's rounding
    of positions to 1 nm and quaternions to 1e-12, which the batch solve sees)."""
    from handeye_ros.formats import write_tum

    write_tum(tmp_path / 'h.txt', rec.hand)
    write_tum(tmp_path / 'e.txt', rec.eye)
    a = _ok(run_main('--hand', tmp_path / 'h.txt', '--eye', tmp_path / 'e.txt', '--json'))
    b = _ok(run_main('--bag', _bag(tmp_path, rec), '--json'))
    assert a['time_offset'] == pytest.approx(b['time_offset'], abs=1e-7)
    np.testing.assert_allclose(
        a['extrinsic']['translation'], b['extrinsic']['translation'], atol=1e-6
    )


def test_topics_picked_by_name_or_listed(tmp_path: Path, rec) -> None:
    bag = _bag(
        tmp_path,
        rec,
        hand=('/vicon/rig/pose', 'PoseStamped'),
        eye=('/ov_msckf/odomimu', 'Odometry'),
    )
    d = _ok(run_main('--bag', bag, '--json'))
    assert d['streams']['hand']['topic'] == '/vicon/rig/pose'
    unclear = _bag(
        tmp_path, rec, hand=('/a', 'PoseStamped'), eye=('/b', 'Odometry'), name='unclear'
    )
    _fails(
        run_main('--bag', unclear),
        'no pose topic looks like the hand stream',
        '--hand-topic',
        '/a (',
        '/b (',
    )
    d = _ok(run_main('--bag', unclear, '--hand-topic', '/a', '--eye-topic', '/b', '--json'))
    assert d['streams']['eye']['topic'] == '/b'


def test_wrong_topic_empty_bag_unsupported_type(tmp_path: Path, rec) -> None:
    bag = _bag(tmp_path, rec)
    _fails(run_main('--bag', bag, '--hand-topic', '/nope'), 'no topic /nope', '/mocap/pose (')
    empty = tmp_path / 'empty'
    with BagWriter(empty):
        pass
    _fails(run_main('--bag', empty), 'holds no messages')
    imu = tmp_path / 'imu'
    with BagWriter(imu) as w:
        T = w.store.types
        for k in range(5):
            msg = T['sensor_msgs/msg/Imu'](
                header=T['std_msgs/msg/Header'](
                    stamp=T['builtin_interfaces/msg/Time'](sec=k, nanosec=0), frame_id='imu'
                ),
                orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.zeros(9),
                angular_velocity=T['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=T['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0),
                linear_acceleration_covariance=np.zeros(9),
            )
            w.write('/imu', 'sensor_msgs/msg/Imu', k * 10**9, msg)
    _fails(
        run_main('--bag', imu, '--hand-topic', '/imu', '--eye-topic', '/vio/odom'),
        'sensor_msgs/msg/Imu',
        'carries no pose',
    )
    _fails(run_main('--bag', tmp_path / 'absent'), 'no such bag')
    (tmp_path / 'junk.bag').write_text('not a bag')
    _fails(run_main('--bag', tmp_path / 'junk.bag'), 'cannot be read')
    _fails(run_main('--bag', bag, '--hand', 'x.txt'), '--bag PATH')


def test_nan_poses_are_rejected_and_reported(tmp_path: Path, rec) -> None:
    p = rec.eye.p_xyz.copy()
    p[::25] = np.nan
    from handeye_ros.core.trajectory import Trajectory

    bad_eye = Trajectory(rec.eye.t_ns, p, rec.eye.q_xyzw, 'eye')
    bag = tmp_path / 'nan'
    write_recording(
        bag,
        [
            ('/mocap/pose', 'PoseStamped', rec.hand, 'm', 'h'),
            ('/vio/odom', 'Odometry', bad_eye, 'o', 'e'),
        ],
    )
    d = _ok(run_main('--bag', bag, '--json'))
    n_bad = int(np.isnan(p[:, 0]).sum())
    assert d['streams']['eye']['rejected']['non_finite'] == n_bad
    assert any('rejected' in w and 'non finite' in w for w in d['warnings'])


def test_output_bag_holds_the_result(tmp_path: Path, rec) -> None:
    from bag_layouts import offset_of
    from rosbags.highlevel import AnyReader
    from rosbags.interfaces import QosDurability

    out = tmp_path / 'result_bag'
    d = _ok(
        run_main(
            '--bag',
            _bag(tmp_path, rec),
            '--json',
            '--output-bag',
            out,
            '--hand-frame-id',
            'marker',
            '--eye-frame-id',
            'body',
        )
    )
    with AnyReader([out]) as reader:
        msgs = {c.topic: reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages()}
        # every topic latched, as the node's and tf2's static broadcaster's
        for c in reader.connections:
            qos = c.ext.offered_qos_profiles
            assert [q.durability for q in qos] == [QosDurability.TRANSIENT_LOCAL], c.topic
    tf = msgs['/tf_static'].transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ('marker', 'body')
    np.testing.assert_allclose(
        [tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z],
        d['extrinsic']['translation'],
    )
    assert msgs['/calibrator/extrinsic'] == tf
    assert msgs['/calibrator/time_offset'].data == d['time_offset']
    ref = msgs['/calibrator/time_reference']
    # the offset to the nanosecond, between the frames it relates, at an eye-clock instant
    assert offset_of(ref) == pytest.approx(d['time_offset'], abs=1e-9)
    assert (ref.header.frame_id, ref.source) == ('body', 'marker')
    assert (
        ref.header.stamp.sec * 10**9 + ref.header.stamp.nanosec
        == d['inputs']['eye']['last_stamp_ns']
    )
    cov = np.asarray(msgs['/calibrator/extrinsic_with_covariance'].pose.covariance)
    assert np.sqrt(cov[[0, 7, 14]]) == pytest.approx(d['std']['translation'], rel=1e-9)


def test_frames_come_from_the_messages(tmp_path: Path, rec) -> None:
    """With no frame options, the result names the frames the bag's messages carry; an option
    still wins, and a PoseStamped (no child frame) falls back to the default name."""
    bag = tmp_path / 'frames'
    write_recording(
        bag,
        [
            ('/mocap/pose', 'TransformStamped', rec.hand, 'vicon', 'rig_marker'),
            ('/vio/odom', 'Odometry', rec.eye, '/odom_vio', 'body_imu'),
        ],
    )
    d = _ok(run_main('--bag', bag, '--json'))
    assert (d['extrinsic']['parent'], d['extrinsic']['child']) == ('rig_marker', 'body_imu')
    assert (d['world_alignment']['parent'], d['world_alignment']['child']) == ('odom_vio', 'vicon')
    assert d['streams']['hand']['frames'] == {'world': 'vicon', 'body': 'rig_marker'}
    d = _ok(run_main('--bag', bag, '--json', '--eye-frame-id', 'imu_link'))
    assert d['extrinsic']['child'] == 'imu_link'
    plain = tmp_path / 'plain'
    write_recording(
        plain,
        [
            ('/mocap/pose', 'PoseStamped', rec.hand, 'vicon', ''),
            ('/vio/odom', 'Odometry', rec.eye, 'odom', 'imu'),
        ],
    )
    d = _ok(run_main('--bag', plain, '--json'))
    assert d['extrinsic']['parent'] == 'mocap_marker'


def test_buffer_bounds_drop_oldest_and_count() -> None:
    b = PoseBuffer('b', capacity=100, max_duration_s=2.0)
    for k in range(1, 1001):
        assert b.add((k * 10_000_000, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)) is None
    s = b.stats()
    assert s.stored == 100 and s.dropped == 900 and s.received == 1000
    assert b.trajectory().t_ns[0] == 901 * 10_000_000
    b2 = PoseBuffer('b2', capacity=10_000, max_duration_s=2.0)
    for k in range(1, 1001):
        b2.add((k * 10_000_000, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0))
    assert b2.stats().span_s <= 2.0 and b2.stats().dropped == 1000 - 201
    assert b2.add((5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)) == 'stamp_not_increasing'
    assert b2.add((0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)) == 'zero_stamp'
    assert b2.add((1000 * 10_000_000, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)) == 'stamp_repeated'
    assert b2.add((10**12, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)) == 'zero_quaternion'
    assert b2.add((10**12, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.5)) == 'non_unit_quaternion'
    assert b2.stats().rejected == {
        'non_finite': 0,
        'zero_quaternion': 1,
        'non_unit_quaternion': 1,
        'zero_stamp': 1,
        'stamp_repeated': 1,
        'stamp_not_increasing': 1,
        'not_in_message': 0,
    }
    # the stream's clock ticked for the 1000 stored poses and the one that went back in time
    assert b2.ticked == 1001
    b2.add((2 * 10**12, float('nan'), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0))  # a lost marker's
    b2.reject('not_in_message')
    assert b2.ticked == 1001


def test_unset_stamps_are_named_and_arrival_time_is_the_way_out(tmp_path: Path, rec) -> None:
    """A MoCap driver that leaves header.stamp at zero: the failure names the cause and the
    option; with use_arrival_time the bag's record times stamp the poses, and the result says
    so."""
    bag = tmp_path / 'zero'
    with BagWriter(bag) as w:
        zero = w.store.types['builtin_interfaces/msg/Time'](sec=0, nanosec=0)
        items = []
        for t, m in pose_messages(w.store, rec.hand, 'PoseStamped', 'mocap', ''):
            m.header.stamp = zero
            items.append((t, '/mocap/pose', 'geometry_msgs/msg/PoseStamped', m))
        items += [
            (t, '/vio/odom', 'nav_msgs/msg/Odometry', m)
            for t, m in pose_messages(w.store, rec.eye, 'Odometry', 'odom', 'imu')
        ]
        for t, topic, msgtype, m in sorted(items, key=lambda x: x[0]):
            w.write(topic, msgtype, t, m)
    _fails(
        run_main('--bag', bag, '--json'), 'had no stamp (header.stamp 0)', 'use_arrival_time: hand'
    )
    d = _ok(run_main('--bag', bag, '--json', '--use-arrival-time', 'hand'))
    assert (d['streams']['hand']['stamps'], d['streams']['eye']['stamps']) == ('arrival', 'header')
    assert any('stamped on arrival' in w for w in d['warnings'])
    # the recorder's clock is the true one here: the offset as from the stamps
    assert abs(d['time_offset'] - rec.truth.time_offset_s) < 3e-3


def test_a_bag_that_cannot_be_written_is_said(tmp_path: Path) -> None:
    """A folder that cannot be made there (a file in the way, a path under /proc) is an
    InputError naming the path, as a bag that exists already is."""
    (tmp_path / 'file').write_text('')
    for where in (tmp_path / 'file' / 'bag', Path('/proc/handeye_bag')):
        with pytest.raises(InputError, match='cannot write the bag'), BagWriter(where):
            pass
    (tmp_path / 'bag').mkdir()
    with pytest.raises(InputError, match='exists already'):
        BagWriter(tmp_path / 'bag')
    # the readers tell ROS 1 from ROS 2 by the name alone: a bag they could not read is refused
    with pytest.raises(InputError, match=r'a ROS 1 bag is one file named \*\.bag'):
        BagWriter(tmp_path / 'one', 'ros1')
    with pytest.raises(InputError, match='a ROS 2 bag .mcap. is a folder whose name does not'):
        BagWriter(tmp_path / 'two.bag')
    ros1 = tmp_path / 'rec.bag'
    with BagWriter(ros1, 'ros1'):
        pass
    ros1.rename(tmp_path / 'renamed')
    _fails(run_main('--bag', tmp_path / 'renamed'), 'it is a ROS 1 bag, which the readers know')
