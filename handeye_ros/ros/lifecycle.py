"""A quiet stop for our ROS executables, whenever the signal comes.

Importing rclpy and scipy takes about a second. Without care, a Ctrl-C in that second prints
a KeyboardInterrupt traceback, and a SIGTERM kills the process with a code that is not 0.
:func:`quiet_start` installs handlers that end the start with exit code 0 (SystemExit).
Once rclpy is initialised, :func:`rclpy_took_over` turns those handlers into no-ops:
rclpy's own handlers shut the context down, so spin returns and the clean-up runs; rclpy
then calls the previous Python handler, which is ours and now does nothing.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from typing import Any

_state = {'rclpy': False, 'hold': False, 'pending': False}


def _on_signal(signum: int, frame: object) -> None:
    if _state['hold']:
        _state['pending'] = True
    elif not _state['rclpy']:
        raise SystemExit(0)


def hold() -> None:
    """Until :func:`release`: a signal is noted, not acted on (while starting child processes
    that must not be left behind half-made)."""
    _state['hold'], _state['pending'] = True, False


def release() -> bool:
    """End :func:`hold`; True when a signal came meanwhile (the caller then stops)."""
    _state['hold'] = False
    return _state['pending']


def quiet_start() -> None:
    """Make SIGINT and SIGTERM end the process quietly (exit code 0) until rclpy is up."""
    _state['rclpy'] = False
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _on_signal)


def rclpy_took_over() -> None:
    """Call right after rclpy.init: from now on rclpy's handlers stop the process."""
    _state['rclpy'] = True


def ignore_signals() -> None:
    """During the clean-up: a second Ctrl-C (or a signal forwarded twice) must not break it."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)


def spin(node: Any, close: Callable[[], None] | None = None) -> None:
    """Spin ``node`` until a signal or an external shutdown, then clean up: ``close`` (the
    node's own resources), the executor, the node, rclpy."""
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        ignore_signals()
        if close is not None:
            close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
