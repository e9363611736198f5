"""sim_publisher's command line: what to simulate, how to publish it, and the defects to put in
(dropouts, clock jumps, unset stamps, NaN poses); absurd values are refused as argparse refuses a
typo (exit 2).
"""

from __future__ import annotations

import argparse
import math

from ..app.commands import prog


def parser() -> argparse.ArgumentParser:
    """The command line."""
    from handeye_ros.core.simulate import MOTIONS

    ap = argparse.ArgumentParser(
        prog=prog('sim_publisher'),
        description=__doc__.split('\n\n')[0],
        epilog="Stamps are the recording's (they start at 1.7e9 s, in November 2023), not the "
        "wall clock's. TFMessage hands the hand as /tf:world.marker (world -> rig on the hand "
        'topic, rig -> marker on /tf_static) and the eye as /tf:odom.imu; RigidBodies sends '
        "the bodies 'wand' and 'rig' (the hand: TOPIC:rig).",
    )
    # seed 1: its 60 s at level 3 give a result settled for an evaluation (the calibration's
    # largest share of a figure 3.1 %), where seed 3's sat at the 5 % line
    ap.add_argument(
        '--seed', type=int, default=1, help='random seed of the recording (default: 1)'
    )
    ap.add_argument(
        '--level',
        type=float,
        default=3.0,
        help="noise level 0-10 of the paper's protocol (default: 3)",
    )
    # the paper's protocol is 60 s: about what settles an evaluation's figures at level 3
    ap.add_argument('--duration', type=float, default=60.0, help='length [s] (default: 60)')
    ap.add_argument(
        '--motion',
        choices=MOTIONS,
        default='random',
        help='how the rig moves (default: random, about every axis); planar and one_axis '
        'never let the calibration see every direction, which the status names',
    )
    ap.add_argument(
        '--hand-rate', type=float, default=100.0, help='MoCap pose rate [Hz] (default: 100)'
    )
    ap.add_argument(
        '--mocap-noise',
        type=float,
        nargs=2,
        default=(0.0, 0.0),
        metavar=('MM', 'DEG'),
        help='white noise of the MoCap poses, position [mm] and rotation [deg] (default: '
        '0 0; a marker rig in a good MoCap room: about 0.1 0.006)',
    )
    ap.add_argument(
        '--eye-rate', type=float, default=20.0, help='VIO pose rate [Hz] (default: 20)'
    )
    ap.add_argument('--hand-topic', default='/mocap/pose', help='default: /mocap/pose')
    ap.add_argument('--eye-topic', default='/vio/odom', help='default: /vio/odom')
    ap.add_argument(
        '--hand-type',
        default='PoseStamped',
        help='PoseStamped (default), PoseWithCovarianceStamped, TransformStamped, '
        'Odometry, TFMessage or RigidBodies (see below)',
    )
    ap.add_argument(
        '--eye-type',
        default='Odometry',
        help='Odometry (default), one of the other one-pose types, or TFMessage',
    )
    ap.add_argument(
        '--rate',
        type=float,
        default=1000.0,
        help='messages per second, both topics together (default: 1000)',
    )
    ap.add_argument(
        '--replay',
        nargs=2,
        default=None,
        metavar=('HAND', 'EYE'),
        help='publish these two trajectory files (TUM or EuRoC, as offline_calibrate reads '
        'them) instead of a simulation, at the pace of their own stamps (--speed); the '
        'simulation options are then not used',
    )
    ap.add_argument(
        '--speed',
        type=float,
        default=None,
        help="pace by the recording's stamps, this many times real time (default: --rate for "
        'a simulation, 1 for --replay)',
    )
    ap.add_argument(
        '--clock-jump',
        type=float,
        default=0.0,
        metavar='SECONDS',
        help="the device's stamps jump by SECONDS halfway through, while its messages keep "
        'coming, as a clock that resynchronises (default: 0; on the wire only, not in --bag)',
    )
    ap.add_argument(
        '--mocap-dropout',
        type=float,
        nargs=2,
        default=None,
        metavar=('START', 'SECONDS'),
        help='the MoCap loses the marker SECONDS long from START s into the recording: its '
        'messages keep coming with a NaN position, as drivers that keep publishing do '
        '(default: none; on the wire only, not in --bag)',
    )
    ap.add_argument(
        '--nan-every',
        type=int,
        default=0,
        help='every k-th eye message has a NaN position (default: 0, none)',
    )
    ap.add_argument(
        '--zero-stamps',
        choices=('hand', 'eye', 'both'),
        default=None,
        help='leave header.stamp at 0 on that stream, as some drivers do '
        '(default: stamp every message)',
    )
    ap.add_argument(
        '--reliable',
        action='store_true',
        help='reliable publishers, which lose nothing: they keep the whole recording and wait '
        'until every message is acknowledged (default: best-effort hand, reliable eye)',
    )
    ap.add_argument(
        '--bag',
        action='append',
        default=[],
        metavar='PATH[:STORAGE]',
        help='also write the same messages to a bag (mcap, sqlite3 or ros1); repeatable',
    )
    ap.add_argument(
        '--wait-subscribers',
        type=float,
        default=10.0,
        metavar='SECONDS',
        help='how long to wait for a subscriber on both topics (default: 10)',
    )
    return ap


#: What a positive option counts, as its error says it.
_UNITS = {'--speed': ''}


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line, its absurd values refused as argparse refuses a typo (exit 2)."""
    ap = parser()
    args = ap.parse_args(argv)
    # the simulation's own values (duration, rates, level, noise) the simulator refuses
    positive = {'--rate': args.rate}
    if args.speed is not None:
        positive['--speed'] = args.speed
    for flag, v in positive.items():
        if not (math.isfinite(v) and v > 0.0):
            ap.error(f'{flag} must be a positive number{_UNITS.get(flag, " of Hz")}, not {v}')
    if args.mocap_dropout is not None and not all(
        math.isfinite(v) and v >= 0.0 for v in args.mocap_dropout
    ):
        ap.error(f'--mocap-dropout takes two times >= 0 (s), not {args.mocap_dropout}')
    if not math.isfinite(args.clock_jump):
        ap.error(f'--clock-jump takes seconds, not {args.clock_jump}')
    if args.nan_every < 0 or not (
        math.isfinite(args.wait_subscribers) and args.wait_subscribers >= 0.0
    ):
        ap.error('--nan-every and --wait-subscribers take amounts >= 0')
    return args
