"""Readiness against the truth (issue 28's figures; printed, not asserted).

Simulated recordings that start poor (planar for their first third) and become rich, each
read as the node's status reads its buffers every 10 s: at every prefix the readiness as the
node's status gathers it (core/checks/progress.py: the whole prefix read when
``Progress.due`` says so, else only the poses new since the last status, then
``readiness_of``) and a full calibration of the same prefix, compared with the truth. Counted:
- READY raised while the calibration of the data so far is further from the truth than 3x the
  targets (precision_time_offset, _translation, _rotation; 1 ms, 10 mm, 0.5 deg): must be 0;
- when READY, the predicted 1-sigmas over the batch stage's reported ones (target: within a
  factor 2);
- recordings that stay planar or one-axis: READY never, and the axis named;
- the status carried over as the node carries it (bench/readiness_real.py's ``prefixes``, on
  the same recordings from 20 s): READY while the calibration of the same prefix is not
  ``good`` (target: 0), and the predicted over reported 1-sigmas, raw and carried (target:
  0.5-2), their median and the share of prefixes within.

Hand 200 Hz with 0.1 mm / 0.0057 deg white noise, eye 30 Hz at noise level 5, 90 s.

Usage: python bench/readiness.py [--seeds 20] [--step 10]
"""

from __future__ import annotations

import argparse
import time

import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
import readiness_real
from common import emit, table

from handeye_ros.core.checks.progress import measure, start
from handeye_ros.core.checks.readiness import readiness, readiness_of
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.simulate import calibration_error, noise_level, simulate

DURATION_S = 90.0
RATES = {'hand_rate_hz': 200.0, 'eye_rate_hz': 30.0}
MOCAP = {'hand_noise_m': 1e-4, 'hand_noise_deg': 0.0057}


def _record(seed: int, motion: str):
    nm, nd = noise_level(5)
    return simulate(
        seed, duration_s=DURATION_S, noise_m=nm, noise_deg=nd, motion=motion, **RATES, **MOCAP
    )


def _prefix(traj, t_end_ns: int):
    return traj.select(np.flatnonzero(traj.t_ns <= t_end_ns))


def _batch_sigmas(res) -> tuple[float, float, float] | None:
    if res.batch is None:
        return None
    s = res.batch.std
    return (s[0], float(np.linalg.norm(s[1:4])), float(np.degrees(np.linalg.norm(s[4:7]))))


def _tail(traj, from_ns: int):
    """What PoseBuffer.since gives: from the newest pose at or before ``from_ns``."""
    first = max(int(np.searchsorted(traj.t_ns, from_ns, side='right')) - 1, 0)
    return traj.select(np.arange(first, len(traj)))


def status_of(progress, hand, eye, cfg: CalibrationConfig):
    """One status of the node on its buffers ``hand`` and ``eye``: the progress, read whole
    or grown by the new poses, and its readiness; ``read_whole`` whether it was read whole."""
    span = min(hand.duration_s, eye.duration_s)
    read_whole = progress is None or progress.due(span) is not None
    if read_whole:
        progress = start(hand, eye, cfg)
    else:
        hand_from, eye_from = progress.wants(int(hand.t_ns[-1]), int(eye.t_ns[-1]))
        progress.take(
            measure(progress.cursor(), _tail(hand, hand_from), _tail(eye, eye_from), cfg)
        )
    durations = (hand.duration_s, eye.duration_s)
    return progress, readiness_of(progress, cfg, durations), read_whole


