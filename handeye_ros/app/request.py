"""The application: calibrate from sources to a result with its outputs, the one function
under every front end: the offline tool's ``main``, ``evaluate``'s runs and the node's worker.

A :class:`Request` says where the poses come from (two trajectory files, a bag replayed
through the node's own conversion and buffers, or a snapshot of the node's buffers), the
options (the algorithm's and the streams', merged from a config file, a manifest and the
command line by the caller) and what to write besides the result (evo exports, the report, a
bag of the node's outputs). :func:`run` reads, calibrates, evaluates and writes, and returns
the result's dictionary and the result. The node's worker calls it through
:func:`handeye_ros.ros.jobs.calibrate_buffers`.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # imported where used: the offline tool starts without numpy's import
    from ..core.config import CalibrationConfig
    from ..core.document import ResultDoc
    from ..core.result import CalibrationResult
    from ..stream.recorder import Snapshot

#: A run shorter than this (s) shows no progress bar.
PROGRESS_DELAY_S = 2.0


@dataclass(frozen=True)
class Request:
    """What to calibrate and what to write.

    hand, eye: trajectory files (TUM or EuRoC), or bag: a ROS 2 / ROS 1 bag; file_format,
    *_stamp_unit, *_quaternion_order: the files' readings ('auto': detected); options: the
    algorithm and stream options by name (unknown names are refused); evaluation: add APE/RPE
    with and without the calibration (rpe_delta [s], rpe_distance [m]); export, report: folders
    for evo-ready files and the HTML report; output_bag: a bag of the node's outputs, in
    output_bag_storage; progress: a progress bar on stderr (None: when it is a terminal);
    source: what the options came from, for messages.
    """

    hand: str | None = None
    eye: str | None = None
    bag: str | None = None
    file_format: str = 'auto'
    hand_stamp_unit: str = 'auto'
    eye_stamp_unit: str = 'auto'
    hand_quaternion_order: str = 'auto'
    eye_quaternion_order: str = 'auto'
    options: Mapping[str, object] = field(default_factory=dict)
    evaluation: bool = True
    rpe_delta: float = 1.0
    rpe_distance: float = 1.0
    export: str | None = None
    report: str | None = None
    output_bag: str | None = None
    output_bag_storage: str = 'mcap'
    progress: bool | None = None
    source: str = 'options'
    snapshot: Snapshot | None = None
    outputs_required: bool = True


def run(req: Request) -> tuple[ResultDoc, CalibrationResult]:
    """Read, calibrate, evaluate, export and report; the result dictionary (with its
    ``evaluation``) and the CalibrationResult. Raises HandeyeError on bad input."""
    from ..core.config import CalibrationConfig
    from ..core.errors import ConfigError
    from ..core.options import split_options
    from ..core.pipeline import STEPS
    from ..stream.config import StreamConfig

    files = req.hand or req.eye
    sources = sum((bool(req.bag), bool(files), req.snapshot is not None))
    if sources != 1 or (files and not (req.hand and req.eye)):
        raise ConfigError('give either --hand FILE and --eye FILE, or --bag PATH')
    readings = _file_readings(req)
    if req.bag and readings:
        raise ConfigError(
            f'{", ".join(readings)}: these read trajectory files, not a bag, whose messages '
            "hold their stamps in nanoseconds and their quaternions x y z w by ROS's "
            'definition (a publisher that writes another order is to be fixed): remove them'
        )
    _check_outputs(req)
    calib, streams = split_options(req.options, (CalibrationConfig, StreamConfig), req.source)
    frames = streams.frames()  # files name no frames: the options or the fallbacks
    if files:
        result = _calibrate_files(req, calib)
        out = result.to_dict(
            hand_frame=frames['hand'],
            eye_frame=frames['eye'],
            hand_world=frames['hand_world'],
            eye_world=frames['eye_world'],
        )
        out['summary'] = result.summary()
    else:
        snap = req.snapshot
        if snap is None:
            from .replay import replay

            assert req.bag is not None, 'one source: the bag'
            given = {s: f'{s}_topic' in req.options for s in ('hand', 'eye')}
            snap = replay(req.bag, streams, given=given, progress=req.progress).snapshot()
        with _progress_bar(req.progress, len(STEPS)) as step:
            result = snap.result(calib, progress=step)
        frames = snap.frames
        out = snap.describe(result)
        if req.bag:
            out['inputs']['bag'] = str(req.bag)
    result = write_outputs(req, result, out, frames)
    return out, result


def _file_readings(req: Request) -> list[str]:
    """The options of how the files are read that the request sets (not 'auto')."""
    given = {
        '--format': req.file_format,
        '--hand-stamp-unit': req.hand_stamp_unit,
        '--eye-stamp-unit': req.eye_stamp_unit,
        '--hand-quaternion-order': req.hand_quaternion_order,
        '--eye-quaternion-order': req.eye_quaternion_order,
    }
    return [f'{flag} {value}' for flag, value in given.items() if value != 'auto']


def _calibrate_files(req: Request, calib: CalibrationConfig) -> CalibrationResult:
    """Read the two trajectory files and calibrate them."""
    import logging

    from ..core.pipeline import STEPS, calibrate
    from ..formats import read_trajectory

    assert req.hand is not None and req.eye is not None, 'run() checked both are given'
    with _progress_bar(req.progress, len(STEPS) + 2) as step:
        step(f'reading {Path(req.hand).name}')
        hand = read_trajectory(
            req.hand, req.file_format, req.hand_stamp_unit, req.hand_quaternion_order
        )
        step(f'reading {Path(req.eye).name}')
        eye = read_trajectory(
            req.eye, req.file_format, req.eye_stamp_unit, req.eye_quaternion_order
        )
        logging.getLogger('handeye_ros.offline').info(
            'hand %s: %d poses at %.1f Hz; eye %s: %d poses at %.1f Hz',
            hand.name,
            len(hand),
            hand.rate_hz,
            eye.name,
            len(eye),
            eye.rate_hz,
        )
        return calibrate(hand, eye, calib, progress=step)


def write_outputs(
    req: Request, result: CalibrationResult, out: ResultDoc, frames: dict[str, str]
) -> CalibrationResult:
    """The evaluation (into ``out``), the exports, the report and the output bag; returns the
    result, with a warning when a failed evaluation or report is not to stop the run."""
    from dataclasses import replace

    from ..evaluation.outputs import evaluate_and_write

    try:
        # purpose evaluation's verdict reads the evaluation's own figures
        judged = result.config.purpose == 'evaluation'
        if req.evaluation or req.export or req.report or judged:
            result = evaluate_and_write(
                result,
                out,
                export_dir=req.export,
                report_dir=req.report,
                delta_s=req.rpe_delta,
                delta_m=req.rpe_distance,
            )
            if not req.evaluation:  # judged, and not written where it was not asked for
                out.pop('evaluation', None)
    except Exception as err:
        if req.outputs_required:
            raise
        note = f'no evaluation or report: {type(err).__name__}: {err}'
        out['warnings'].append(note)
        result = replace(result, warnings=(*result.warnings, note))
    if req.output_bag:
        from ..formats.bag import write_result_bag
        from ..formats.messages import Published

        write_result_bag(
            req.output_bag,
            Published.from_result(result, frames),
            result.eye.last_stamp_ns,
            req.output_bag_storage,
        )
    return result


def _check_outputs(req: Request) -> None:
    """Refuse absurd RPE steps, unwritable output directories and an output bag that cannot go
    where it is asked to, before the calibration."""
    from ..core.errors import ConfigError
    from ..evaluation.outputs import check_directory

    for name, value in (('--rpe-delta', req.rpe_delta), ('--rpe-distance', req.rpe_distance)):
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f'{name} must be a positive number, got {value:g}')
    for flag, path in (('--export', req.export), ('--report', req.report)):
        if path:
            check_directory(path, flag)
    if req.output_bag:
        from ..formats.bag import check_bag_path

        check_bag_path(Path(req.output_bag), req.output_bag_storage)


def load_options(path: str | None) -> dict[str, object]:
    """Options from a YAML file: a flat mapping or a ROS 2 params file for the node.

    Node-only parameters (services, QoS, ...) are dropped, so one file configures both.
    """
    if path is None:
        return {}
    import yaml

    from ..core.errors import ConfigError
    from .params_file import NODE_ONLY_KEYS

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


@contextmanager
def _progress_bar(show: bool | None, steps: int) -> Iterator[Callable[[str], None]]:
    """A step counter on stderr (tqdm) that appears only after PROGRESS_DELAY_S, so that short
    runs print nothing; ``show`` None: only when stderr is a terminal. Yields ``step(name)``.
    With ``show`` False no bar is made at all: tqdm's lock is a multiprocessing semaphore, which
    a worker process that is stopped (the node's) would leave to its resource tracker."""
    if show is False:
        yield lambda name: None
        return
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
