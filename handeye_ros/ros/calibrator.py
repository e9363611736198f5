"""``ros2 run handeye_ros calibrator``: start the node (:mod:`.node`), spin it, stop it.

The shape is the Jazzy examples' main (init, make the node, spin, and a try / except / finally
that shuts down whatever happens), with four things they do not need:
- the worker process is started before ``rclpy.init`` (see :mod:`.worker`) and stopped in the
  ``finally``, so that no process outlives the node;
- ``--help`` and a stray argument are answered before anything starts;
- the signals are ours, not rclpy's (``SignalHandlerOptions.NO``): a SIGINT or SIGTERM is only
  noted (:mod:`.lifecycle`), while importing, starting or spinning alike, and the spin loop
  looks at it at least every ``lifecycle.STOP_POLL_S``. rclpy's own handler would shut the context down
  at once, from its thread, and a ``~/calibrate`` caller waiting for a running calibration
  could then never be answered;
- the stop therefore happens in order, on a context that still works: the worker is stopped
  (a running calibration is abandoned), the pending ``~/calibrate`` calls are answered
  "aborted: shutting down" and the executor spins until the answers are sent (at most
  ``ANSWER_S``, then ``LINGER_S`` more), then the node is destroyed and rclpy shut down.
  Ctrl-C or SIGTERM at any moment exit 0 and quietly.
"""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # imported where used, after quiet_start
    from rclpy.executors import Executor

    from .node import CalibratorNode

from ..app.commands import prog
from .lifecycle import (
    ignore_signals,
    quiet_start,
    spin_until_stopped,
    stop_requested,
    stop_with_parent,
    stoppable_executor,
)

#: How long the stop spins to send the answers to pending ``~/calibrate`` calls (s).
ANSWER_S = 2.0
#: How long it spins on once it has sent any (s): under load a response can miss its reader
#: at the first attempt, and only a writer that still exists repeats it.
LINGER_S = 0.5


#: glibc's M_MMAP_THRESHOLD (mallopt's parameter -3) and the value it is fixed at: its default.
M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES = -3, 128 * 1024


def return_freed_memory() -> None:
    """Fix glibc's mmap threshold at its default, so that an array of more than 128 kB is
    mapped and given back to the system when freed. Left dynamic, glibc raises the threshold
    to the size of each mapped block freed (up to 32 MB), and the next blocks of that size then
    come from its heap, which it seldom gives back: each snapshot of the buffers (half a
    million poses: 30 MB, and its copies) left the node some 60 MB larger after a few minutes of
    1 kHz (bench/node_ingest.py). A no-op without glibc."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library('c') or 'libc.so.6')
        libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
    except (OSError, AttributeError):  # not glibc: nothing to fix
        pass


def main(args: list[str] | None = None) -> int:
    """Run the node; returns the exit code (0; 1 for refused options; 2 for a bad command
    line)."""
    argv = sys.argv[1:] if args is None else list(args)
    name = prog('calibrator')
    if (code := _command_line(argv, name)) is not None:
        return code
    quiet_start()
    stop_with_parent()
    if missing := _rclpy_missing():
        print(f'{name}: error: {missing}', file=sys.stderr)
        return 1
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions

    from ..core.errors import ConfigError
    from . import worker
    from .node import CalibratorNode

    if stop_requested():  # a signal while the imports ran
        return 0
    return_freed_memory()
    made = worker.new_pool()  # before rclpy.init: see worker's docstring
    pool: worker.Pool | None = made  # to stop here, until the node owns it
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = executor = None
    try:
        if not stop_requested():
            node = CalibratorNode(made)
            pool = None  # the node owns it, and stops it in close()
            executor = stoppable_executor(node)
            spin_until_stopped(executor)
    except ExternalShutdownException:  # a context shut down from elsewhere
        pass
    except ConfigError as err:
        print(f'{name}: error: {err}', file=sys.stderr)
        return 1
    finally:
        ignore_signals()  # a second Ctrl-C must not break the clean-up
        if node is not None:
            node.close()  # the worker stopped: every pending calibration has its answer
            if executor is not None:
                send_answers(node, executor, ANSWER_S, LINGER_S)
                executor.shutdown()
            node.destroy_node()
        if pool is not None:
            worker.stop(pool)
        rclpy.try_shutdown()
    return 0


def _command_line(argv: list[str], name: str) -> int | None:
    """The exit code when the arguments before ``--ros-args`` answer alone (--help: 0; a stray
    argument: 2), else None: the node starts."""
    ours = argv[: argv.index('--ros-args')] if '--ros-args' in argv else argv
    if '-h' in ours or '--help' in ours:
        from ..app.params_file import usage

        print(usage(name))
        return 0
    if ours:
        print(
            f'{name}: error: unknown argument {ours[0]!r}; parameters go after '
            f'--ros-args (-p NAME:=VALUE, --params-file FILE); see {name} --help',
            file=sys.stderr,
        )
        return 2
    return None


def _rclpy_missing() -> str | None:
    """Why rclpy cannot be imported (a pip install without ROS), in one line, or None."""
    try:
        import rclpy  # noqa: F401
    except ImportError as err:
        return (
            f'rclpy cannot be imported in this Python ({sys.executable}: {err}); source '
            '/opt/ros/jazzy/setup.bash first (offline_calibrate needs no ROS)'
        )
    return None


def send_answers(
    node: CalibratorNode, executor: Executor, timeout_s: float, linger_s: float
) -> None:
    """At the stop, after the node's ``close``: spin until every ``~/calibrate`` call waiting
    for a calibration has been answered (close gave them ABORTED), at most timeout_s,
    then on for linger_s when any was: a reliable DDS writer repeats a response its reader
    missed only while it exists, and the node is destroyed right after this."""
    from .calls import ABORTED  # imported by main already

    waiting = node.open_calls
    if not waiting:
        return
    deadline = time.monotonic() + timeout_s
    while node.open_calls and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    node.get_logger().info(
        f'stopping: {waiting - node.open_calls} ~/calibrate caller(s) answered '
        f"'{ABORTED}'" + (f', {node.open_calls} not' if node.open_calls else '')
    )
    deadline = time.monotonic() + linger_s
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


if __name__ == '__main__':
    sys.exit(main())
