"""report.html: one page that opens offline (inline CSS, the plots embedded as data URIs and
also written beside it as PNG files), built from the result dictionary.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

from ..core.checks.verdict import Verdict
from ..core.document import ErrorKey, EvaluationDoc, ResultDoc, TransformDoc
from .terminal import other_purpose, purpose_words, unsaid_warnings

VERDICT_COLOUR: dict[str, str] = {
    Verdict.GOOD: '#1a7f37',
    Verdict.DOUBTFUL: '#9a6700',
    Verdict.FAILED: '#cf222e',
}

STYLE = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ddd;padding-bottom:.2em}
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #ddd;padding:.25em .6em;
text-align:right;font-variant-numeric:tabular-nums}th{background:#f6f8fa}td.l,th.l{text-align:left}
.verdict{display:inline-block;color:#fff;padding:.2em .7em;border-radius:.3em;font-weight:bold}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #eee}figcaption{color:#555}
code{background:#f6f8fa;padding:0 .2em}pre{background:#f6f8fa;padding:.5em;overflow-x:auto}
"""


def _e(x: object) -> str:
    return html.escape(str(x))


def _f(x: float | None, fmt: str = '.4f', scale: float = 1.0) -> str:
    return '&ndash;' if x is None else format(float(x) * scale, fmt)


def _transform(title: str, t: TransformDoc) -> str:
    rows = ''.join(
        '<tr>' + ''.join(f'<td>{v:+.6f}</td>' for v in row) + '</tr>' for row in t['matrix']
    )
    tr = ' '.join(f'{v:+.5f}' for v in t['translation'])
    q = ' '.join(f'{v:+.6f}' for v in t['rotation'])
    return (
        f'<h3>{_e(title)}</h3><p>parent <code>{_e(t["parent"])}</code>, child '
        f'<code>{_e(t["child"])}</code><br>translation [m]: <code>{tr}</code><br>'
        f'rotation [qx qy qz qw]: <code>{q}</code></p><table>{rows}</table>'
    )


def _numbers(d: ResultDoc) -> str:
    """The numbers table of the report: the offset, drift, scale and T_HE with their 1-sigmas,
    the coverage and the readiness."""
    s = d['std']
    rows = [
        (
            'time offset dt (eye clock minus hand clock)',
            f'{d["time_offset"] * 1e3:+.4f} ms',
            _f(s['time_offset'] if s else None, '.4f', 1e3) + ' ms',
        ),
        ('time offset, exact', f'{d["time_offset_ns"]} ns', ''),
    ]
    drift, scale = d['clock_drift'], d['scale']
    if drift is not None:
        rows.append(
            (
                'clock drift',
                f'{drift * 1e6:+.3f} ppm',
                _f(s['clock_drift'] if s else None, '.3f', 1e6) + ' ppm',
            )
        )
    if scale is not None:
        rows.append(
            (
                'scale (s * eye positions are metric)',
                f'{scale:.5f}',
                _f(s['scale'] if s else None, '.5f'),
            )
        )
    if s:
        rows.append(
            (
                'T_HE translation',
                ' '.join(f'{v:+.4f}' for v in d['extrinsic']['translation']) + ' m',
                ' '.join(_f(v, '.2f', 1e3) for v in s['translation']) + ' mm',
            )
        )
        rows.append(
            (
                'T_HE rotation (tangent, eye frame)',
                '',
                ' '.join(_f(v, '.3f', 57.29577951308232) for v in s['rotation']) + ' deg',
            )
        )
    rows += _recording_rows(d)
    body = ''.join(
        f'<tr><td class="l">{_e(a)}</td><td>{b}</td><td>{c}</td></tr>' for a, b, c in rows
    )
    return (
        '<table><tr><th class="l">quantity</th><th>value</th><th>1-sigma</th></tr>'
        f'{body}</table><p class="l">convention: <code>{_e(d["convention"])}</code></p>'
    )


def _recording_rows(d: ResultDoc) -> list[tuple[str, str, str]]:
    """The numbers table's rows on the recording: the MoCap's coverage."""
    rows = []
    cov = d.get('coverage')
    if cov:
        rows.append(
            (
                "MoCap coverage of the eye's time",
                f'{cov["fraction"]:.0%} of {cov["eye_s"]:.1f} s',
                (
                    f'{cov["hand_gaps"]} gap(s), {cov["hand_gap_s"]:.1f} s '
                    f'(longest {cov["longest_hand_gap_s"]:.2f} s)'
                ),
            )
        )
    return rows


