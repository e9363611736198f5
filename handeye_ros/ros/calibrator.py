"""``ros2 run handeye_ros calibrator``: the entry point of the node (in :mod:`.node`).

It answers ``--help`` without starting anything, and names a stray argument. A signal that
comes while the node starts ends it quietly (see :mod:`.lifecycle`).
"""

from __future__ import annotations

import sys

from .lifecycle import quiet_start, stop_requested


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
    from .node import run

    if stop_requested():  # a signal while the imports ran
        return 0
    return run(args)


if __name__ == '__main__':
    sys.exit(main())
