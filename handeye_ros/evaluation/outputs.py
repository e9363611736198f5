"""What the front ends write after a calibration: the evaluation in the result dictionary, the
evo exports and the report (one call for the offline tool, the node and the evaluation runner).
"""

from __future__ import annotations

import logging
import time
from dataclasses import replace
from pathlib import Path

from ..core.checks.verdict import Purpose, assess_evaluation
from ..core.document import ErrorKey, FilesDoc, ResultDoc
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
) -> CalibrationResult:
    """Add ``evaluation`` (APE/RPE with and without the calibration) to the result dictionary
    ``out`` and judge its figures (:func:`judge_figures`: the result returned, ``out``'s
    quality and summary with it); write the exports and the report where asked (their paths
    go to ``out['files']``). Raises InputError when a directory cannot be written."""
    evaluated = evaluation_of(result, delta_s, delta_m)
    if evaluated is None:
        return result
    ev, cal, base = evaluated
    result = judge_figures(result, ev)
    out['quality'] = result.quality.to_dict()
    if 'summary' in out:
        out['summary'] = result.summary()
    out['evaluation'] = ev.to_dict()
    files: FilesDoc = {}
    if export_dir:
        from .export import write_exports

        files['export'] = [str(p) for p in write_exports(export_dir, result, cal)]
    if report_dir:
        files['report'] = str(write_report(report_dir, result, out, cal, base))
    if files:
        out['files'] = files
    return result


#: The figures purpose evaluation judges: (key, label, the unit said, the factor to it).
JUDGED: tuple[tuple[ErrorKey, str, str, float], ...] = (
    ('ape_translation', 'APE translation rmse', 'mm', 1e3),
    ('ape_rotation', 'APE rotation rmse', 'deg', 1.0),
    ('rpe_time_translation', 'RPE translation rmse per {s:g} s', 'mm', 1e3),
    ('rpe_time_rotation', 'RPE rotation rmse per {s:g} s', 'deg', 1.0),
    ('rpe_distance_translation', 'RPE translation rmse per {m:g} m', 'mm', 1e3),
    ('rpe_distance_rotation', 'RPE rotation rmse per {m:g} m', 'deg', 1.0),
)


def judge_figures(result: CalibrationResult, ev: Evaluation) -> CalibrationResult:
    """The result with its verdict's rule on the evaluation's own figures
    (:func:`~handeye_ros.core.checks.verdict.assess_evaluation`): each calibrated figure's rmse
    against the 1-sigma the calibration gives it."""
    figures = []
    for key, label, unit, k in JUDGED:
        stats = getattr(ev.calibrated, key)
        sigma = None if ev.sigmas is None else ev.sigmas.sigmas[key]['rmse']
        figures.append(
            (
                label.format(s=ev.delta_s, m=ev.delta_m),
                stats.rmse * k,
                None if sigma is None else sigma * k,
                unit,
                '' if ev.sigmas is None else ev.sigmas.through.get(key, ''),
            )
        )
    why = '' if ev.sigmas is not None else ev.sigmas_why
    batch = result.batch
    dominant = {} if batch is None or batch.uncertainty is None else batch.uncertainty.dominant()
    one_axis = batch is not None and batch.held_axis is not None
    reasons, notes, ratio = assess_evaluation(figures, why, dominant, one_axis)
    # no error bars because the batch stage did not run is said once (the core said it)
    said = {r.code for r in result.quality.found if Purpose.EVALUATION in r.purposes}
    reasons = [r for r in reasons if r.code not in said]
    return replace(result, quality=result.quality.with_evaluation(reasons, notes, ratio))


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
