"""Offline calibration of a hand (MoCap) and an eye (VO/VIO) trajectory: two files or one bag.

Installed as ``offline_calibrate`` (``ros2 run handeye_ros offline_calibrate``) and runnable as
``python -m handeye_ros.offline``. A bag (ROS 2 sqlite3/mcap or ROS 1) is replayed through the
node's own conversion and buffering code (:class:`handeye_ros.stream.Recorder`), so it gives
the answer the node would have given live. The result goes to stdout (a report, or one JSON
document with ``--json``) and optionally to a YAML/JSON file and a bag; logs go to stderr.
Errors in the input give one line naming the file and the problem and exit code 1, never a
traceback. Every result carries a verdict (``quality.verdict``: good, doubtful or failed, with
its reasons); ``--strict`` makes any verdict but ``good`` exit with code 2.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any

LOG = logging.getLogger('handeye_ros.offline')  # not __name__: it is __main__ under -m

#: A run shorter than this (s) shows no progress bar.
PROGRESS_DELAY_S = 2.0
#: Stream options given on the command line (the algorithm ones come from their specs).
STREAM_OPTION_KEYS = (
    'hand_topic',
    'eye_topic',
    'hand_frame_id',
    'eye_frame_id',
    'hand_world_frame_id',
    'eye_world_frame_id',
    'use_arrival_time',
)


def add_options(group: Any, cls: Any, show_all: bool = True) -> None:
    """Command-line options generated from an option set's specs (names, help, types); the
    expert ones (:attr:`.core.options.Spec.expert`) parse alike but are listed only when
    ``show_all``."""
    defaults = cls().to_dict()
    for name, spec in cls.specs().items():
        flag = name.replace('_', '-')
        text = spec.description.replace('%', '%%')  # argparse formats help with %
        hidden = spec.expert and not show_all
        if spec.kind == 'bool':
            on = not defaults[name]
            names = [f'--{flag}' if on else f'--no-{flag}']
            if spec.alias:
                names.append(f'--{spec.alias}' if on else f'--no-{spec.alias}')
            group.add_argument(
                *names,
                dest=name,
                action='store_const',
                const=on,
                help=argparse.SUPPRESS if hidden else f'{"" if on else "do not: "}{text}',
            )
            continue
        default = 'estimated/automatic' if defaults[name] is None else defaults[name]
        rng = spec.range_text() if not spec.choices else ''
        group.add_argument(
            f'--{flag}',
            dest=name,
            choices=spec.choices or None,
            type={'float': float, 'int': int, 'str': str}[spec.kind],
            metavar=None if spec.choices else name.split('_')[-1].upper(),
            help=argparse.SUPPRESS
            if hidden
            else f'{text} (default {default}{", " + rng if rng else ""})',
        )


class _HelpAll(argparse.Action):
    """--help-all: the help with every option, the expert ones too."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: Any):
        super().__init__(option_strings, dest, nargs=0, **kwargs)

    def __call__(self, parser: Any, namespace: Any, values: Any, option_string: Any = None):
        build_parser(show_all=True).print_help()
        parser.exit()


