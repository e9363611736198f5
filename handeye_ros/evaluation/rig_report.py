"""rig.html: a rig's page (:mod:`handeye_ros.app.rig`), one file that opens offline.

Its figure shows every recording's own T_HE around the rig's, as differences from it (own [-]
rig: translation [mm] in the hand frame, rotation [deg] on the right), in three planes each,
with the 95 % ellipse of each covariance (2-D chi-square 5.99): a recording whose ellipse misses
the rig's point by far is one the consistency test names.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.arrays import Floats
from ..core.geometry import difference
from ..core.rig import EXTRINSIC
from ..core.rig_document import RigDoc, RigExtrinsicDoc, RigRecordingDoc
from .figures import canvas, save
from .html import STYLE, VERDICT_COLOUR, _e
from .terminal import other_purpose, purpose_words

#: The 2-D ellipse drawn: chi-square with 2 dof at 95 %.
ELLIPSE_CHI2 = 5.991
PLANES = ((0, 1), (0, 2), (1, 2))
AXES = 'xyz'


def _ellipse(cov2: Floats) -> Floats:
    """Points (2, 64) of the ELLIPSE_CHI2 contour of a 2x2 covariance, about 0."""
    lam, V = np.linalg.eigh(0.5 * (cov2 + cov2.T))
    a = np.linspace(0.0, 2 * np.pi, 64)
    return V @ (np.sqrt(np.clip(lam, 0.0, None) * ELLIPSE_CHI2)[:, None] * [np.cos(a), np.sin(a)])


def figure(doc: RigDoc, path: Path) -> str:
    """The recordings' own T_HE around the rig's (module docstring); returns the caption."""
    rig = doc['rig']
    fig, axes = canvas(2, 3, height=3.2, width=11.0)
    e, cov = rig['extrinsic'], rig['covariance']
    assert e is not None and cov is not None, 'drawn for a rig with a T_HE'
    q0, p0 = np.asarray(e['rotation']), np.asarray(e['translation'])
    C0 = np.asarray(cov['matrix'], dtype=float)
    scale: Floats = np.array([1e3] * 3 + [np.degrees(1.0)] * 3)
    outer = np.outer(scale, scale)
    colours = {'used': '#1f77b4', 'out': '#cf222e'}
    for rec in doc['recordings']:
        own = rec.get('own')
        if not own:
            continue
        d = difference(np.asarray(own['rotation']), np.asarray(own['translation']), q0, p0)
        d = d * scale
        C = np.asarray(own['covariance']['matrix'], dtype=float)[EXTRINSIC, EXTRINSIC] * outer
        colour = colours['used' if rec['used'] else 'out']
        for row, off in ((0, 0), (1, 3)):
            for col, (i, j) in enumerate(PLANES):
                ax = axes[row][col]
                idx = [off + i, off + j]
                ring = _ellipse(C[np.ix_(idx, idx)])
                ax.plot(d[idx[0]] + ring[0], d[idx[1]] + ring[1], color=colour, lw=0.8)
                ax.plot(*d[idx], 'o', color=colour, ms=3)
                ax.annotate(rec['name'], d[idx], fontsize=7, color=colour)
    for row, off, unit in ((0, 0, 'mm'), (1, 3, 'deg')):
        for col, (i, j) in enumerate(PLANES):
            ax = axes[row][col]
            idx = [off + i, off + j]
            ring = _ellipse((C0 * outer)[np.ix_(idx, idx)])
            ax.plot(ring[0], ring[1], color='k', lw=1.5)
            ax.plot(0, 0, 'k+', ms=10)
            what = 'translation' if row == 0 else 'rotation'
            ax.set_xlabel(f'{what} {AXES[i]} [{unit}]')
            ax.set_ylabel(f'{what} {AXES[j]} [{unit}]')
            ax.set_aspect('equal', adjustable='datalim')
    save(fig, path)
    return (
        "each recording's own T_HE minus the rig's (black cross and ellipse), with the 95 % "
        'ellipses of their covariances; blue: used, red: left out'
    )


def write_rig_report(doc: RigDoc, directory: Path) -> Path:
    """rig.html and rig.png in ``directory`` (created); returns the page's path."""
    import base64

    directory.mkdir(parents=True, exist_ok=True)
    rig = doc['rig']
    q = rig['quality']
    colour = VERDICT_COLOUR.get(q['verdict'], '#555')
    reasons = ''.join(f'<li><b>{_e(r["code"])}</b>: {_e(r["message"])}</li>' for r in q['reasons'])
    fig = ''
    if rig['extrinsic']:
        png = directory / 'rig.png'
        caption = figure(doc, png)
        data = base64.b64encode(png.read_bytes()).decode('ascii')
        fig = (
            f'<figure><img alt="rig" src="data:image/png;base64,{data}">'
            f'<figcaption>{_e(caption)}</figcaption></figure>'
        )
    page = directory / 'rig.html'
    page.write_text(
        f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>handeye_ros rig report</title>
<style>{STYLE}</style></head><body>
<h1>handeye_ros rig report</h1>
<p><span class="verdict" style="background:{colour}">{_e(q['verdict'].upper())}</span>
&nbsp;{len(rig['used'])} of {len(doc['recordings'])} recordings share the T_HE below</p>
<p>Judged for {_e(purpose_words(q))}; {_e(other_purpose(q))}.</p>
{f'<ul>{reasons}</ul>' if reasons else ''}
<h2>The rig's T_HE</h2>{_extrinsic(rig['extrinsic'])}
<h2>Recordings</h2>{_recordings(doc['recordings'])}
{fig}
</body></html>
"""
    )
    return page


def _extrinsic(e: RigExtrinsicDoc | None) -> str:
    if not e:
        return '<p>none: no recording gave a T_HE the others agree with</p>'
    t = ' '.join(f'{v:+.5f}' for v in e['translation'])
    r = ' '.join(f'{v:+.6f}' for v in e['rotation'])
    st = ' '.join(f'{v * 1e3:.2f}' for v in e['std']['translation'])
    sr = ' '.join(f'{np.degrees(v):.3f}' for v in e['std']['rotation'])
    return (
        f'<p>translation [m]: <code>{t}</code> (1-sigma [mm]: <code>{st}</code>)<br>'
        f'rotation [qx qy qz qw]: <code>{r}</code> (1-sigma [deg]: <code>{sr}</code>)</p>'
    )


def _recordings(recs: list[RigRecordingDoc]) -> str:
    head = (
        '<tr><th class="l">recording</th><th class="l">part</th><th>dt [ms]</th>'
        '<th>1-sigma [ms]</th><th>chi2</th><th>from the rig [mm]</th>'
        '<th>from the rig [deg]</th><th class="l">why</th></tr>'
    )
    rows = []
    for rec in recs:
        shared, test = rec.get('shared'), rec.get('test')
        dt = shared['values'].get('time_offset') if shared else None
        sd = shared['std'].get('time_offset') if shared else None
        part = 'used' if rec['used'] else ('follows' if rec.get('follows') else 'left out')
        cells = [
            _e(rec['name']),
            part,
            '&ndash;' if dt is None else f'{dt * 1e3:+.3f}',
            '&ndash;' if sd is None else f'{sd * 1e3:.3f}',
            '&ndash;' if not test else f'{test["chi2"]:.1f}',
            '&ndash;' if not test else f'{test["translation_mm"]:.1f}',
            '&ndash;' if not test else f'{test["rotation_deg"]:.3f}',
            _e(rec['reason']),
        ]
        rows.append(
            '<tr>'
            + ''.join(
                f'<td class="l">{c}</td>' if k in (0, 1, 7) else f'<td>{c}</td>'
                for k, c in enumerate(cells)
            )
            + '</tr>'
        )
    return f'<table>{head}{"".join(rows)}</table>'
