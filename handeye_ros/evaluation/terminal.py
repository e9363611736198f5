"""The terminal report of a result dictionary (the HTML report is :mod:`.html`)."""

from __future__ import annotations

from pathlib import Path

from ..core.document import ErrorStatsDoc, QualityDoc, ResultDoc, StatusDoc, TransformDoc


def format_report(d: ResultDoc) -> str:
    """A terminal report of a result dictionary (see :mod:`handeye_ros.core.result`)."""
    ta, lin, m = d['time_alignment'], d['linear'], d['metrics']
    lines = _heading_lines(d)
    peak = ta['peak_correlation']
    lines += [
        '',
        (
            f'time offset dt = {d["time_offset"] * 1e3:+.3f} ms  (eye clock minus hand clock; the '
            'hand pose at hand time t - dt belongs to the eye pose at eye time t)'
        ),
        f'  method {ta["method"]}'
        + (
            f', peak correlation {peak:.3f}, second peak {ta["second_peak_ratio"]:.2f} of it'
            if peak is not None
            else ''
        ),
        '',
        _transform('T_HE: eye frame in hand frame', d['extrinsic']),
        _transform('T_EH: hand frame in eye frame', d['extrinsic_inverse']),
        _transform('T_WG: hand (MoCap) world in eye (VIO) world', d['world_alignment']),
        '',
        (
            f'linear stage: {lin["inliers"]}/{lin["motions"]} motions inliers '
            f'({lin["relative_poses"]} keyframes), sigma7/sigma6 {lin["sigma_ratio"]:.3g}, '
            f'rotation axes spread {lin["axis_spread_deg"]:.0f} deg'
        ),
        *_batch_lines(d),
        (
            f'metrics over {m["poses"]} poses: APE rmse {m["ape_rmse"] * 1e3:.1f} mm '
            f'(max {m["ape_max"] * 1e3:.1f}), ARE rmse {m["are_rmse"]:.3f} deg '
            f'(max {m["are_max"]:.3f})'
        ),
        *_evaluation_lines(d),
        *_screening_lines(d),
    ]
    files = d.get('files') or {}
    export = files.get('export')
    if export:
        lines.append(
            f'exports: {Path(export[0]).parent}/ (evo_ape tum groundtruth.tum estimate.tum, no -a)'
        )
    if files.get('report'):
        lines.append(f'report: {files["report"]}')
    lines += [f'WARNING: {w}' for w in unsaid_warnings(d)]
    return '\n'.join(lines)


def unsaid_warnings(d: ResultDoc) -> list[str]:
    """The warnings the verdict does not already say: one that is also a note of it (the
    eye's breaks, clocks on different epochs) is said once, with the verdict."""
    said = {*d['quality']['notes'], *(r['message'] for r in d['quality']['reasons'])}
    return [w for w in d['warnings'] if w not in said]


def purpose_words(q: QualityDoc) -> str:
    """What the verdict was judged for, in words."""
    if q['purpose'] == 'extrinsic':
        return 'the extrinsic: its precision_* targets'
    judged = q['for_evaluation']['figures_judged']
    return 'an evaluation: ' + (
        "the calibration's share of each APE/RPE figure"
        if judged
        else "the figures were not evaluated, so the extrinsic's rules stand in"
    )


def other_purpose(q: QualityDoc) -> str:
    """The verdict of the purpose not judged, in one line."""
    other = 'extrinsic' if q['purpose'] == 'evaluation' else 'evaluation'
    o = q['for_extrinsic'] if other == 'extrinsic' else q['for_evaluation']
    codes = f' ({", ".join(o["codes"])})' if o['codes'] else ''
    return f'for purpose {other}: {o["verdict"]}{codes}'


def _heading_lines(d: ResultDoc) -> list[str]:
    """The verdict with its reasons and notes, the inputs and the MoCap's coverage."""
    q = d['quality']
    lines = [
        'handeye_ros calibration',
        f'  convention: {d["convention"]}',
        '',
        f'VERDICT: {q["verdict"].upper()} (judged for {purpose_words(q)})',
    ]
    lines += [f'  - {r["code"]}: {r["message"]}' for r in q['reasons']]
    lines.append(f'  {other_purpose(q)}')
    lines += [f'  note: {n}' for n in q['notes']]
    for name, info in (('hand', d['inputs']['hand']), ('eye', d['inputs']['eye'])):
        lines.append(
            f'  {name:4s}: {info["source"]} ({info["poses"]} poses, '
            f'{info["rate_hz"]:.1f} Hz, {info["duration_s"]:.1f} s)'
        )
    cov = d.get('coverage')
    if cov:
        lines.append(
            f"  MoCap coverage: {cov['fraction']:.0%} of the eye's {cov['eye_s']:.1f} s, "
            f'{cov["hand_gaps"]} gap(s) inside it ({cov["hand_gap_s"]:.1f} s, the longest '
            f'{cov["longest_hand_gap_s"]:.2f} s)'
        )
    return lines


def _transform(title: str, t: TransformDoc) -> str:
    tr = ' '.join(f'{v:+.5f}' for v in t['translation'])
    q = ' '.join(f'{v:+.6f}' for v in t['rotation'])
    rows = '\n'.join('    [' + ' '.join(f'{v:+.6f}' for v in row) + ']' for row in t['matrix'])
    return f'{title}\n  translation [m]: {tr}\n  rotation [qx qy qz qw]: {q}\n{rows}'


