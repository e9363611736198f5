"""The node's status against its own calibrations on real recordings (issue 45, item 4), without
DDS: each recording is read as the node's buffers would hold it after 20, 30, ... s, and at each
prefix the status's readiness (the result's ``readiness`` before it is carried over: the
figures the status shows for those buffers) is carried over as the node carries it
(``core/checks/carry.py``: ``carry_over`` with the factors and held reasons of the last result,
``predictor_factors``: at the first prefix
predicted READY that prefix's own calibration, as the node checks it, then auto mode's, each
time the span has grown by GROWTH), then compared with a calibration of that prefix.

Counted per recording: the prefixes whose carried status is READY while the calibration of the
same prefix is not ``good`` (target: 0), and the predicted over reported 1-sigma (dt,
translation, rotation) with and without the carry-over (target: 0.5-2): its median over the
prefixes and the share of them within 0.5-2. A live replay through
the node at the recordings' own stamps is not run here: this runs the same functions on the
same buffers, a step of 10 s apart instead of every status period.

Usage: python bench/readiness_real.py [--step 10]
"""

from __future__ import annotations

import argparse

import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
import realdata
from common import emit, table

from handeye_ros.core.checks.carry import (
    SIGMA_KEYS,
    carry_over,
    held_reasons,
    predictor_factors,
)
from handeye_ros.core.checks.verdict import BLOCKS_MARGIN, sigmas_of
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.formats import read_trajectory
from handeye_ros.ros.auto_mode import GROWTH

TUMVI = realdata.REAL_DATA / 'VSLAM-comparison' / 'Trajectory-files' / 'tum-vi'
FIRST_S = 20.0
HEADER = [
    'recording',
    'prefixes',
    'READY, result not good',
    'READY',
    'good',
    'predicted / reported (dt t r), raw',
    'carried over',
]


def recordings() -> list[tuple[str, object, object]]:
    out = []
    for name in ('V1_02 evo', 'V2_01 mono', 'V2_02 stereo', 'MH_01 stereo', 'MH_03 mono'):
        pair = next(p for p in realdata.PAIRS if p.name == name)
        out.append((f'EuRoC {name}', *realdata.load(pair)))
    out.append(
        (
            'TUM-VI room1 ORB-SLAM3 VIO',
            read_trajectory(TUMVI / 'room1_GT.tum'),
            read_trajectory(TUMVI / 'orbslam-room1-vio.tum'),
        )
    )
    return out


def _reported(res) -> np.ndarray:
    s = sigmas_of(res.batch.std)
    return np.array([s[0] * 1e3, s[1] * 1e3, s[2]])


def _carried(status: dict, published: dict | None) -> dict:
    """The status as the node carries it over from the result ``published``."""
    if published is None:
        return carry_over(status, {}, [])
    return carry_over(
        status, predictor_factors(published), held_reasons(published), margin=BLOCKS_MARGIN
    )


def prefixes(hand, eye, step: float) -> list[list]:
    """Per prefix: [seconds, READY carried, verdict, predicted / reported raw, carried]."""
    t0 = max(hand.t_ns[0], eye.t_ns[0])
    end = min(hand.t_ns[-1], eye.t_ns[-1])
    published, span, rows = None, 0.0, []
    for s in np.arange(FIRST_S, (end - t0) * 1e-9 + step, step):
        cut = t0 + int(s * 1e9)
        try:
            res = calibrate(hand.select(hand.t_ns <= cut), eye.select(eye.t_ns <= cut))
        except HandeyeError:
            continue
        doc = res.to_dict()
        # the status the node shows for these buffers: the predictions, before any result
        status = None if res.readiness is None else res.readiness.to_dict()
        if status is None or res.batch is None:
            continue
        carried, had = _carried(status, published), published is not None
        if carried['ready'] and published is None:  # the node checks it with this calibration
            carried, published, span = _carried(status, doc), doc, s
        raw = np.array([status['sigma'][k] or np.nan for k in SIGMA_KEYS])
        now = np.array([carried['sigma'][k] or np.nan for k in SIGMA_KEYS])
        rows.append(
            [
                float(s),
                carried['ready'],
                res.quality.verdict.value,
                raw / _reported(res),
                now / _reported(res),
                had,  # its ratio is a prediction's (the check's own is 1 by construction)
            ]
        )
        if published is not None and s >= GROWTH * span:  # auto mode's next result
            published, span = doc, s
    return rows


def spread(ratios: np.ndarray) -> str:
    """Per group (dt t r): the median ratio and the share of prefixes within 0.5-2."""
    inside = np.mean((ratios >= 0.5) & (ratios <= 2.0), axis=0)
    return ' '.join(
        f'{m:.2f} ({f:.0%})' for m, f in zip(np.median(ratios, 0), inside, strict=True)
    )


def summary(name: str, rows: list[list]) -> list:
    """A row of HEADER from :func:`prefixes`' rows: READY while not ``good``, READY, ``good``
    and the ratios, raw and carried (those of prefixes with a result to carry)."""
    carried = [r for r in rows if r[5]]
    raw = np.array([r[3] for r in rows])
    now = np.array([r[4] for r in carried]) if carried else np.full((1, 3), np.nan)
    return [
        name,
        len(rows),
        sum(r[1] and r[2] != 'good' for r in rows),
        sum(r[1] for r in rows),
        sum(r[2] == 'good' for r in rows),
        spread(raw),
        spread(now),
    ]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--step', type=float, default=10.0, help='seconds between prefixes')
    a = p.parse_args()
    out = []
    for name, hand, eye in recordings():
        out.append(summary(name, prefixes(hand, eye, a.step)))
        print(out[-1], flush=True)
    emit(
        'readiness_real',
        table(
            f'The status on prefixes of real recordings ({FIRST_S:.0f} s, then every {a.step:g} s), '
            'carried over as the node carries it, against a calibration of each prefix',
            HEADER,
            out,
        ),
    )


if __name__ == '__main__':
    main()
