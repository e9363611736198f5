"""The output messages of a result, built without DDS: the same builders fill rosbags' classes
(the output bag) and rclpy's (the node, publish_calibration), and their numbers must be the
result's own."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from handeye_ros.formats.bag import _typestore
from handeye_ros.report import read_result, write_result
from handeye_ros.stream import messages

E = {
    'parent': 'marker',
    'child': 'imu',
    'translation': [0.1, -0.2, 0.3],
    'rotation': [0.0, 0.0, np.sin(0.25), np.cos(0.25)],
}


def _result(dt_ns: int, covariance: bool, eye_last_ns: int = 1_700_000_000_123_456_789) -> dict:
    from scipy.spatial.transform import Rotation

    M = np.eye(4)
    M[:3, :3] = Rotation.from_quat(E['rotation']).as_matrix()
    M[:3, 3] = E['translation']
    cov = None
    if covariance:
        A = np.random.default_rng(1).normal(size=(7, 7))
        cov = {'matrix': (A @ A.T).tolist()}
    return {
        'extrinsic': {**E, 'matrix': M.tolist()},
        'time_offset': dt_ns * 1e-9,
        'time_offset_ns': dt_ns,
        'time_offset_stamp_ns': None,
        'covariance': cov,
        'inputs': {'eye': {'last_stamp_ns': eye_last_ns}},
    }


@pytest.mark.parametrize('dt_ns', [87_300_123, -4_999_917_129_833, 0])
def test_time_reference_holds_the_offset_to_the_nanosecond(dt_ns: int) -> None:
    ref = messages.time_reference(_typestore().types, _result(dt_ns, False))
    assert (ref.header.frame_id, ref.source) == ('imu', 'marker')
    assert ref.header.stamp.sec * 10**9 + ref.header.stamp.nanosec == 1_700_000_000_123_456_789
    stamp, time_ref = ref.header.stamp, ref.time_ref
    assert (stamp.sec - time_ref.sec) * 10**9 + stamp.nanosec - time_ref.nanosec == dt_ns
    assert messages.offset_of(ref) == pytest.approx(dt_ns * 1e-9, abs=1e-12)


def test_time_reference_left_out_when_a_clock_is_no_ros_time() -> None:
    """A boot clock (eye stamps of a few seconds) minus a larger offset is before 1970."""
    boot = _result(1_700_000_000 * 10**9, False, eye_last_ns=30 * 10**9)
    assert messages.time_reference(_typestore().types, boot) is None
    assert messages.TIME_REFERENCE not in messages.outputs(_typestore().types, boot, 10**9)


def test_covariance_in_ros_order_or_marked_unknown() -> None:
    r = _result(0, True)
    cov = messages.extrinsic_covariance(r).reshape(6, 6)
    A = np.asarray(r['covariance']['matrix'])[1:, 1:]
    R = np.asarray(r['extrinsic']['matrix'])[:3, :3]
    np.testing.assert_allclose(cov[:3, :3], A[:3, :3], atol=1e-12)  # translation as is
    np.testing.assert_allclose(cov[3:, 3:], R @ A[3:, 3:] @ R.T, atol=1e-12)  # to H's axes
    np.testing.assert_allclose(cov, cov.T, atol=1e-12)
    unknown = messages.extrinsic_covariance(_result(0, False))
    assert unknown[0] == -1.0 and not unknown[1:].any()


def test_every_output_from_one_result_with_one_stamp() -> None:
    out = messages.outputs(_typestore().types, _result(5, True), 42)
    assert set(out) == set(messages.OUTPUT_TYPES)
    tf, pwc = out[messages.EXTRINSIC], out[messages.EXTRINSIC_WITH_COVARIANCE]
    assert tf.header.stamp.nanosec == pwc.header.stamp.nanosec == 42
    assert (tf.header.frame_id, tf.child_frame_id) == ('marker', 'imu')
    assert [tf.transform.rotation.z, tf.transform.rotation.w] == E['rotation'][2:]
    assert pwc.pose.pose.position.y == E['translation'][1]
    assert out[messages.TIME_OFFSET].data == 5e-9


@pytest.mark.skipif(importlib.util.find_spec('rclpy') is None, reason='rclpy not installed')
def test_rclpy_classes_get_the_same_content() -> None:
    from handeye_ros.ros.types import RclpyTypes

    r = _result(87_300_123, True)
    ours, bag = messages.outputs(RclpyTypes(), r, 7), messages.outputs(_typestore().types, r, 7)
    assert type(ours[messages.TIME_REFERENCE]).__module__.startswith('sensor_msgs')
    assert messages.offset_of(ours[messages.TIME_REFERENCE]) == messages.offset_of(
        bag[messages.TIME_REFERENCE]
    )
    np.testing.assert_array_equal(
        ours[messages.EXTRINSIC_WITH_COVARIANCE].pose.covariance,
        bag[messages.EXTRINSIC_WITH_COVARIANCE].pose.covariance,
    )


def test_read_result_round_trip_and_refusals(tmp_path) -> None:
    good = tmp_path / 'r.json'
    write_result(good, _result(3, False))
    assert read_result(good)['extrinsic']['parent'] == 'marker'
    for name, text in (('a.yaml', 'extrinsic: 3\n'), ('b.yaml', '[1, 2\n'), ('c.yaml', '')):
        (tmp_path / name).write_text(text)
        with pytest.raises(Exception, match='not a handeye_ros result|not YAML or JSON') as err:
            read_result(tmp_path / name)
        assert type(err.value).__name__ == 'InputError'
    with pytest.raises(Exception, match='cannot read'):
        read_result(tmp_path / 'missing.yaml')
