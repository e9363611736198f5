"""Options of the calibrator node itself (services, periodic work, QoS); no rclpy here.

With :class:`~handeye_ros.core.config.CalibrationConfig` and
:class:`~handeye_ros.stream.config.StreamConfig` these are all of the node's parameters.
The offline tool reads the same params file and ignores these.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..core.config import CalibrationConfig
from ..core.options import Options, option
from ..stream.config import StreamConfig


@dataclass(frozen=True)
class NodeConfig(Options):
    """Node-only behaviour."""

    output_file: str = option(
        'handeye_result.yaml', 'str', 'where ~/save writes the last result (YAML, or JSON for '
        '.json); relative to the working directory')
    report_dir: str = option(
        '', 'str', 'where ~/save also writes report.html and its plots (empty: no report); '
        'each calibration then draws its report in the worker, ready for ~/save')
    calibrate_period: float = option(
        0.0, 'float', 'run the calibration every this many seconds while data flow (online use); '
        '0 disables', low=0.0, high=86_400.0)
    diagnostics_period: float = option(
        1.0, 'float', 'period of the /diagnostics status [s]', low=0.05, high=3600.0)
    qos_reliability: str = option(
        'best_effort', 'str', 'subscription reliability: best_effort also receives from reliable '
        'publishers and matches sensor-data MoCap drivers; reliable matches reliable ones only',
        choices=('best_effort', 'reliable'))
    qos_depth: int = option(
        1000, 'int', 'subscription queue depth: deep enough that bursts are not dropped',
        low=1, high=1_000_000)
    topic_wait: float = option(
        30.0, 'float', 'with hand_type/eye_type auto: how long to wait for a publisher to learn '
        'the type before warning again [s]', low=0.1, high=86_400.0)


#: Parameters the offline tool ignores in a node params file (ROS's own use_sim_time too).
NODE_ONLY_KEYS = frozenset(NodeConfig.specs()) | {'use_sim_time'}


def all_specs() -> dict:
    """Every node parameter name -> Spec (algorithm, streams, node)."""
    return {**CalibrationConfig.specs(), **StreamConfig.specs(), **NodeConfig.specs()}


PARAMS_HEADER = """\
# Parameters of the calibrator node (ros2 run handeye_ros calibrator --ros-args
# --params-file config/calibrator.yaml). offline_calibrate --config reads the same file and
# ignores the node-only block. Every value is the default. Units: s, m, deg, Hz, rad.
# Generated from the option specs by handeye_ros.ros.config.params_yaml(); do not edit.
"""


def params_yaml() -> str:
    """The node's params file with every parameter at its default and its description (the
    text of config/calibrator.yaml; a test checks that the shipped file is this)."""
    import textwrap

    import yaml
    blocks = (('pose streams (node and bag replay)', StreamConfig),
              ("algorithm (same names as offline_calibrate's options)", CalibrationConfig),
              ('node only', NodeConfig))
    lines = [PARAMS_HEADER.rstrip('\n'), 'calibrator:', '  ros__parameters:']
    for title, cls in blocks:
        lines.append(f'    # --- {title} '.ljust(99, '-'))
        defaults = cls().to_dict()
        for name, spec in cls.specs().items():
            rng = spec.range_text() if not spec.choices else ''
            text = spec.description + (f' {rng}' if rng else '')
            lines += textwrap.wrap(text, 99, initial_indent='    # ', subsequent_indent='    # ')
            value = defaults[name]
            value = float('nan') if value is None else value
            lines.append(f'    {yaml.safe_dump({name: value}, default_flow_style=True)[1:-2]}')
    return '\n'.join(lines) + '\n'
