"""The calibrator's worker process: what it does when it starts. No rclpy here.

The node starts the worker with SIGINT blocked (see ``CalibratorNode._new_pool``), so that a
Ctrl-C, which reaches the whole process group, cannot interrupt the worker's imports with a
KeyboardInterrupt traceback. Stopping the worker is the node's job.
"""

from __future__ import annotations

import importlib
import signal

#: The module whose function the worker runs; imported at start, not on the first call.
MODULE = 'handeye_ros.evaluation.outputs'


def start() -> None:
    """Process pool initializer: ignore SIGINT for good, unblock it, import the core."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    importlib.import_module(MODULE)


def stop_tracker() -> None:
    """Stop and reap multiprocessing's resource tracker, a child of the node once it has
    had a worker: left to itself it ends only when the node has exited, unreaped."""
    import gc
    from multiprocessing import resource_tracker
    gc.collect()  # the pool's semaphores unregister as they are collected; the tracker first
    resource_tracker._resource_tracker._stop()  # no public call; the standard tests use it