def build_parser(show_all: bool = False) -> argparse.ArgumentParser:
    """The argument parser (kept apart from numpy and scipy so that --help is instant).

    ``show_all``: list the expert options too (--help-all); they parse either way.
    """
    from .core.config import CalibrationConfig

    def expert(text: str) -> str:
        return text if show_all else argparse.SUPPRESS

    p = argparse.ArgumentParser(
        prog='offline_calibrate',
        description='Estimate the time offset dt and the extrinsic T_HE between a MoCap '
        'trajectory (hand, T_GH) and a VO/VIO trajectory (eye, T_WE), with '
        'T_WE(t) = T_WG * T_GH(t - dt) * T_HE.',
        epilog=None
        if show_all
        else "--help-all lists the other options: the paper's ablation switches and the fine "
        'tuning of each stage, the input conventions the tool otherwise detects, frame names, '
        'and output details.',
    )
    p.add_argument('--help-all', action=_HelpAll, help='show every option and exit')
    io = p.add_argument_group('input: two trajectory files, or one bag')
    io.add_argument('--hand', metavar='FILE', help='MoCap trajectory (T_GH), TUM or EuRoC')
    io.add_argument('--eye', metavar='FILE', help='VO/VIO trajectory (T_WE), TUM or EuRoC')
    io.add_argument(
        '--format',
        choices=('auto', 'tum', 'euroc'),
        default='auto',
        help=expert('file format of both inputs (default: detected from the content)'),
    )
    for stream in ('hand', 'eye'):
        io.add_argument(
            f'--{stream}-stamp-unit',
            choices=('auto', 'Gs', 's', 'ms', 'us', 'ns'),
            default='auto',
            help=expert(
                f"unit of the {stream} file's stamps (default: "
                "the format's, seconds for TUM, nanoseconds for EuRoC; a unit the "
                'data contradict is detected and named; Gs: units of 1e9 s)'
            ),
        )
        io.add_argument(
            f'--{stream}-quaternion-order',
            choices=('auto', 'xyzw', 'wxyz'),
            default='auto',
            help=expert(
                f"order of the {stream} file's quaternion "
                "columns (default: the format's, x y z w for TUM, w x y z for EuRoC)"
            ),
        )
    io.add_argument('--bag', metavar='PATH', help='a ROS 2 (sqlite3, mcap) or ROS 1 bag')
    io.add_argument(
        '--hand-topic',
        metavar='SELECTOR',
        help='hand pose topic in the bag (default: /mocap/pose if present, else '
        'the one pose topic named like a MoCap); /tf:PARENT.CHILD selects the '
        'pose of CHILD in PARENT from tf2_msgs/TFMessage (static transforms '
        'of /tf_static chained; /tf:P.C:/other_static names the static topic), '
        'TOPIC:NAME the rigid body NAME of mocap4r2_msgs/RigidBodies',
    )
    io.add_argument(
        '--eye-topic',
        metavar='SELECTOR',
        help='eye pose topic in the bag (default: /vio/odom if present, else the one '
        'pose topic named like a VIO); the same selectors as --hand-topic',
    )
    io.add_argument(
        '--hand-frame-id',
        metavar='FRAME',
        help=expert("parent frame of the extrinsic (default: from the bag's messages)"),
    )
    io.add_argument(
        '--eye-frame-id',
        metavar='FRAME',
        help=expert("child frame of the extrinsic (default: from the bag's messages)"),
    )
    io.add_argument(
        '--hand-world-frame-id',
        metavar='FRAME',
        help=expert("the MoCap world frame (default: from the bag's messages)"),
    )
    io.add_argument(
        '--eye-world-frame-id',
        metavar='FRAME',
        help=expert("the VIO world frame (default: from the bag's messages)"),
    )
    io.add_argument(
        '--use-arrival-time',
        choices=('none', 'hand', 'eye', 'both'),
        help=expert(
            "with --bag: stamp that stream's poses with the bag's record time "
            'instead of header.stamp (for publishers that leave it unset or '
            'frozen; the transport delay then joins the time offset)'
        ),
    )
    io.add_argument(
        '--progress',
        action=argparse.BooleanOptionalAction,
        default=None,
        help=expert(
            'progress bars while replaying a bag and calibrating, shown after '
            f'{PROGRESS_DELAY_S:g} s (default: when stderr is a '
            'terminal)'
        ),
    )
    out = p.add_argument_group('output')
    out.add_argument(
        '-o',
        '--output',
        metavar='FILE',
        help='write the result to FILE (.json for JSON, otherwise YAML)',
    )
    out.add_argument(
        '--json',
        action='store_true',
        help='print exactly one JSON document with the result on stdout',
    )
    out.add_argument(
        '--output-bag',
        metavar='PATH',
        help='write the result to a new bag, latched, on the topics the node '
        'publishes: /tf_static and /calibrator/extrinsic (T_HE), '
        '/calibrator/extrinsic_with_covariance, /calibrator/time_offset '
        '(std_msgs/Float64) and /calibrator/time_reference '
        '(sensor_msgs/TimeReference)',
    )
    out.add_argument(
        '--export',
        metavar='DIR',
        help='write evo-ready files into DIR: groundtruth.tum (the MoCap mapped '
        "into the eye's frame, world and clock), estimate.tum, T_HE.json and "
        'T_EH.json (evo transform JSON), export.json',
    )
    out.add_argument(
        '--report',
        metavar='DIR',
        help='write report.html (one page that opens offline) and its PNG plots into DIR',
    )
    out.add_argument(
        '--evaluation',
        action=argparse.BooleanOptionalAction,
        default=True,
        help=expert(
            'add APE/RPE with and without the calibration to the result (default; '
            'about 4 s for an hour of 200 Hz VIO); --export and --report imply it'
        ),
    )
    out.add_argument(
        '--rpe-delta',
        metavar='SECONDS',
        type=float,
        default=1.0,
        help=expert('time step of the RPE per time (default 1 s)'),
    )
    out.add_argument(
        '--rpe-distance',
        metavar='METRES',
        type=float,
        default=1.0,
        help=expert('path length of the RPE per distance (default 1 m)'),
    )
    out.add_argument(
        '--output-bag-storage',
        choices=('mcap', 'sqlite3', 'ros1'),
        default='mcap',
        help=expert('storage of --output-bag (default mcap)'),
    )
    out.add_argument(
        '--config',
        metavar='YAML',
        help="options file: a flat mapping or the node's params file "
        '(<node>: ros__parameters: ...); command-line options override it',
    )
    out.add_argument(
        '--strict',
        action='store_true',
        help='exit with code 2 unless the verdict is good (for scripts and CI)',
    )
    out.add_argument(
        '-v',
        '--verbose',
        action='store_true',
        help='log stage timings (and show the traceback of an internal error)',
    )
    alg = p.add_argument_group(
        "algorithm (defaults: the paper's; same names as the node's parameters)"
    )
    add_options(alg, CalibrationConfig, show_all)
    return p


