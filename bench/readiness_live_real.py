"""The node's status and auto mode live on real recordings (issue 45, item 4): each recording of
bench/readiness_real.py written to two EuRoC files and replayed through DDS at its own stamps
(``sim_publisher --replay``, real time unless ``--speed``) to a calibrator with
``auto_calibrate`` and the defaults, while a probe in this process takes every ``~/status`` and,
after each new result, the file ``~/save`` writes.

Counted per recording:
- READY checked: every status that says READY, at most one per CHECK_S seconds of the
  recording (``--check-every``, whose table is ``readiness_live_real_dense``), is checked by an
  offline calibration of what that status judged (the recording's first ``span_s`` seconds, the
  span of the buffers it read): READY while that calibration is not ``good`` must not happen;
- each published result: its verdict, and the status's predicted 1-sigmas just before it over
  the result's reported ones (dt, translation, rotation; target 0.5-2): their medians, and the
  results whose three lie within 0.5-2, all and those whose prediction carried the last
  result's blocks' term (not the first result's, nor one after a result of too few eye poses
  for the blocks);
- what auto mode said last (converged must not be said of a doubtful result: that is
  ``stalled``).

Usage: python bench/readiness_live_real.py [--speed 1] [--only NAME] [--check-every S]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
import readiness_real
from common import emit, table
from node_ingest import start, stop
from readiness_live import LiveProbe, _reported, _sigmas

from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.formats import write_euroc

#: READY statuses are checked at most this often (recording seconds).
CHECK_S = 10.0
#: After the replay: how long results may still come (a calibration started at its end).
GRACE_S = 6.0


def replay(probe: LiveProbe, name: str, hand, eye, out: Path, speed: float) -> dict:
    """One recording through the node: the statuses, and each result with its saved file."""
    probe.clear()
    tag = name.replace(' ', '_')
    files = [out / f'{tag}_hand.csv', out / f'{tag}_eye.csv']
    write_euroc(files[0], hand)
    write_euroc(files[1], eye)
    saved = out / f'{tag}.yaml'
    node = start(
        'handeye_ros.ros.calibrator',
        *('--ros-args', '-p', 'auto_calibrate:=true', '-p', f'output_dir:={out}'),
        *('-p', f'output_file:={saved.name}'),
        log=out / f'{tag}.log',
    )
    pub = start(
        'handeye_ros.ros.sim_publisher',
        *('--replay', *map(str, files), '--speed', str(speed)),
    )
    docs = probe.results_until(pub, saved, GRACE_S)
    out_text, err = pub.communicate()
    stop(node)
    with probe.lock:
        statuses = list(probe.statuses)
    return {'statuses': statuses, 'docs': docs, 'sent': out_text, 'log': err}


def _verdict_at(hand, eye, cut_ns: int) -> str:
    try:
        res = calibrate(hand.select(hand.t_ns <= cut_ns), eye.select(eye.t_ns <= cut_ns))
    except HandeyeError as e:
        return f'failed ({e})'[:40]
    return res.quality.verdict.value


def judged(run: dict, hand, eye, every_s: float = CHECK_S) -> dict:
    """READY statuses, at most one per ``every_s`` seconds of the recording, checked by a
    calibration of what the status judged (its buffers' span from the start of the recording);
    results' verdicts and predicted over reported sigmas."""
    t0 = max(int(hand.t_ns[0]), int(eye.t_ns[0]))
    ready, checked, last_s = 0, [], -np.inf
    for _, st in run['statuses']:
        if st['message'] != 'READY':
            continue
        ready += 1
        s = float(st['span_s'])
        if s - last_s < every_s:
            continue
        last_s = s
        checked.append((s, _verdict_at(hand, eye, t0 + int(s * 1e9))))
    results, ratios, carried, previous = [], [], [], None
    for when, doc in run['docs']:
        if not isinstance(doc, dict) or not doc.get('std'):
            results.append('no result')
            continue
        results.append(doc['quality']['verdict'])
        before = [st for w, st in run['statuses'] if w < when and 'sigma.translation_mm' in st]
        if before:
            ratios.append(_sigmas(before[-1]) / _reported(doc))
            # the prediction carries the last result's blocks' term (or none: the first, or
            # one of too few eye poses for the blocks)
            carried.append(
                previous is not None and previous['std'].get('block_factors') is not None
            )
        previous = doc
    auto = [st.get('auto_calibrate', '') for _, st in run['statuses']]
    return {
        'span': (min(hand.t_ns[-1], eye.t_ns[-1]) - t0) * 1e-9,
        'ready': ready,
        'checked': checked,
        'results': results,
        'ratios': np.array(ratios) if ratios else np.full((1, 3), np.nan),
        'carried': np.array(carried if ratios else [False]),
        'auto': next((a.split(':')[0] for a in reversed(auto) if a), '-'),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--speed', type=float, default=1.0, help='times real time (default 1)')
    p.add_argument('--only', default='', help='only the recordings whose name contains this')
    p.add_argument(
        '--check-every',
        type=float,
        default=CHECK_S,
        help=f'check a READY status at most once per this many recording seconds ({CHECK_S:g})',
    )
    a = p.parse_args()
    probe = LiveProbe()
    rows, totals = [], [0, 0, 0, 0]
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for name, hand, eye in readiness_real.recordings():
                if a.only not in name:
                    continue
                run = replay(probe, name, hand, eye, Path(tmp), a.speed)
                if not run['sent'].strip():
                    print(name, 'the replay did not end:', run['log'][-400:], flush=True)
                    continue
                j = judged(run, hand, eye, a.check_every)
                bad = [f'{s:.0f} s' for s, v in j['checked'] if v != 'good']
                known = np.all(np.isfinite(j['ratios']), axis=1)
                ratios, carried = j['ratios'][known], j['carried'][known]
                ok = np.all((ratios >= 0.5) & (ratios <= 2.0), axis=1)
                counts = (int(ok.sum()), len(ok), int(ok[carried].sum()), int(carried.sum()))
                totals = [a + b for a, b in zip(totals, counts, strict=True)]
                rows.append(
                    [
                        name,
                        f'{j["span"]:.0f}',
                        f'{j["ready"]} ({len(j["checked"])})',
                        ', '.join(bad) or '0',
                        ', '.join(j['results']) or '-',
                        ' '.join(f'{v:.2f}' for v in np.nanmedian(j['ratios'], axis=0)),
                        '{} of {} ({} of {})'.format(*counts),
                        j['auto'],
                    ]
                )
                print(rows[-1], json.dumps(j['checked']), ratios.round(2).tolist(), flush=True)
    finally:
        probe.close()
    emit(
        'readiness_live_real' + ('' if a.check_every == CHECK_S else '_dense'),
        table(
            f'Real recordings replayed live at {a.speed:g}x their stamps through the node '
            '(auto_calibrate, defaults): READY statuses (checked, one per '
            f'{a.check_every:g} s) against a calibration of what the node had then; results',
            [
                'recording',
                'seconds',
                'READY statuses (checked)',
                'READY, calibration not good',
                'results (verdicts)',
                'predicted / reported, median (dt t r)',
                "all three in 0.5-2 (carried from a result with the blocks' term)",
                'auto mode said last',
            ],
            rows,
        )
        + '\nresults whose predicted / reported sigmas all lie in 0.5-2: {} of {}; of those whose '
        "prediction carried a result with the blocks' term: {} of {}".format(*totals),
    )


if __name__ == '__main__':
    main()
