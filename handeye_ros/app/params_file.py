"""The node's parameters: its own options (services, periodic work, QoS), the params file and
``--help`` generated from every option's spec; no rclpy here.

With :class:`~handeye_ros.core.config.CalibrationConfig` and
:class:`~handeye_ros.stream.config.StreamConfig` these are all of the node's parameters. The
offline tool reads the same params file and ignores the node's own block
(:data:`NODE_ONLY_KEYS`), which is why this lives beside it, below :mod:`handeye_ros.ros`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..core.config import CalibrationConfig
from ..core.options import Options, Spec, option
from ..stream.config import StreamConfig


@dataclass(frozen=True)
class NodeConfig(Options):
    """Node-only behaviour."""

    output_dir: str = option(
        '',
        'str',
        'the folder the node writes in, and only there: output_file, report_dir and rig_file '
        'are paths inside it (empty: $ROS_HOME/handeye_ros, ~/.ros/handeye_ros without '
        'ROS_HOME); read only once the node runs',
        expert=True,
    )
    output_file: str = option(
        'handeye_result.yaml',
        'str',
        'where ~/save writes the last result (YAML, or JSON for .json), inside output_dir; '
        'an existing file is replaced only when it is a result; may be set while the node runs',
    )
    report_dir: str = option(
        '',
        'str',
        'where ~/save also writes report.html and its plots, inside output_dir (empty: no '
        'report); each calibration then draws its report in the worker, ready for ~/save; may '
        'be set while the node runs (the next calibration draws the report)',
    )
    rig_file: str = option(
        '',
        'str',
        'a rig file inside output_dir (offline_calibrate --rig -o, or one this node wrote; made '
        'when missing): each ~/calibrate adds this session (the buffers since the start or '
        "~/reset) to its recordings, and the latched extrinsic becomes the rig's T_HE when the "
        'session agrees with the rig (empty: off); may be set while the node runs',
        expert=True,
    )
    calibrate_period: float = option(
        0.0,
        'float',
        'run the calibration every this many seconds while data flow (online use); 0 disables',
        low=0.0,
        high=86_400.0,
        expert=True,
    )
    status_period: float = option(
        1.0,
        'float',
        'period of the readiness status while recording [s]: READY (the latest calibration of '
        'the buffers is good), how far the device turned, what is missing; on ~/status, '
        '/diagnostics and one log line. Its calibrations (each second of growth) take up to '
        'half a core in the worker; 0 disables (and with it the calibrations that check READY '
        'and auto_calibrate)',
        low=0.0,
        high=3600.0,
        expert=True,
    )
    auto_calibrate: bool = option(
        False,
        'bool',
        "publish the status's calibrations that are good for the purpose (READY), as the "
        'buffers grow, until the reported sigmas stop improving or the buffers are full (said '
        'in the status); ~/calibrate works at any time',
    )
    diagnostics_period: float = option(
        1.0,
        'float',
        'period of the /diagnostics status [s]',
        low=0.05,
        high=3600.0,
        expert=True,
    )
    qos_reliability: str = option(
        'best_effort',
        'str',
        'subscription reliability: best_effort also receives from reliable '
        'publishers and matches sensor-data MoCap drivers; reliable matches reliable ones only',
        choices=('best_effort', 'reliable'),
        expert=True,
    )
    # 5 s of a 1 kHz stream: DDS keeps at most this many messages for a reader that does not
    # take them, so a stall of the executor loses about stall x rate - depth (a second or two
    # under load loses nothing: bench/results/node.md); an idle queue costs nothing
    qos_depth: int = option(
        5000,
        'int',
        'subscription queue depth: deep enough that bursts and stalls lose nothing',
        low=1,
        high=1_000_000,
        expert=True,
    )
    topic_wait: float = option(
        30.0,
        'float',
        'with hand_type/eye_type auto: how long to wait for a publisher to learn '
        'the type before warning again [s]',
        low=0.1,
        high=86_400.0,
        expert=True,
    )


#: Node parameters that may change while the node runs: the algorithm options and where
#: ~/save writes. The others shape subscriptions and buffers and are read once.
RUNTIME_NODE_KEYS = frozenset({'output_file', 'report_dir', 'rig_file'})
RUNTIME_KEYS = frozenset(CalibrationConfig.specs()) | RUNTIME_NODE_KEYS

#: Parameters earlier versions had, still in users' params files: ignored, with why.
REMOVED = {
    'type_probes': 'the type probes were removed: they changed nothing measurable '
    '(bench/RESULTS.md); remove it from the params file',
    'vector_refinement': 'the vector refinement of the time offset was removed: the batch '
    'stage refines the offset, and the final results are the same without it '
    '(bench/results/trust.md); remove it from the params file',
}
#: Parameters the offline tool ignores in a node params file (ROS's own use_sim_time too).
NODE_ONLY_KEYS = frozenset(NodeConfig.specs()) | {'use_sim_time'} | frozenset(REMOVED)


def all_specs() -> dict[str, Spec]:
    """Every node parameter name -> Spec (algorithm, streams, node)."""
    return {**CalibrationConfig.specs(), **StreamConfig.specs(), **NodeConfig.specs()}


PARAMS_HEADER = """\
# Parameters of the calibrator node, every one at its default. Copy this file, change what your
# rig needs (the first section: the topics, the frames, auto_calibrate, ...) and pass your copy:
#   ros2 run handeye_ros calibrator --ros-args --params-file my_calibrator.yaml
#   ros2 launch handeye_ros calibrator.launch.py params_file:=my_calibrator.yaml
# The section /**/calibrator applies to the node in any namespace. offline_calibrate --config
# reads the same file and ignores the node's own parameters. The expert sections hold what few
# rigs need to change. Units: s, m, deg, Hz, rad. (The shipped
# file is made from the option specs by handeye_ros.app.params_file.params_yaml().)
"""
#: The params file's section: the calibrator in any namespace. (Not /**: a -p value of another
#: type than the file's is then silently dropped by rcl, the file's kept.)
PARAMS_SECTION = '/**/calibrator'


def _described(spec: Spec) -> str:
    """An option's description with its range (a choice lists its values apart)."""
    rng = spec.range_text() if not spec.choices else ''
    return spec.description + (f' {rng}' if rng else '')


