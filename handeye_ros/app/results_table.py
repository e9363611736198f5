"""The table of many runs (:mod:`.evaluate`): one row per run, written as results.csv (every
column of :data:`COLUMNS`) and results.md (the columns a reader scans first).
"""

from __future__ import annotations

import csv
from pathlib import Path

from ..core.document import ErrorKey, Json, PoseErrorsDoc, ResultDoc, Row

#: Columns of results.csv, in order.
COLUMNS = (
    'name',
    'algorithm',
    'sequence',
    'trial',
    'status',
    'reason',
    'verdict',
    'verdict_reasons',
    'time_offset_ms',
    'time_offset_std_ms',
    'clock_drift_ppm',
    'scale',
    'tx_m',
    'ty_m',
    'tz_m',
    'qx',
    'qy',
    'qz',
    'qw',
    'translation_std_mm',
    'rotation_std_deg',
    'ape_mm',
    'ape_deg',
    'rpe_1s_mm',
    'rpe_1s_deg',
    'rpe_1m_mm',
    'rpe_1m_deg',
    'ape_mm_cal_sigma',
    'ape_deg_cal_sigma',
    'rpe_1s_mm_cal_sigma',
    'rpe_1s_deg_cal_sigma',
    'rpe_1m_mm_cal_sigma',
    'rpe_1m_deg_cal_sigma',
    'ape_uncalibrated_mm',
    'ape_uncalibrated_deg',
    'rpe_1s_uncalibrated_mm',
    'pairs',
    'seconds',
    'cached',
    'pid',
    'rss_mb',
    'rig',
)


def _norm(v: list[float]) -> float:
    """Euclidean norm of a list of numbers."""
    return float(sum(x * x for x in v) ** 0.5)


def row_of(d: ResultDoc) -> Row:
    """A run's row (the result columns of :data:`COLUMNS`) from its result document."""
    s = d['std']
    ev = d.get('evaluation')
    cal, base = (ev['calibrated'], ev['uncalibrated']) if ev else (None, None)

    def stat(pe: PoseErrorsDoc | None, key: ErrorKey, k: float) -> float | None:
        v = pe[key]['rmse'] if pe else None
        return None if v is None else v * k

    def bar(key: ErrorKey, k: float) -> float | None:
        v = cal[key].get('calibration_sigma', {}).get('rmse') if cal else None
        return None if v is None else v * k

    t, q, drift = d['extrinsic']['translation'], d['extrinsic']['rotation'], d['clock_drift']
    return {
        'verdict': d['quality']['verdict'],
        'verdict_reasons': ' '.join(r['code'] for r in d['quality']['reasons']),
        'time_offset_ms': d['time_offset'] * 1e3,
        'time_offset_std_ms': None if not s else s['time_offset'] * 1e3,
        'clock_drift_ppm': None if drift is None else drift * 1e6,
        'scale': d['scale'],
        'tx_m': t[0],
        'ty_m': t[1],
        'tz_m': t[2],
        'qx': q[0],
        'qy': q[1],
        'qz': q[2],
        'qw': q[3],
        'translation_std_mm': None if not s else _norm(s['translation']) * 1e3,
        'rotation_std_deg': None if not s else _norm(s['rotation']) * 57.29577951308232,
        'ape_mm': stat(cal, 'ape_translation', 1e3),
        'ape_deg': stat(cal, 'ape_rotation', 1.0),
        'rpe_1s_mm': stat(cal, 'rpe_time_translation', 1e3),
        'rpe_1s_deg': stat(cal, 'rpe_time_rotation', 1.0),
        'rpe_1m_mm': stat(cal, 'rpe_distance_translation', 1e3),
        'rpe_1m_deg': stat(cal, 'rpe_distance_rotation', 1.0),
        'ape_mm_cal_sigma': bar('ape_translation', 1e3),
        'ape_deg_cal_sigma': bar('ape_rotation', 1.0),
        'rpe_1s_mm_cal_sigma': bar('rpe_time_translation', 1e3),
        'rpe_1s_deg_cal_sigma': bar('rpe_time_rotation', 1.0),
        'rpe_1m_mm_cal_sigma': bar('rpe_distance_translation', 1e3),
        'rpe_1m_deg_cal_sigma': bar('rpe_distance_rotation', 1.0),
        'ape_uncalibrated_mm': stat(base, 'ape_translation', 1e3),
        'ape_uncalibrated_deg': stat(base, 'ape_rotation', 1.0),
        'rpe_1s_uncalibrated_mm': stat(base, 'rpe_time_translation', 1e3),
        'pairs': d['association']['pairs'],
    }


def write_tables(output: Path, rows: list[Row]) -> tuple[Path, Path]:
    """results.csv (one row per run, :data:`COLUMNS`) and results.md; returns both paths."""
    csv_path, md_path = output / 'results.csv', output / 'results.md'
    with csv_path.open('w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction='ignore')
        w.writeheader()
        for r in rows:
            w.writerow({k: _cell(r.get(k)) for k in COLUMNS})
    shown = (
        'name',
        'status',
        'verdict',
        'time_offset_ms',
        'tx_m',
        'ty_m',
        'tz_m',
        'ape_mm',
        'ape_mm_cal_sigma',
        'ape_deg',
        'rpe_1s_mm',
        'ape_uncalibrated_mm',
        'reason',
    ) + (('rig',) if any(r.get('rig') for r in rows) else ())
    lines = ['| ' + ' | '.join(shown) + ' |', '|' + '---|' * len(shown)]
    for r in rows:
        cells = [_md(r.get(k)) for k in shown]
        lines.append('| ' + ' | '.join(cells) + ' |')
    md_path.write_text('\n'.join(lines) + '\n')
    return csv_path, md_path


def _cell(v: Json) -> Json:
    if isinstance(v, float):
        return f'{v:.6g}'
    return '' if v is None else v


def _md(v: Json) -> str:
    if isinstance(v, float):
        return f'{v:.4g}'
    return ('' if v is None else str(v)).replace('|', '\\|').replace('\n', ' ')[:200]
