"""What the front ends write after a calibration: the evaluation in the result dictionary, the
evo exports and the report (one call for the offline tool, the node and the evaluation runner).
"""

from __future__ import annotations

import logging
import time
from pathlib import Path

from ..core.document import FilesDoc, ResultDoc
from ..core.errors import InputError
from ..core.result import CalibrationResult
from .aligned import AlignedTrajectories, calibrated, uncalibrated
from .error_bars import calibration_sigmas
from .metrics import Evaluation, ape

LOG = logging.getLogger(__name__)

#: The report's PNG files, in page order, with the function that draws each.
FIGURES = ('time_alignment', 'clock', 'linear', 'excitation', 'residuals', 'trajectories')


def check_directory(path: str | Path, what: str) -> Path:
    """Create ``path`` and make sure files can be written there; raises InputError naming
    ``what`` (an option) otherwise."""
    out = Path(path)
    probe = out / '.handeye_ros_write_test'
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe.write_bytes(b'')
        probe.unlink()
    except OSError as err:
        raise InputError(f'{what} {out}: cannot write there ({err.strerror or err})') from None
    return out


def evaluate_and_write(
    result: CalibrationResult,
    out: ResultDoc,
    *,
    export_dir: str | Path | None = None,
    report_dir: str | Path | None = None,
    delta_s: float = 1.0,
    delta_m: float = 1.0,
) -> None:
    """Add ``evaluation`` (APE/RPE with and without the calibration) to the result dictionary
    ``out``; write the exports and the report where asked (their paths go to
    ``out['files']``). Raises InputError when a directory cannot be written."""
    evaluated = evaluation_of(result, delta_s, delta_m)
    if evaluated is None:
        return
    ev, cal, base = evaluated
    out['evaluation'] = ev.to_dict()
    files: FilesDoc = {}
    if export_dir:
        from .export import write_exports

        files['export'] = [str(p) for p in write_exports(export_dir, result, cal)]
    if report_dir:
        files['report'] = str(write_report(report_dir, result, out, cal, base))
    if files:
        out['files'] = files


def evaluation_of(
    result: CalibrationResult, delta_s: float = 1.0, delta_m: float = 1.0
) -> tuple[Evaluation, AlignedTrajectories, AlignedTrajectories | None] | None:
    """(APE/RPE evaluation with and without the calibration, the calibrated figures with their
    error bars from the calibration, the calibrated and the uncalibrated aligned trajectories)
    of a result, or None when it has no poses
    (:meth:`CalibrationResult.detached`)."""
    if result.used is None:
        return None
    cal = calibrated(result)
    base, why = uncalibrated(result)
    sigmas = calibration_sigmas(result, delta_s, delta_m)
    return (
        Evaluation.of(cal, base, delta_s=delta_s, delta_m=delta_m, why=why, sigmas=sigmas),
        cal,
        base,
    )


def write_report(
    directory: str | Path,
    result: CalibrationResult,
    out: ResultDoc,
    cal: AlignedTrajectories | None = None,
    base: AlignedTrajectories | None = None,
) -> Path:
    """Write the report's PNGs and report.html into ``directory``; returns the page's path."""
    from . import plots
    from .html import render

    t0 = time.perf_counter()
    d = check_directory(directory, 'report directory')
    if cal is None:
        cal = calibrated(result)
        base, _ = uncalibrated(result)
    figures = []
    try:
        for name in FIGURES:
            path = d / f'{name}.png'
            if name == 'trajectories':
                caption = plots.trajectories(
                    cal, path, ape(cal)[0], base, None if base is None else ape(base)[0]
                )
            else:
                caption = getattr(plots, name)(result, path)
            figures.append((path, caption))
        page = d / 'report.html'
        page.write_text(render(out, figures), encoding='utf-8')
    except OSError as err:
        raise InputError(f'report directory {d}: cannot write ({err.strerror or err})') from None
    LOG.info('report written in %.2f s: %s', time.perf_counter() - t0, page)
    return page
