"""The calibrator's outputs: a new result goes out on every latched topic at once, with one
stamp (on the executor's thread, as everything the node publishes); ``~/save`` writes the last
one to files (:func:`save`).

The result topics of :mod:`handeye_ros.formats.messages` (``~/extrinsic``,
``~/extrinsic_with_covariance``, ``~/time_offset``, ``~/time_reference``), /tf_static where
tf2_msgs is importable, and two nav_msgs/Path (:data:`PATHS`). Latched: a subscriber that comes
later gets the last result. A failure cannot withdraw them; /diagnostics names them stale
(:mod:`.diagnostics`).
"""

from __future__ import annotations

from pathlib import Path

from rclpy.event_handler import PublisherEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..app.params_file import NodeConfig
from ..core.errors import ConfigError, HandeyeError
from ..formats import messages
from ..formats.result_file import read_result, write_result
from ..stream.convert import TF_TYPE
from . import files
from .jobs import Calibrated
from .types import RclpyTypes

#: Latched result topics: late subscribers get the last result.
LATCHED = QoSProfile(
    depth=1,
    history=HistoryPolicy.KEEP_LAST,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
#: The latched nav_msgs/Path topics of each result (relative to the node), by path: the eye's
#: trajectory and the calibrated ground truth (the hand in the eye's world and clock), both in
#: the eye's world frame, for RViz or Foxglove to overlay.
PATHS = {'eye': 'eye_path', 'ground_truth': 'ground_truth_path'}


def quiet_publisher(node: Node, cls: type, topic: str, qos: QoSProfile | int) -> Publisher:
    """``node.create_publisher`` without QoS event handlers: rclpy's executor puts each one in
    the wait set it rebuilds for every pose message (bench/results/node.md), and they would say
    nothing: a reliable transient-local offer matches every request, and a subscriber that asks
    for more than ~/status or /diagnostics offer is warned by its own rclpy."""
    quiet = PublisherEventCallbacks(use_default_callbacks=False)
    return node.create_publisher(cls, topic, qos, event_callbacks=quiet)


class Outputs:
    """The publishers of a result (made with the node)."""

    def __init__(self, node: Node, types: RclpyTypes) -> None:
        self._node, self._types = node, types
        self._topics = {
            name: quiet_publisher(node, types[t], f'~/{name}', LATCHED)
            for name, t in messages.OUTPUT_TYPES.items()
        }
        self._paths = {
            name: quiet_publisher(node, types['nav_msgs/msg/Path'], f'~/{name}', LATCHED)
            for name in PATHS.values()
        }
        self._static_tf = self._static_broadcaster()

    def publish(self, session: Calibrated, stamp: int) -> None:
        """Every output of a new result, stamped ``stamp`` (int64 ns, the node's clock)."""
        published = messages.Published.from_result(session.result, session.frames)
        out = messages.outputs(self._types, published, stamp)
        for name, pub in self._topics.items():
            if name in out:
                pub.publish(out[name])
        if messages.TIME_REFERENCE not in out:
            self._node.get_logger().warning(
                'the time offset is not published as a TimeReference: its instant on one of '
                'the clocks is no ROS time (before 1970); ~/time_offset has it'
            )
        if self._static_tf is not None:
            self._static_tf.publish(self._types[TF_TYPE](transforms=[out[messages.EXTRINSIC]]))
        world = session.frames['eye_world']
        for key, name in PATHS.items():
            if key in session.paths:
                self._paths[name].publish(messages.path(self._types, world, *session.paths[key]))

    def _static_broadcaster(self) -> Publisher | None:
        """A latched /tf_static publisher, as tf2's static broadcaster keeps one, where
        tf2_msgs is importable (a ROS 2 install; the PyPI wheels have neither tf2_msgs nor
        tf2_ros); None otherwise, said once."""
        try:
            cls = self._types[TF_TYPE]
        except ConfigError:
            self._node.get_logger().info(
                'tf2_msgs is not importable here: the extrinsic is published '
                'on ~/extrinsic, not on /tf_static (publish_calibration FILE '
                'writes it into a bag)'
            )
            return None
        return quiet_publisher(self._node, cls, '/tf_static', LATCHED)


def save(session: Calibrated, cfg: NodeConfig) -> tuple[bool, str]:
    """``~/save``: the result file, and with ``report_dir`` the report the worker drew for it
    (copied from where it was staged), each inside ``output_dir`` (:mod:`.files`). (success,
    what was written, or why not, in one line)."""
    try:
        # every path checked before anything is written: a refusal changes nothing
        path = files.inside(cfg.output_dir, cfg.output_file, 'output_file')
        folder, staged = None, session.staged_dir
        if cfg.report_dir and staged:
            folder = files.inside(cfg.output_dir, cfg.report_dir, 'report_dir')
            files.check_report_folder(folder)
        files.replace_file(path, lambda tmp: write_result(tmp, session.document), _is_result)
        wrote = [str(path)]
        if folder is not None and staged:
            files.copy_report(staged, folder)
            wrote.append(str(folder / 'report.html'))
        elif cfg.report_dir:
            wrote.append('no report (report_dir was set after this calibration: calibrate again)')
    except HandeyeError as err:
        return False, str(err)
    except OSError as err:
        return False, f'{err.filename or cfg.output_dir}: cannot write ({err.strerror or err})'
    return True, 'wrote ' + ', '.join(wrote)


def _is_result(path: Path) -> bool:
    """Whether ``path`` holds a result of this package (``~/save``'s, offline_calibrate's)."""
    try:
        read_result(path)
    except HandeyeError:
        return False
    return True
