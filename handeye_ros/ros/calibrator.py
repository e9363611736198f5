"""``ros2 run handeye_ros calibrator``: start the node (:mod:`.node`), spin it, stop it.

The shape is the Jazzy examples' main (init, make the node, spin, and a try / except / finally
that shuts down whatever happens), with three things they do not need:
- the worker process is started before ``rclpy.init`` (see :mod:`.worker`) and stopped in the
  ``finally``, so that no process outlives the node;
- ``--help`` and a stray argument are answered before anything starts;
- a signal while rclpy and scipy import is noted, not raised (:mod:`.lifecycle`), and the start
  looks at it where stopping is safe: Ctrl-C or SIGTERM at any moment exit 0 and quietly.
"""

from __future__ import annotations

import sys

from .lifecycle import ignore_signals, quiet_start, stop_requested


def main(args: list[str] | None = None) -> int:
    """Run the node; returns the exit code (0; 1 for refused options; 2 for a bad command
    line)."""
    argv = sys.argv[1:] if args is None else list(args)
    ours = argv[: argv.index('--ros-args')] if '--ros-args' in argv else argv
    if '-h' in ours or '--help' in ours:
        from ..node_config import usage

        print(usage())
        return 0
    if ours:
        print(
            f'calibrator: error: unknown argument {ours[0]!r}; parameters go after '
            '--ros-args (-p NAME:=VALUE, --params-file FILE); see calibrator --help',
            file=sys.stderr,
        )
        return 2
    quiet_start()
    import rclpy
    from rclpy.executors import ExternalShutdownException

    from ..core.errors import ConfigError
    from . import worker
    from .node import CalibratorNode

    if stop_requested():  # a signal while the imports ran
        return 0
    pool = worker.new_pool()  # before rclpy.init: see worker's docstring
    rclpy.init(args=args)
    node = None
    try:
        if not stop_requested():
            node = CalibratorNode(pool)
            pool = None  # the node owns it, and stops it in close()
        # checked again: an executor made on a context a signal has shut down fails half-made
        # and says so in a traceback from its __del__
        if node is not None and not stop_requested():
            rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except ConfigError as err:
        print(f'calibrator: error: {err}', file=sys.stderr)
        return 1
    except RuntimeError:
        # rclpy's handler shuts the context down from its own thread: what is made on it in
        # between (the node, the executor's wait set) fails with an RCLError, a RuntimeError
        # ("the given context is not valid"; ros2/ros2cli#854). That is the stop we were asked
        # for; else it is not.
        if rclpy.ok() and not stop_requested():
            raise
    finally:
        ignore_signals()  # a second Ctrl-C must not break the clean-up
        if node is not None:
            node.close()
            node.destroy_node()
        if pool is not None:
            worker.stop(pool)
            pool = None  # its semaphores must be gone before the resource tracker stops
        worker.stop_tracker()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