def _batch_lines(d: ResultDoc) -> list[str]:
    b, s = d['batch'], d['std']
    if not b['used'] or s is None:
        return ['batch stage: ' + ('off' if not b['enabled'] else 'not used (see warnings)')]
    return [
        (
            f'batch stage: cost {b["cost_before"]:.6g} -> {b["cost_after"]:.6g} in '
            f'{b["iterations"]} iterations ({b["termination"]}); dt moved '
            f'{b["time_offset_change"] * 1e3:+.3f} ms from stage 1'
        ),
        f'  1-sigma: time offset {s["time_offset"] * 1e3:.3f} ms, translation '
        + ' '.join(f'{v * 1e3:.2f}' for v in s['translation'])
        + ' mm, rotation '
        + ' '.join(f'{v * 57.29577951308232:.3f}' for v in s['rotation'])
        + ' deg',
    ]


def _screening_lines(d: ResultDoc) -> list[str]:
    sc = d.get('screening') or {}
    out = []
    for name, rep in sc.items():
        removed = {k: v for k, v in rep['removed'].items() if v}
        if removed or rep['breaks_ns']:
            out.append(
                f'screening {name}: removed '
                + (
                    ', '.join(f'{v} {k.replace("_", " ")}' for k, v in removed.items())
                    or 'nothing'
                )
                + (f'; {len(rep["breaks_ns"])} break(s)' if rep['breaks_ns'] else '')
                + f' of {rep["poses_in"]} poses'
            )
    return out


def _evaluation_lines(d: ResultDoc) -> list[str]:
    ev = d.get('evaluation')
    if not ev:
        return []
    out = []
    for pe in (ev['calibrated'], ev['uncalibrated']):
        if pe is None:
            continue
        out.append(
            f'  {pe["what"]}: APE {_mm(pe["ape_translation"])} mm / '
            f'{_deg(pe["ape_rotation"])} deg, RPE per {ev["rpe_delta_s"]:g} s '
            f'{_mm(pe["rpe_time_translation"])} mm / {_deg(pe["rpe_time_rotation"])} deg, '
            f'per {ev["rpe_delta_m"]:g} m {_mm(pe["rpe_distance_translation"])} mm / '
            f'{_deg(pe["rpe_distance_rotation"])} deg (RMSE)'
        )
    if ev.get('uncalibrated_why'):
        out.append(f'  without the calibration: {ev["uncalibrated_why"]}')
    bars = ev['calibration_sigmas']
    if 'draws' in bars and 'parameters' in bars:
        out.append(
            "  (+- x: the 1-sigma of that figure from the calibration's own uncertainty, "
            f'{bars["draws"]} draws of {", ".join(bars["parameters"])} in opposite pairs)'
        )
    elif bars.get('why_not'):
        out.append(f'  no error bars from the calibration: {bars["why_not"]}')
    return ['evaluation of the eye against the MoCap:', *out] if out else []


def _mm(st: ErrorStatsDoc) -> str:
    if st['rmse'] is None:
        return 'n/a'
    bar = (st.get('calibration_sigma') or {}).get('rmse')
    return f'{st["rmse"] * 1e3:.1f}' + ('' if bar is None else f' (+-{bar * 1e3:.2g})')


def _deg(st: ErrorStatsDoc) -> str:
    if st['rmse'] is None:
        return 'n/a'
    bar = (st.get('calibration_sigma') or {}).get('rmse')
    return f'{st["rmse"]:.2f}' + ('' if bar is None else f' (+-{bar:.2g})')


#: The bar of the turns' axes is full when they spread this far (deg: two axes or more turned
#: about alike); display only.
BAR_FULL_DEG = 90.0


def status_line(r: StatusDoc, width: int = 8) -> str:
    """One line in the spirit of the camera calibrator's bars: READY, how far the device turned
    and how far apart the axes it turned about are (what the data observe of T_HE: one axis
    leaves part of it out, whichever device axes that one fills), the latest calibration's
    verdict and 1-sigmas, and the first thing to do."""
    n = round(width * min(1.0, r['axis_spread_deg'] / BAR_FULL_DEG))
    total, spread = sum(r['rotation_deg'].values()), r['axis_spread_deg']
    line = (
        f'{"READY" if r["ready"] else "not ready"} | turned {total:.0f} deg, axes apart '
        f'[{"#" * n}{"." * (width - n)}] {spread:.0f} deg | '
    )
    if r['verdict'] is None:
        line += 'no calibration yet'
    else:
        s = r['sigma']
        figures = ' '.join(
            f'{"?" if s[k] is None else format(s[k], ".2g")} {unit}'
            for k, unit in (
                ('time_offset_ms', 'ms'),
                ('translation_mm', 'mm'),
                ('rotation_deg', 'deg'),
            )
        )
        line += (
            f'{r["verdict"]} for {r["purpose"]} ({r["calibrated_span_s"]:.0f} s, '
            f'{r["age_s"]:.0f} s ago), 1-sigma {figures}'
        )
    return line + (f' | {r["missing"][0]}' if r['missing'] else '')
