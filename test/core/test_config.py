"""Options: one set of names for the YAML file, the CLI and the node; bad values refused."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from conftest import ROOT

from handeye_ros.app.params_file import NodeConfig, params_yaml
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import ConfigError
from handeye_ros.stream.config import StreamConfig


def test_defaults_are_the_papers() -> None:
    c = CalibrationConfig()
    assert (c.eta, c.mu, c.inlier_rotation, c.inlier_translation) == (5.0, 5.0, 0.5, 0.02)
    assert c.relative_poses == 'rotation' and c.robust_kernel and c.peak_fit == 'quadratic'


def test_option_choices_are_the_owners_names() -> None:
    from handeye_ros.core.config import RELATIVE_POSES
    from handeye_ros.core.linear.keyframes import STRATEGIES

    assert RELATIVE_POSES == tuple(STRATEGIES)


def test_shipped_params_file_matches_the_defaults() -> None:
    """config/calibrator.yaml documents every parameter at its default, and nothing unknown;
    it is the generated text (regenerate with handeye_ros.app.params_file.params_yaml())."""
    text = (ROOT / 'config' / 'calibrator.yaml').read_text()
    assert text == params_yaml(), 'regenerate config/calibrator.yaml from params_yaml()'
    params = yaml.safe_load(text)
    values = params['/**/calibrator']['ros__parameters']
    parts = (CalibrationConfig, StreamConfig, NodeConfig)
    assert set(values) == {k for cls in parts for k in cls.specs()}
    for cls in parts:
        assert cls.from_mapping({k: values[k] for k in cls.specs()}) == cls()


def test_a_user_reads_at_most_fifteen_options() -> None:
    """The params file's first section and the node's --help show the options a rig sets (the
    topics, frames, offset search, drift, scale, precision targets, where ~/save writes, auto
    mode); every other is expert: below, in the file's expert sections, and named in --help."""
    import re

    from handeye_ros.app.params_file import usage

    first = params_yaml().split('# --- expert')[0]
    users = re.findall(r'^    (\w+):', first, flags=re.MULTILINE)
    shown = re.findall(r'^  (\w+)(?: \*)? \(default', usage(), flags=re.MULTILINE)
    every = {
        k: s
        for cls in (StreamConfig, CalibrationConfig, NodeConfig)
        for k, s in cls.specs().items()
    }
    assert sorted(users) == sorted(shown) and len(users) <= 15
    assert set(users) == {k for k, s in every.items() if not s.expert}
    assert all(k in usage() for k, s in every.items() if s.expert)


def test_stream_and_node_options() -> None:
    with pytest.raises(ConfigError, match='hand_type.*Imu'):
        StreamConfig(hand_type='Imu')
    assert StreamConfig(eye_type='Odometry').eye_type == 'Odometry'
    with pytest.raises(ConfigError, match='buffer_size must lie in'):
        StreamConfig.from_mapping({'buffer_size': 1})
    with pytest.raises(ConfigError, match='qos_reliability must be one of'):
        NodeConfig(qos_reliability='sometimes')
    # one topic for both streams: only as two items of tf or RigidBodies (the node, subscribing
    # it twice with two likely types, ended in rcl's traceback)
    both = 'options hand_topic and eye_topic both read /vio/odom'
    with pytest.raises(ConfigError, match=both):
        StreamConfig(hand_topic='/vio/odom', eye_topic='/vio/odom')
    with pytest.raises(ConfigError, match='both read /bodies'):
        StreamConfig(hand_topic='/bodies:rig', eye_topic=' /bodies:rig')
    assert StreamConfig(hand_topic='/bodies:wand', eye_topic='/bodies:rig').eye_topic
    assert StreamConfig(hand_topic='/tf:world.marker', eye_topic='/tf:odom.imu').hand_topic


@pytest.mark.parametrize(
    ('values', 'message'),
    [
        ({'etaa': 5.0}, 'unknown option.*etaa'),
        ({'eta': 'five'}, 'eta must be of type float'),
        ({'eta': 0.0}, 'eta must lie in'),
        ({'mu': -1.0}, 'mu must lie in'),
        ({'ransac_iterations': 2.5}, 'ransac_iterations must be of type int'),
        ({'batch': 1}, 'batch must be of type bool'),
        ({'purpose': 'keyframes'}, 'purpose must be one of'),
        # the paper's ablation switches are no user's options (only bench/ and tests set them)
        ({'robust_kernel': False}, 'unknown option.*robust_kernel'),
        ({'peak_fit': 'none'}, 'unknown option.*peak_fit'),
        ({'max_time_offset': 0.0}, 'max_time_offset must lie in'),
        ({'max_time_offset': float('inf')}, 'max_time_offset must be a finite number'),
        ({'min_motions': 1}, 'min_motions must lie in'),
    ],
)
def test_bad_values_are_refused_by_name(values: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        CalibrationConfig.from_mapping(values, source='my.yaml')


def test_nan_and_null_mean_estimate() -> None:
    c = CalibrationConfig.from_mapping({'time_offset': float('nan'), 'resample_rate_hz': None})
    assert c.time_offset is None and c.resample_rate_hz is None
    assert CalibrationConfig.from_mapping({'time_offset': 0}).time_offset == 0.0


def test_source_named_in_messages(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match='my.yaml'):
        CalibrationConfig.from_mapping({'nope': 1}, source='my.yaml')
