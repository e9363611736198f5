"""A quiet stop for our ROS executables, whenever the signal comes.

Importing rclpy and scipy and starting the worker take about a second. A Ctrl-C in that second
would print a KeyboardInterrupt traceback from wherever it struck (inside an extension
module's initialisation it even turns into an ImportError), and a SIGTERM would kill the
process with a code that is not 0. :func:`quiet_start` therefore replaces both handlers by one
that only notes the signal; the start checks :func:`stop_requested` at the points where
stopping is safe and then returns 0. The calibrator keeps this handler for its whole life
(``rclpy.init`` without rclpy's handlers) and its spin loop looks at :func:`stop_requested`
too, so that it can answer its callers before the context goes (:mod:`.calibrator`);
publish_calibration does the same. Both spin with :func:`stoppable_executor` and
:func:`spin_until_stopped`, which look every :data:`STOP_POLL_S`.
:func:`ignore_signals` keeps a second Ctrl-C out of the clean-up.

A signal in the interpreter's first ~0.1 s, before it runs any of this package's code (while it
imports site and the ROS wheels' .pth bootstrapper), is CPython's to handle, not ours.
"""

from __future__ import annotations

import signal
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # rclpy is imported where used: quiet_start runs before its import
    from rclpy.executors import Executor, SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.timer import Timer

_state = {'stop': False}

#: How often a spin loop looks for a noted signal (s): rclpy's wait does not return for a
#: Python signal handler, so a timer this often ends it. (A timeout on spin_once would do it
#: too, but rclpy makes a new timer for every wait then, hundreds a second at 1 kHz.)
STOP_POLL_S = 0.1


def _on_signal(signum: int, frame: object) -> None:
    _state['stop'] = True


def quiet_start() -> None:
    """Note SIGINT and SIGTERM instead of acting on them (until rclpy's handlers, if any,
    take over)."""
    _state['stop'] = False
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _on_signal)


#: Linux's prctl option that signals a process when its parent ends.
PR_SET_PDEATHSIG = 1


def stop_with_parent() -> None:
    """A SIGTERM when the parent process ends (Linux; elsewhere nothing). ``ros2 launch``
    ends at once on SIGTERM and leaves its processes running (launch says so: "using SIGTERM
    can result in orphaned processes"); with this, ours stop as on a SIGTERM of their own. A
    parent already gone before the call is a stop too."""
    import ctypes
    import os

    parent = os.getppid()
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):  # not Linux: no such call
        return
    if os.getppid() != parent:
        _state['stop'] = True


def stop_requested() -> bool:
    """Whether a SIGINT or SIGTERM came since :func:`quiet_start`."""
    return _state['stop']


def steady_timer(node: Node, period_s: float, callback: Callable[[], None]) -> Timer:
    """A timer of ``node`` on the steady clock: it fires every ``period_s`` of real time
    whatever the node's clock does. A node with ``use_sim_time`` runs its own timers on /clock,
    which stands still before ``ros2 bag play --clock`` starts, on pause and after the end."""
    from rclpy.clock import Clock, ClockType

    return node.create_timer(period_s, callback, clock=Clock(clock_type=ClockType.STEADY_TIME))


def stoppable_executor(node: Node) -> SingleThreadedExecutor:
    """A single-threaded executor spinning ``node``, with a steady timer that wakes it every
    :data:`STOP_POLL_S`, so that :func:`spin_until_stopped` sees a noted signal."""
    from rclpy.executors import SingleThreadedExecutor

    steady_timer(node, STOP_POLL_S, lambda: None)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    return executor


def spin_until_stopped(executor: Executor) -> None:
    """Spin until a SIGINT or SIGTERM is noted (or the context is shut down)."""
    import rclpy

    while rclpy.ok() and not stop_requested():
        executor.spin_once()


def ignore_signals() -> None:
    """During the clean-up: a second Ctrl-C (or a signal forwarded twice) must not break it."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