def poor_then_rich(seeds: int, step_s: float, cfg: CalibrationConfig) -> tuple[str, dict]:
    target = np.array(
        [cfg.precision_time_offset, cfg.precision_translation, cfg.precision_rotation]
    )
    rows, ratios, false_ready, ready_at = [], [], 0, []
    status_s, read_whole = [], 0
    for seed in range(seeds):
        rec = _record(seed, 'planar_start')
        t0 = int(rec.eye.t_ns[0])
        first_ready, progress = None, None
        for t in np.arange(step_s, DURATION_S - 2.0 + 1e-9, step_s):
            end = t0 + int(t * 1e9)
            hand, eye = _prefix(rec.hand, end + 10**9), _prefix(rec.eye, end)
            c0 = time.perf_counter()
            progress, r, whole = status_of(progress, hand, eye, cfg)
            status_s.append(time.perf_counter() - c0)
            read_whole += whole
            if not r.ready:
                continue
            try:
                res = calibrate(hand, eye, cfg)
            except HandeyeError:
                false_ready += 1
                continue
            err = calibration_error(rec.truth, res.time_offset_s, res.q_HE, res.p_HE)
            e = np.array([err.time_offset_s, err.translation_m, err.rotation_deg])
            if np.any(e > 3 * target):
                false_ready += 1
            batch = _batch_sigmas(res)
            if batch is not None:
                ratios.append(np.array(r.sigma) / np.array(batch))
            if first_ready is None:
                first_ready = t
        ready_at.append(first_ready)
        rows.append([seed, '-' if first_ready is None else f'{first_ready:.0f} s'])
    ratios = np.array(ratios) if ratios else np.zeros((0, 3))
    summary = {
        'false_ready': false_ready,
        'ready_prefixes': len(ratios),
        'never_ready': sum(r is None for r in ready_at),
        'ratio_min': ratios.min(axis=0) if len(ratios) else None,
        'ratio_max': ratios.max(axis=0) if len(ratios) else None,
        'read_whole': f'{read_whole} of {len(status_s)}',
        'status_ms': 1e3 * float(np.median(status_s)),
        'status_max_ms': 1e3 * float(np.max(status_s)),
    }
    return table(
        f'Poor then rich ({seeds} seeds, planar for the first 30 s of {DURATION_S:.0f}): '
        'first prefix found READY',
        ['seed', 'READY from'],
        rows,
    ), summary


def stays_poor(seeds: int, cfg: CalibrationConfig) -> tuple[int, int, int]:
    """Recordings that stay planar or one-axis: (recordings, ever READY, axis advice given)."""
    n = ready = named = 0
    for motion in ('planar', 'one_axis'):
        for seed in range(seeds):
            rec = _record(100 + seed, motion)
            r = readiness(rec.hand, rec.eye, cfg)
            n += 1
            ready += r.ready
            named += any(m.startswith('turn the device about its') for m in r.missing)
    return n, ready, named


def carried(seeds: int, step_s: float) -> list[list]:
    """The poor-then-rich recordings' statuses carried over as the node carries them: a row
    of READY while not ``good``, READY, ``good`` and the ratios, raw and carried."""
    rows = []
    for seed in range(seeds):
        rec = _record(seed, 'planar_start')
        rows += readiness_real.prefixes(rec.hand, rec.eye, step_s)
    return [readiness_real.summary(f'{seeds} poor then rich', rows)]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--seeds', type=int, default=20)
    p.add_argument('--step', type=float, default=10.0, help='prefix step [s] (default 10)')
    args = p.parse_args()
    cfg = CalibrationConfig()
    per_seed, s = poor_then_rich(args.seeds, args.step, cfg)
    n, ready, named = stays_poor(args.seeds // 2, cfg)

    def rng(k: int) -> str:
        if s['ratio_min'] is None:
            return '-'
        return f'{s["ratio_min"][k]:.2f}-{s["ratio_max"][k]:.2f}'

    rows = [
        ['READY while the calibration so far is beyond 3x the targets', s['false_ready'], '0'],
        ['prefixes found READY (and calibrated)', s['ready_prefixes'], ''],
        ['poor-then-rich recordings never READY', s['never_ready'], ''],
        ['predicted / reported 1-sigma, dt', rng(0), '0.5-2'],
        ['predicted / reported 1-sigma, translation', rng(1), '0.5-2'],
        ['predicted / reported 1-sigma, rotation', rng(2), '0.5-2'],
        [f'planar and one-axis recordings ({n}) ever READY', ready, '0'],
        [f'planar and one-axis recordings ({n}) naming the axis to add', named, str(n)],
        [
            'status computation, median / max [ms]',
            f'{s["status_ms"]:.0f} / {s["status_max_ms"]:.0f}',
            '',
        ],
        ['statuses that read the whole prefix', s['read_whole'], ''],
    ]
    emit(
        'readiness',
        per_seed
        + '\n\n'
        + table(
            'Readiness against the truth (core/checks/progress.py and readiness.py)',
            ['figure', 'measured', 'target'],
            rows,
        ),
        seeds=f'0..{args.seeds - 1} (poor then rich), 100..{100 + args.seeds // 2 - 1} (planar, one-axis)',
    )
    emit(
        'readiness_carried',
        table(
            f'The status carried over as the node carries it (from {readiness_real.FIRST_S:.0f} s, '
            f'every {args.step:g} s), against a calibration of each prefix',
            readiness_real.HEADER,
            carried(args.seeds, args.step),
        ),
        seeds=f'0..{args.seeds - 1}',
    )


if __name__ == '__main__':
    main()
