"""How steady the verdict and the reported sigmas are as a real recording grows (issue 45, item
4): the six recordings of bench/readiness_real.py calibrated on their first 20, 24, 28, ... s
(``--step``), as the node's buffers would hold them.

Counted per recording:
- the verdict's turns between ``good`` and ``doubtful`` from one prefix to the next: a sigma
  near its target that moves by chance (where the blocks' edges fall, core/batch/correlated.py)
  turns it, and a user watching the node sees the verdict flicker;
- the rms change of the log of each reported 1-sigma (dt, translation, rotation) from one
  prefix to the next;
- the prediction carried from a prefix to the one GROWTH times longer (auto mode's next
  calibration; ``core/checks/carry.py``: that prefix's own prediction times this one's reported
  over predicted sigmas) over the longer prefix's reported sigmas: the share of prefixes whose
  three lie within 0.5-2 (the live target).

Usage: python bench/prefixes.py [--step 4]
"""

from __future__ import annotations

import argparse
import itertools

import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
import readiness_real
from common import emit, table

from handeye_ros.core.checks.carry import SIGMA_KEYS
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.ros.auto_mode import GROWTH

FIRST_S = 20.0


def prefixes(hand, eye, step_s: float) -> list[tuple[float, dict, dict, str, np.ndarray]]:
    """(seconds, the status's readiness, the result's document, its verdict, its reported
    1-sigmas in ms, mm, deg) for each prefix that calibrates."""
    t0 = max(int(hand.t_ns[0]), int(eye.t_ns[0]))
    span = (min(int(hand.t_ns[-1]), int(eye.t_ns[-1])) - t0) * 1e-9
    out = []
    for s in np.arange(FIRST_S, span + 1e-9, step_s):
        cut = t0 + int(s * 1e9)
        try:
            res = calibrate(hand.select(hand.t_ns <= cut), eye.select(eye.t_ns <= cut))
        except HandeyeError:
            continue
        if res.readiness is None or res.batch is None:
            continue
        status, verdict = res.readiness.to_dict(), res.quality.verdict.value
        out.append((float(s), status, res.to_dict(), verdict, readiness_real._reported(res)))
    return out


def steadiness(rows: list[tuple[float, dict, dict, str, np.ndarray]], step_s: float) -> dict:
    """The verdict's turns, the sigmas' log changes and the carried predictions' ratios."""
    seconds = np.array([r[0] for r in rows])
    sigmas = np.array([r[4] for r in rows])
    verdicts = [r[3] for r in rows]
    ratios = []
    for s, _, doc, _, _ in rows:
        j = int(np.argmin(np.abs(seconds - GROWTH * s)))
        if seconds[j] <= s or abs(seconds[j] - GROWTH * s) > step_s / 2:
            continue
        carried = readiness_real._carried(rows[j][1], doc)
        predicted = np.array([carried['sigma'][k] for k in SIGMA_KEYS], dtype=float)
        ratios.append(predicted / sigmas[j])
    return {
        'turns': sum(a != b for a, b in itertools.pairwise(verdicts)),
        'log_changes': np.diff(np.log(sigmas), axis=0),
        'ratios': np.array(ratios).reshape(-1, 3),
        'good': verdicts.count('good'),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--step', type=float, default=4.0, help='seconds between prefixes (4)')
    a = p.parse_args()
    rows, turns, changes, ratios = [], 0, [], []
    for name, hand, eye in readiness_real.recordings():
        found = prefixes(hand, eye, a.step)
        if len(found) < 2:
            rows.append([name, len(found), '-', '-', '-', '-'])
            continue
        st = steadiness(found, a.step)
        inside = np.all((st['ratios'] >= 0.5) & (st['ratios'] <= 2.0), axis=1)
        turns += st['turns']
        changes.append(st['log_changes'])
        ratios.append(st['ratios'])
        rms = np.sqrt(np.mean(st['log_changes'] ** 2, axis=0))
        rows.append(
            [
                name,
                f'{len(found)} ({st["good"]} good)',
                st['turns'],
                ' '.join(f'{v:.3f}' for v in rms),
                f'{inside.sum()} of {len(inside)}',
                ' '.join(f'{v:.2f}' for v in np.median(st['ratios'], axis=0)),
            ]
        )
        print(rows[-1], flush=True)
    all_ratios = np.vstack(ratios)
    inside = np.all((all_ratios >= 0.5) & (all_ratios <= 2.0), axis=1)
    rms = np.sqrt(np.mean(np.vstack(changes) ** 2, axis=0))
    rows.append(
        [
            'all',
            '',
            turns,
            ' '.join(f'{v:.3f}' for v in rms),
            f'{inside.sum()} of {len(inside)} ({inside.mean():.0%})',
            ' '.join(f'{v:.2f}' for v in np.median(all_ratios, axis=0)),
        ]
    )
    emit(
        'prefixes',
        table(
            f'Real recordings calibrated on their first {FIRST_S:g}, {FIRST_S + a.step:g}, ... s: '
            "the verdict's turns, the reported 1-sigmas' log change from one prefix to the next "
            f'(rms), and the prediction carried to the prefix {GROWTH:g} times longer over its '
            'reported sigmas',
            [
                'recording',
                'prefixes',
                'verdict turns',
                'log sigma change, rms (dt t r)',
                'carried: all three in 0.5-2',
                'carried / reported, median (dt t r)',
            ],
            rows,
        ),
    )


if __name__ == '__main__':
    main()
