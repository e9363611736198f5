"""Offline calibration of a hand (MoCap) and an eye (VO/VIO) trajectory: two files or one bag.

Installed as ``offline_calibrate`` (``ros2 run handeye_ros offline_calibrate``) and runnable as
``python -m handeye_ros.offline``. A bag (ROS 2 sqlite3/mcap or ROS 1) is replayed through the
node's own conversion and buffering code (:class:`handeye_ros.stream.Recorder`), so it gives
the answer the node would have given live. The result goes to stdout (a report, or one JSON
document with ``--json``) and optionally to a YAML/JSON file and a bag; logs go to stderr.
Errors in the input give one line naming the file and the problem and exit code 1, never a
traceback. Every result carries a verdict (``quality.verdict``: good, doubtful or failed, with
its reasons); ``--strict`` makes any verdict but ``good`` exit with code 2. The command line
itself is built in :mod:`.offline_options`.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
from typing import TYPE_CHECKING

from .offline_options import STREAM_OPTION_KEYS, build_parser

if TYPE_CHECKING:  # imported where used: --help answers before the core is loaded
    from ..core.document import ResultDoc
    from ..core.result import CalibrationResult
    from .request import Request

LOG = logging.getLogger('handeye_ros.offline')  # not __name__: it is __main__ under -m


def request_of(args: argparse.Namespace) -> Request:
    """The application's request from the parsed command line: the ``--config`` file's options
    overridden by those given on the command line."""
    from ..core.config import CalibrationConfig
    from .request import Request, load_options

    options = load_options(args.config)
    keys = (*STREAM_OPTION_KEYS, *CalibrationConfig.specs())
    options.update({k: getattr(args, k) for k in keys if getattr(args, k) is not None})
    return Request(
        hand=args.hand,
        eye=args.eye,
        bag=args.bag,
        file_format=args.format,
        hand_stamp_unit=args.hand_stamp_unit,
        eye_stamp_unit=args.eye_stamp_unit,
        hand_quaternion_order=args.hand_quaternion_order,
        eye_quaternion_order=args.eye_quaternion_order,
        options=options,
        evaluation=args.evaluation,
        rpe_delta=args.rpe_delta,
        rpe_distance=args.rpe_distance,
        export=args.export,
        report=args.report,
        output_bag=args.output_bag,
        output_bag_storage=args.output_bag_storage,
        progress=args.progress,
        source=args.config or 'options',
    )


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format='%(name)s: %(message)s',
        stream=sys.stderr,
    )
    from ..core.errors import HandeyeError
    from ..formats.result_file import write_result

    if args.rig:
        return _rig_main(args)
    try:
        from ..formats.result_file import check_result_path
        from .request import run

        if args.output:
            check_result_path(args.output)
        document, result = run(request_of(args))
        if args.output:
            write_result(args.output, document)
    except HandeyeError as err:
        print(f'offline_calibrate: error: {err}', file=sys.stderr)
        return 1
    except ImportError as err:  # an optional dependency missing (rosbags, tqdm)
        print(
            f'offline_calibrate: error: {err.name or err} is not installed: {err}', file=sys.stderr
        )
        return 1
    except KeyboardInterrupt:
        return 130
    except MemoryError:
        print(
            'offline_calibrate: error: out of memory; the inputs are larger than this '
            'machine can hold (check the stamp units, or cut the recording)',
            file=sys.stderr,
        )
        return 1
    except Exception as err:
        if args.verbose:
            raise
        print(
            f'offline_calibrate: internal error: {type(err).__name__}: {err} (run with -v '
            'for the traceback and please report it)',
            file=sys.stderr,
        )
        return 3
    return _said(args, document, result)


def _said(args: argparse.Namespace, document: ResultDoc, result: CalibrationResult) -> int:
    """The result on stdout (the report, or JSON), its warnings on stderr; the exit code: 2 for
    a verdict other than good under --strict, else 0."""
    from ..core.checks.verdict import Verdict
    from ..evaluation.terminal import format_report

    for w in result.warnings:
        LOG.warning('%s', w)
    if args.json:
        json.dump(document, sys.stdout, indent=2)
        sys.stdout.write('\n')
    else:
        print(format_report(document))
    verdict = result.quality.verdict
    if args.strict and verdict != Verdict.GOOD:
        print(
            f'offline_calibrate: verdict {verdict} (--strict): ' + '; '.join(result.quality.codes),
            file=sys.stderr,
        )
        return 2
    return 0


def _rig_main(args: argparse.Namespace) -> int:
    """``--rig MANIFEST``: :func:`handeye_ros.app.rig.calibrate_rig` on the manifest's recordings,
    the command line's options under each recording's own."""
    from dataclasses import replace

    from ..core.errors import HandeyeError
    from ..evaluation.outputs import check_directory
    from ..formats.result_file import write_result
    from .rig import calibrate_rig
    from .rig_file import rig_summary
    from .runs import read_manifest

    try:
        if args.hand or args.eye or args.bag:
            raise HandeyeError(
                '--rig takes its recordings from the manifest: give no --hand, '
                '--eye or --bag with it'
            )
        runs = read_manifest(args.rig)
        if len(runs) < 2:
            raise HandeyeError(
                f'{args.rig}: a rig needs at least two recordings, it has '
                f'{len(runs)}; calibrate one with --hand/--eye or --bag'
            )
        given = request_of(args).options
        # the rig page (--report) is the rig's; per-recording reports are evaluate's
        runs = [replace(r, options={**given, **r.options}, report=False) for r in runs]
        output = check_directory(args.export, '--export') if args.export else None
        document, _ = calibrate_rig(runs, output)
        if args.output:
            write_result(args.output, document)
        if args.report:
            from ..evaluation.rig_report import write_rig_report

            write_rig_report(document, check_directory(args.report, '--report'))
    except HandeyeError as err:
        print(f'offline_calibrate: error: {err}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    if args.json:
        json.dump(document, sys.stdout, indent=2)
        sys.stdout.write('\n')
    else:
        print(rig_summary(document))
    verdict = document['rig']['quality']['verdict']
    if args.strict and verdict != 'good':
        print(f'offline_calibrate: rig verdict {verdict} (--strict)', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
