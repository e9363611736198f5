"""``ros2 run handeye_ros publish_calibration FILE``: a saved calibration back into ROS.

FILE is a result written by the node's ``~/save`` or by ``offline_calibrate -o``. Where
tf2_msgs is importable (a ROS 2 install), it publishes the extrinsic T_HE latched on
/tf_static, as tf2's static_transform_publisher does, together with the calibrator's own
latched topics (see :mod:`handeye_ros.formats.messages`), and runs until Ctrl-C. Where tf2_msgs
is not importable (the PyPI wheels), or with ``--bag``, it writes the same messages into a new
bag instead, with /tf_static recorded as latched, so that a replay latches them.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # imported where used, after quiet_start
    from ..formats import messages

from ..app.commands import prog
from .lifecycle import (
    ignore_signals,
    quiet_start,
    spin_until_stopped,
    stop_requested,
    stoppable_executor,
)


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=prog('publish_calibration'),
        description='A saved calibration back into ROS. Where tf2_msgs is importable (a ROS 2 '
        "install): T_HE latched on /tf_static and the calibrator's latched topics, "
        'until Ctrl-C. Where it is not (the PyPI wheels), or with --bag: the same '
        'messages in a new bag, recorded as latched.',
    )
    p.add_argument(
        'file', metavar='FILE', help='the result (YAML or JSON) of ~/save or offline_calibrate -o'
    )
    p.add_argument(
        '--bag',
        metavar='PATH',
        help='write a bag at PATH instead of publishing (default where tf2_msgs '
        'cannot be imported: FILE without its suffix, plus _calibration)',
    )
    p.add_argument(
        '--storage',
        choices=('mcap', 'sqlite3', 'ros1'),
        default='mcap',
        help='storage of the bag (default: mcap)',
    )
    p.add_argument(
        '--namespace',
        default='/calibrator',
        metavar='NS',
        help='where the calibrator topics go, as the node publishes them (default: /calibrator)',
    )
    return p


def main(args: list[str] | None = None) -> int:
    """Returns the exit code: 0, 1 for a file that is no result or a bag that cannot be
    written, 2 for a bad command line."""
    quiet_start()
    a = parser().parse_args(args)
    from ..core.errors import HandeyeError
    from ..formats.messages import Published
    from ..formats.result_file import read_result

    try:
        result = read_result(a.file)
        published = Published.from_document(result)
        if a.bag is None and importlib.util.find_spec('tf2_msgs') is None:
            a.bag = str(Path(a.file).with_suffix('')) + '_calibration'
            print(
                f'publish_calibration: tf2_msgs cannot be imported in this Python '
                f'({sys.executable}), so nothing can go on /tf_static here: writing the bag '
                f'{a.bag} instead (ros2 bag play it where ROS 2 is installed)',
                file=sys.stderr,
            )
        if a.bag is not None:
            from ..formats.bag import write_result_bag

            stamp = int(
                result.get('inputs', {}).get('eye', {}).get('last_stamp_ns') or time.time_ns()
            )
            write_result_bag(a.bag, published, stamp, a.storage)
            print(f'wrote {a.bag}', file=sys.stderr)
            return 0
    except HandeyeError as err:
        print(f'publish_calibration: error: {err}', file=sys.stderr)
        return 1
    if stop_requested():
        return 0
    return _publish(published, a.namespace.rstrip('/'))


def _publish(published: messages.Published, namespace: str) -> int:
    """Publish a :class:`~handeye_ros.formats.messages.Published` latched until a signal.

    The signals stay ours (:mod:`.lifecycle`), as in the calibrator: a noted signal ends the
    loop within ``lifecycle.STOP_POLL_S``. (With rclpy's handler, which shuts the context down from its own
    thread, this once in some 20 CI runs had not exited 10 s after Ctrl-C; why, we did not
    find.)"""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions

    from ..formats import messages
    from .outputs import LATCHED
    from .types import RclpyTypes

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = executor = None
    try:
        node = rclpy.create_node('calibration_publisher')
        types = RclpyTypes()
        out = messages.outputs(types, published, node.get_clock().now().nanoseconds)
        tf = types['tf2_msgs/msg/TFMessage']
        node.create_publisher(tf, '/tf_static', LATCHED).publish(
            tf(transforms=[out[messages.EXTRINSIC]])
        )
        for name, msg in out.items():
            topic = f'{namespace}/{name}'
            node.create_publisher(types[messages.OUTPUT_TYPES[name]], topic, LATCHED).publish(msg)
        node.get_logger().info(
            f'publishing {published.parent} -> {published.child} on /tf_static and the '
            f'calibration on {namespace}/*, latched; Ctrl-C to stop'
        )
        executor = stoppable_executor(node)
        spin_until_stopped(executor)
    except ExternalShutdownException:  # a context shut down from elsewhere
        pass
    finally:
        ignore_signals()  # a second Ctrl-C must not break the clean-up
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