def _metrics(ev: EvaluationDoc | None) -> str:
    if not ev:
        return '<p>no evaluation</p>'
    cols: list[tuple[ErrorKey, str, float, str]] = [
        ('ape_translation', 'APE translation', 1e3, 'mm'),
        ('ape_rotation', 'APE rotation', 1.0, 'deg'),
        ('rpe_time_translation', f'RPE per {ev["rpe_delta_s"]:g} s translation', 1e3, 'mm'),
        ('rpe_time_rotation', f'RPE per {ev["rpe_delta_s"]:g} s rotation', 1.0, 'deg'),
        ('rpe_distance_translation', f'RPE per {ev["rpe_delta_m"]:g} m translation', 1e3, 'mm'),
        ('rpe_distance_rotation', f'RPE per {ev["rpe_delta_m"]:g} m rotation', 1.0, 'deg'),
    ]
    head = (
        '<tr><th class="l">metric</th><th class="l">alignment</th><th>RMSE</th>'
        '<th>its 1-sigma from the calibration</th><th>mean</th><th>median</th><th>max</th>'
        '<th>n</th></tr>'
    )
    rows = []
    for key, name, k, unit in cols:
        for pe in (ev['calibrated'], ev['uncalibrated']):
            if pe is None:
                continue
            st = pe[key]
            rows.append(
                f'<tr><td class="l">{_e(name)} [{unit}]</td><td class="l">'
                f'{_e(pe["what"])}</td><td>{_f(st["rmse"], ".3f", k)}</td>'
                + (
                    f'<td>{_f(st["calibration_sigma"].get("rmse"), ".3f", k)}</td>'
                    if 'calibration_sigma' in st
                    else '<td>-</td>'
                )
                + ''.join(
                    f'<td>{_f(v, ".3f", k)}</td>' for v in (st['mean'], st['median'], st['max'])
                )
                + f'<td>{st["n"]}</td></tr>'
            )
    why = ev.get('uncalibrated_why')
    note = f'<p>Without the calibration: {_e(why)}</p>' if why else ''
    bars = ev['calibration_sigmas']
    if 'draws' in bars and 'parameters' in bars and 'poses' in bars:
        note += (
            '<p>The 1-sigma from the calibration: how much each figure moves when dt and T_HE '
            f'({_e(", ".join(bars["parameters"]))}) move within their reported uncertainty '
            f'({bars["draws"]} draws over {bars["poses"]} eye poses; docs/evaluation.md). Two '
            'estimates whose figures differ by less than a few of these cannot be told apart '
            'by this alignment.</p>'
        )
    elif bars.get('why_not'):
        note += f'<p>No error bars from the calibration: {_e(bars["why_not"])}</p>'
    return f'<table>{head}{"".join(rows)}</table>{note}'


def _inputs(d: ResultDoc) -> str:
    rows = ''.join(
        f'<tr><td class="l">{name}</td><td class="l">{_e(i["source"])}</td>'
        f'<td>{i["poses"]}</td><td>{i["rate_hz"]:.1f}</td>'
        f'<td>{i["duration_s"]:.1f}</td></tr>'
        for name, i in (('hand', d['inputs']['hand']), ('eye', d['inputs']['eye']))
    )
    return (
        '<table><tr><th class="l">stream</th><th class="l">source</th><th>poses</th>'
        f'<th>rate [Hz]</th><th>duration [s]</th></tr>{rows}</table>'
    )


def render(d: ResultDoc, figures: list[tuple[Path, str]]) -> str:
    """The page for result dictionary ``d`` and ``figures`` (PNG path, caption)."""
    q = d['quality']
    colour = VERDICT_COLOUR.get(q['verdict'], '#555')
    reasons = ''.join(f'<li><b>{_e(r["code"])}</b>: {_e(r["message"])}</li>' for r in q['reasons'])
    notes = ''.join(f'<li>{_e(n)}</li>' for n in q['notes'])
    warnings = ''.join(f'<li>{_e(w)}</li>' for w in unsaid_warnings(d))
    figs = ''.join(
        f'<figure><img alt="{_e(p.stem)}" src="data:image/png;base64,'
        f'{base64.b64encode(p.read_bytes()).decode("ascii")}" data-file="{_e(p.name)}">'
        f'<figcaption>{_e(c)} (<a href="{_e(p.name)}">{_e(p.name)}</a>)</figcaption></figure>'
        for p, c in figures
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>handeye_ros calibration report</title>
<style>{STYLE}</style></head><body>
<h1>handeye_ros calibration report</h1>
<p><span class="verdict" style="background:{colour}">{_e(q['verdict'].upper())}</span>
&nbsp;{_e(d.get('summary', ''))}</p>
<p>Judged for {_e(purpose_words(q))}; {_e(other_purpose(q))}.</p>
{f'<ul>{reasons}</ul>' if reasons else ''}{f'<p>Notes:</p><ul>{notes}</ul>' if notes else ''}
<h2>Result</h2>{_numbers(d)}
{_transform('T_HE: eye frame in hand frame', d['extrinsic'])}
{_transform('T_EH: hand frame in eye frame', d['extrinsic_inverse'])}
{_transform('T_WG: hand (MoCap) world in eye (VIO) world', d['world_alignment'])}
<h2>Accuracy of the eye against the calibrated ground truth</h2>{_metrics(d.get('evaluation'))}
<h2>Inputs</h2>{_inputs(d)}
{f'<h2>Warnings</h2><ul>{warnings}</ul>' if warnings else ''}
<h2>Plots</h2>{figs}
</body></html>
"""
