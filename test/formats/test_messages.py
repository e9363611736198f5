"""The output messages of a result, built without DDS: the same builders fill rosbags' classes
(the output bag) and rclpy's (the node, publish_calibration), and their numbers must be the
result's own."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from bag_layouts import offset_of

from handeye_ros.formats import messages
from handeye_ros.formats.bag import _typestore
from handeye_ros.formats.result_file import read_result, write_result

E = {
    'parent': 'marker',
    'child': 'imu',
    'translation': [0.1, -0.2, 0.3],
    'rotation': [0.0, 0.0, np.sin(0.25), np.cos(0.25)],
}


def _document(dt_ns: int, covariance: bool, eye_last_ns: int = 1_700_000_000_123_456_789) -> dict:
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


def _result(dt_ns: int, covariance: bool, eye_last_ns: int = 1_700_000_000_123_456_789):
    """What the outputs are made of, read back from a result file's contents."""
    return messages.Published.from_document(_document(dt_ns, covariance, eye_last_ns))


@pytest.mark.parametrize('dt_ns', [87_300_123, -4_999_917_129_833, 0])
def test_time_reference_holds_the_offset_to_the_nanosecond(dt_ns: int) -> None:
    ref = messages.time_reference(_typestore().types, _result(dt_ns, False))
    assert (ref.header.frame_id, ref.source) == ('imu', 'marker')
    assert ref.header.stamp.sec * 10**9 + ref.header.stamp.nanosec == 1_700_000_000_123_456_789
    stamp, time_ref = ref.header.stamp, ref.time_ref
    assert (stamp.sec - time_ref.sec) * 10**9 + stamp.nanosec - time_ref.nanosec == dt_ns
    assert offset_of(ref) == pytest.approx(dt_ns * 1e-9, abs=1e-12)


def test_time_reference_left_out_when_a_clock_is_no_ros_time() -> None:
    """A boot clock (eye stamps of a few seconds) minus a larger offset is before 1970."""
    boot = _result(1_700_000_000 * 10**9, False, eye_last_ns=30 * 10**9)
    assert messages.time_reference(_typestore().types, boot) is None
    assert messages.TIME_REFERENCE not in messages.outputs(_typestore().types, boot, 10**9)


def test_covariance_in_ros_order_or_marked_unknown() -> None:
    d = _document(0, True)
    cov = messages.extrinsic_covariance(messages.Published.from_document(d)).reshape(6, 6)
    A = np.asarray(d['covariance']['matrix'])[1:, 1:]
    R = np.asarray(d['extrinsic']['matrix'])[:3, :3]
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
    assert offset_of(ours[messages.TIME_REFERENCE]) == offset_of(bag[messages.TIME_REFERENCE])
    np.testing.assert_array_equal(
        ours[messages.EXTRINSIC_WITH_COVARIANCE].pose.covariance,
        bag[messages.EXTRINSIC_WITH_COVARIANCE].pose.covariance,
    )


def test_read_result_round_trip_and_refusals(tmp_path) -> None:
    good = tmp_path / 'r.json'
    write_result(good, _document(3, False))
    assert read_result(good)['extrinsic']['parent'] == 'marker'
    for name, text in (('a.yaml', 'extrinsic: 3\n'), ('b.yaml', '[1, 2\n'), ('c.yaml', '')):
        (tmp_path / name).write_text(text)
        with pytest.raises(Exception, match='not a handeye_ros result|not YAML or JSON') as err:
            read_result(tmp_path / name)
        assert type(err.value).__name__ == 'InputError'
    with pytest.raises(Exception, match='cannot read'):
        read_result(tmp_path / 'missing.yaml')


@pytest.mark.parametrize('options', [{}, {'clock_drift': True}, {'estimate_scale': True}])
def test_a_result_and_its_file_publish_the_same(options: dict) -> None:
    """The node publishes from the typed result, publish_calibration and the bag writer from
    the result file: both must give the same messages. With a clock drift or a scale the
    covariance is 8x8 or 9x9, and only its translation and rotation block is T_HE's (the
    9x9 once gave a 64-value covariance that no message takes)."""
    from handeye_ros.core.config import CalibrationConfig
    from handeye_ros.core.pipeline import calibrate
    from handeye_ros.core.simulate import simulate

    rec = simulate(3, duration_s=40.0, clock_drift=50e-6, scale=0.8)
    result = calibrate(rec.hand, rec.eye, CalibrationConfig(**options))
    assert result.batch is not None
    frames = {'hand': 'marker', 'eye': 'imu', 'hand_world': 'mocap', 'eye_world': 'odom'}
    doc = result.to_dict(hand_frame='marker', eye_frame='imu')
    typed = messages.Published.from_result(result, frames)
    read = messages.Published.from_document(doc)
    types = _typestore().types
    a, b = messages.outputs(types, typed, 11), messages.outputs(types, read, 11)
    assert set(a) == set(b) == set(messages.OUTPUT_TYPES)
    assert a[messages.EXTRINSIC] == b[messages.EXTRINSIC]
    assert a[messages.TIME_REFERENCE] == b[messages.TIME_REFERENCE]
    assert a[messages.TIME_OFFSET] == b[messages.TIME_OFFSET]
    cov_a = a[messages.EXTRINSIC_WITH_COVARIANCE].pose.covariance
    np.testing.assert_array_equal(cov_a, b[messages.EXTRINSIC_WITH_COVARIANCE].pose.covariance)
    assert cov_a.shape == (36,) and cov_a[0] > 0.0
    # the detached result (what the node keeps) says the same
    assert result.detached().to_dict(hand_frame='marker', eye_frame='imu') == doc