def params_yaml() -> str:
    """The node's params file with every parameter at its default and its description (the
    text of config/calibrator.yaml; a test checks that the shipped file is this)."""
    import textwrap

    import yaml

    blocks = (
        ('pose streams (node and bag replay)', StreamConfig),
        ("algorithm (same names as offline_calibrate's options)", CalibrationConfig),
        ('node only', NodeConfig),
    )
    sections = [('what a rig needs', [(c, False) for _, c in blocks])]
    sections += [(f'expert: {title}', [(c, True)]) for title, c in blocks]
    lines = [PARAMS_HEADER.rstrip('\n'), f'{PARAMS_SECTION}:', '  ros__parameters:']
    for title, parts in sections:
        lines.append(f'    # --- {title} '.ljust(99, '-'))
        for cls, expert in parts:
            defaults = cls().to_dict()
            for name, spec in cls.specs().items():
                if spec.expert != expert:
                    continue
                text = _described(spec)
                lines += textwrap.wrap(
                    text, 99, initial_indent='    # ', subsequent_indent='    # '
                )
                value = defaults[name]
                value = float('nan') if value is None else value
                lines.append(f'    {yaml.safe_dump({name: value}, default_flow_style=True)[1:-2]}')
    return '\n'.join(lines) + '\n'


USAGE = """\
usage: calibrator [-h] [--ros-args [-p NAME:=VALUE ...] [--params-file FILE] ...]

The handeye_ros calibrator node: buffers a MoCap pose stream (the hand, marker frame H in the
MoCap world G) and a VO/VIO pose stream (the eye, body frame E in the VIO world W), and on
request estimates the time offset dt (eye clock minus hand clock) and the extrinsic T_HE, with
T_WE(t) = T_WG * T_GH(t - dt) * T_HE.

services (std_srvs/Trigger), under the node's name (/calibrator by default):
  ~/calibrate   calibrate on a copy of the buffers (the answer holds the one-line result)
  ~/reset       empty the buffers
  ~/save        write the last result to output_file (and the report to report_dir); both
                parameters may be changed at run time (ros2 param set)
latched topics: ~/extrinsic (geometry_msgs/TransformStamped, H -> E), and on /tf_static where
  tf2_msgs is importable; ~/extrinsic_with_covariance (geometry_msgs/PoseWithCovarianceStamped);
  ~/time_offset (std_msgs/Float64, s); ~/time_reference (sensor_msgs/TimeReference: header
  stamp on the eye clock, time_ref the same instant on the hand clock). Status: /diagnostics.
Ctrl-C, SIGINT or SIGTERM stop the node (exit code 0).

parameters a rig sets (* may change at run time; every one, the expert ones too, with its
default and description in config/calibrator.yaml):
"""


def usage(command: str = 'calibrator') -> str:
    """The text of ``calibrator --help`` (``command``: the one typed): what the node does and
    every parameter."""
    import textwrap

    defaults = {
        **CalibrationConfig().to_dict(),
        **StreamConfig().to_dict(),
        **NodeConfig().to_dict(),
    }
    lines = [USAGE.rstrip('\n').replace('usage: calibrator', f'usage: {command}', 1)]
    specs = all_specs()
    for name, spec in specs.items():
        if spec.expert:
            continue
        value = defaults[name]
        shown = 'automatic' if value is None else repr(value)
        lines.append(f'  {name}{" *" if name in RUNTIME_KEYS else ""} (default {shown})')
        text = _described(spec)
        if spec.choices:
            text += ' (one of: ' + ', '.join(spec.choices) + ')'
        lines += textwrap.wrap(text, 95, initial_indent='      ', subsequent_indent='      ')
    expert = ', '.join(
        f'{n}{" *" if n in RUNTIME_KEYS else ""}' for n, s in specs.items() if s.expert
    )
    lines += textwrap.wrap(
        f'expert parameters (settable the same way): {expert}', 95, subsequent_indent='  '
    )
    return '\n'.join(lines)
