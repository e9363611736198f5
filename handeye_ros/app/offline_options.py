"""The offline tool's command line: the files or bag, the outputs, and every algorithm option,
generated from the option specs (:mod:`handeye_ros.core.options`) so that the node's parameters,
the params file and the command line cannot disagree. ``--help`` shows the options a user
usually needs; ``--help-all`` every one.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Sequence
from typing import Any, Literal, Protocol

from ..core.options import Options
from ..formats.text import QUATERNION_ORDERS
from .commands import prog
from .request import PROGRESS_DELAY_S

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


class ArgumentAdder(Protocol):
    """An argparse parser or argument group: what options are added to (the keywords
    :func:`add_options` passes)."""

    def add_argument(
        self,
        *names: str,
        dest: str | None = ...,
        action: Literal['store_const'] = ...,
        const: object = ...,
        choices: Sequence[str] | None = ...,
        type: Callable[[str], object] = ...,
        metavar: str | None = ...,
        help: str | None = ...,
    ) -> argparse.Action: ...


def add_options(group: ArgumentAdder, cls: type[Options], show_all: bool = True) -> None:
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

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: object,
        option_string: str | None = None,
    ) -> None:
        build_parser(show_all=True).print_help()
        parser.exit()


def build_parser(show_all: bool = False) -> argparse.ArgumentParser:
    """The argument parser (kept apart from numpy and scipy so that --help is instant).

    ``show_all``: list the expert options too (--help-all); they parse either way.
    """
    from ..core.config import CalibrationConfig

    def expert(text: str) -> str:
        return text if show_all else argparse.SUPPRESS

    p = argparse.ArgumentParser(
        prog=prog('offline_calibrate'),
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
            choices=QUATERNION_ORDERS,
            default='auto',
            help=expert(
                f"order of the {stream} file's quaternion "
                "columns (default: the format's, x y z w for TUM, w x y z for EuRoC; yzwx: "
                "Eigen's Quaterniond(x, y, z, w) written through coeffs())"
            ),
        )
    io.add_argument('--bag', metavar='PATH', help='a ROS 2 (sqlite3, mcap) or ROS 1 bag')
    io.add_argument(
        '--rig',
        metavar='MANIFEST',
        help="many recordings of one rig (evaluate's manifest or folder layout): one T_HE "
        'shared by all, each its own time offset; recordings that disagree are named and left '
        "out (-o: the rig result; --export DIR: each recording at the rig's T_HE; --report "
        'DIR: the rig page)',
    )
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