def load_options(path: str | None) -> dict[str, Any]:
    """Options from a YAML file: a flat mapping or a ROS 2 params file for the node.

    Node-only parameters (services, QoS, ...) are dropped, so one file configures both.
    """
    if path is None:
        return {}
    import yaml

    from .core.errors import ConfigError
    from .params import NODE_ONLY_KEYS

    try:
        data = yaml.safe_load(Path(path).read_text(encoding='utf-8')) or {}
    except OSError as err:
        raise ConfigError(f'{path}: cannot read the options file ({err.strerror})') from None
    except UnicodeDecodeError:
        raise ConfigError(
            f'{path}: not a text file; --config wants a YAML file of options'
        ) from None
    except yaml.YAMLError as err:
        first = str(err).splitlines()[0] if str(err) else 'syntax error'
        raise ConfigError(f'{path}: not valid YAML ({first})') from None
    if not isinstance(data, dict):
        raise ConfigError(f'{path}: expected a mapping of option names to values')
    nodes = [
        v['ros__parameters']
        for v in data.values()
        if isinstance(v, dict) and isinstance(v.get('ros__parameters'), dict)
    ]
    if nodes:
        data = nodes[0]
    return {k: v for k, v in data.items() if k not in NODE_ONLY_KEYS}


def calibrate_args(
    args: argparse.Namespace, extra_options: dict[str, Any] | None = None
) -> tuple[dict[str, Any], Any]:
    """Read, calibrate, evaluate, export and report; the result dictionary (with its
    ``evaluation``) and the CalibrationResult. ``extra_options`` (a manifest's) override the
    ``--config`` file and are overridden by the command line. Raises HandeyeError on bad
    input."""
    from .core.config import CalibrationConfig
    from .core.errors import ConfigError
    from .core.options import split_options
    from .stream.config import StreamConfig

    files = args.hand or args.eye
    if (args.bag and files) or (not args.bag and not (args.hand and args.eye)):
        raise ConfigError('give either --hand FILE and --eye FILE, or --bag PATH')
    _check_outputs(args)
    options = load_options(args.config)
    options.update(extra_options or {})
    keys = (*STREAM_OPTION_KEYS, *CalibrationConfig.specs())
    options.update({k: getattr(args, k) for k in keys if getattr(args, k) is not None})
    calib, streams = split_options(
        options, (CalibrationConfig, StreamConfig), source=args.config or 'options'
    )
    frames = streams.frames()  # files name no frames: the options or the fallbacks
    if args.bag:
        from .replay import replay

        given = {s: f'{s}_topic' in options for s in ('hand', 'eye')}
        from .core.pipeline import STEPS

        rec = replay(args.bag, streams, given=given, progress=args.progress)
        snap = rec.snapshot()
        with _progress_bar(args.progress, len(STEPS)) as step:
            result = snap.result(calib, progress=step)
        frames = snap.frames
        out = snap.describe(result)
        out['inputs']['bag'] = str(args.bag)
    else:
        from .core.pipeline import STEPS, calibrate
        from .formats import read_trajectory

        with _progress_bar(args.progress, len(STEPS) + 2) as step:
            step(f'reading {Path(args.hand).name}')
            hand = read_trajectory(
                args.hand, args.format, args.hand_stamp_unit, args.hand_quaternion_order
            )
            step(f'reading {Path(args.eye).name}')
            eye = read_trajectory(
                args.eye, args.format, args.eye_stamp_unit, args.eye_quaternion_order
            )
            LOG.info(
                'hand %s: %d poses at %.1f Hz; eye %s: %d poses at %.1f Hz',
                hand.name,
                len(hand),
                hand.rate_hz,
                eye.name,
                len(eye),
                eye.rate_hz,
            )
            result = calibrate(hand, eye, calib, progress=step)
        out = result.to_dict(
            hand_frame=frames['hand'],
            eye_frame=frames['eye'],
            hand_world=frames['hand_world'],
            eye_world=frames['eye_world'],
        )
        out['summary'] = result.summary()
    from .evaluation.outputs import evaluate_and_write

    if args.evaluation or args.export or args.report:
        evaluate_and_write(
            result,
            out,
            export_dir=args.export,
            report_dir=args.report,
            delta_s=args.rpe_delta,
            delta_m=args.rpe_distance,
        )
    if args.output_bag:
        from .formats.bag import write_result_bag
        from .stream.messages import Published

        write_result_bag(
            args.output_bag,
            Published.from_result(result, frames),
            result.eye.last_stamp_ns,
            args.output_bag_storage,
        )
    return out, result


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse absurd RPE steps and unwritable output directories before the calibration."""
    from .core.errors import ConfigError
    from .evaluation.outputs import check_directory

    for name, value in (('--rpe-delta', args.rpe_delta), ('--rpe-distance', args.rpe_distance)):
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f'{name} must be a positive number, got {value:g}')
    for flag, path in (('--export', args.export), ('--report', args.report)):
        if path:
            check_directory(path, flag)


@contextmanager
def _progress_bar(show: bool | None, steps: int):
    """A step counter on stderr (tqdm) that appears only after PROGRESS_DELAY_S, so that short
    runs print nothing; ``show`` None: only when stderr is a terminal. Yields ``step(name)``."""
    from tqdm import tqdm

    bar = tqdm(
        total=steps,
        desc='calibrating',
        unit='step',
        file=sys.stderr,
        disable=None if show is None else not show,
        delay=PROGRESS_DELAY_S,
        bar_format='{desc}: {n}/{total} {bar} {elapsed} {postfix}',
    )
    started = [False]

    def step(name: str) -> None:
        if started[0]:
            bar.update(1)
        started[0] = True
        bar.set_postfix_str(name, refresh=True)

    try:
        yield step
        bar.update(1)
    finally:
        bar.close()


def main(argv: list[str] | None = None) -> int:
    """Entry point; returns the process exit code."""
    args = build_parser().parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format='%(name)s: %(message)s',
        stream=sys.stderr,
    )
    from .core.checks.verdict import Verdict
    from .core.errors import HandeyeError
    from .report import format_report, write_result

    try:
        document, result = calibrate_args(args)
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


if __name__ == '__main__':
    sys.exit(main())
