"""How often the bounded excerpt misjudges a candidate offset (issue 47, item 1).

The self-check examines a runner-up of the correlation with stage 2 on an excerpt of the
recording (handeye_ros.core.checks.excerpt: 8 windows holding some 800 of the eye's keyframe
motions) and scores it on at most 2000 keyframe motions. Judged there, the right offset must not be lost (a *false rejection*:
stage 2 fails at it, or a wrong candidate scores better) where the whole recording would keep
it. Each case is a 6-minute recording (100 Hz hand, 30 Hz eye) of one motion and noise level;
the candidates are the true offset and one a lap away (180 s: the ``loops`` motion repeats
there, the others do not), each solved on its own excerpt and scored together, as the
pipeline does. Per motion and level, over the seeds where stage 2 succeeds at the truth on
the whole recording: the excerpt's median share of the recording (1: the whole, for a slow
motion's few keyframes), the seeds where the truth is lost on the excerpt (stage 2 fails there,
or the lap away scores better), those where stage 2 fails a lap away, the median score ratio
(lap / truth) where it does not, and stage 2's T_HE on the excerpt against the whole's.

Usage: python bench/candidates.py [--seeds 20]
"""

from __future__ import annotations

import argparse

import numpy as np
from cases import protocol_seed
from common import emit, table

from handeye_ros.core.checks.excerpt import excerpt, excerpt_share
from handeye_ros.core.checks.selfcheck import (
    Hypothesis,
    eye_keyframes,
    score_candidates,
    scored_motions,
)
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.geometry import quat_angle
from handeye_ros.core.linear.solve import solve_linear
from handeye_ros.core.simulate import LOOP_PERIOD_S, noise_level, simulate

MOTIONS = ('random', 'loops', 'slow', 'planar_start')
LEVELS = (2.0, 5.0, 10.0)
DURATION_S = 360.0


def one(motion: str, level: float, seed: int) -> dict[str, float]:
    """A recording's truth and lap-away candidates judged on their excerpts."""
    noise_m, noise_deg = noise_level(level)
    rec = simulate(
        seed,
        duration_s=DURATION_S,
        eye_rate_hz=30.0,
        noise_m=noise_m,
        noise_deg=noise_deg,
        motion=motion,
    )
    cfg = CalibrationConfig()
    dt = rec.truth.time_offset_s
    n = eye_keyframes(rec.eye, np.deg2rad(5.0))[0].size
    share = excerpt_share(rec.eye, n)
    out = dict.fromkeys(('lost', 'rejected'), 0.0) | {'share': share}
    out |= dict.fromkeys(('ratio', 'mm', 'deg'), float('nan'))
    try:
        whole, _ = solve_linear(rec.hand, rec.eye, dt, cfg)
    except HandeyeError:
        out['share'] = float('nan')  # not calibratable at the truth: no candidate to lose
        return out
    try:
        true_lin, _ = solve_linear(*excerpt(rec.hand, rec.eye, dt, n), dt, cfg)
    except HandeyeError:
        out['lost'] = 1.0
        return out
    out['mm'] = 1e3 * float(np.linalg.norm(true_lin.p_HE - whole.p_HE))
    out['deg'] = float(np.degrees(quat_angle(true_lin.q_HE, whole.q_HE)))
    hyps = [Hypothesis(dt, 'truth', true_lin.q_HE, true_lin.p_HE)]
    wrong = dt + LOOP_PERIOD_S
    try:
        lin, _ = solve_linear(*excerpt(rec.hand, rec.eye, wrong, n), wrong, cfg)
        hyps.append(Hypothesis(wrong, 'a lap away', lin.q_HE, lin.p_HE))
    except HandeyeError:
        out['rejected'] = 1.0  # stage 2 fails a lap away: the truth stands
        return out
    scored = score_candidates(rec.hand, rec.eye, hyps, scored_motions(rec.eye, np.deg2rad(5.0)))
    out['lost'] = float(not scored[0].chosen)
    out['ratio'] = scored[1].score / scored[0].score
    return out


def _median(runs: list[dict[str, float]], key: str) -> float | str:
    values = [r[key] for r in runs if np.isfinite(r[key])]
    return float(np.median(values)) if values else '-'


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    p.add_argument('--seeds', type=int, default=20)
    args = p.parse_args()
    rows, seeds = [], []
    for motion in MOTIONS:
        for level in LEVELS:
            ks = [protocol_seed(level, k) for k in range(args.seeds)]
            seeds += ks
            runs = [one(motion, level, s) for s in ks]
            ok = [r for r in runs if np.isfinite(r['share'])]
            rows.append(
                [
                    motion,
                    level,
                    f'{len(ok)} of {len(runs)}',
                    _median(ok, 'share'),
                    f'{sum(r["lost"] for r in ok):.0f}',
                    f'{sum(r["rejected"] for r in ok):.0f}',
                    _median(ok, 'ratio'),
                    max((r['mm'] for r in ok if np.isfinite(r['mm'])), default='-'),
                    max((r['deg'] for r in ok if np.isfinite(r['deg'])), default='-'),
                ]
            )
            print(rows[-1], flush=True)
    emit(
        'candidates',
        table(
            'A candidate judged on the excerpt: the true offset against one a lap (180 s) '
            f'away, {DURATION_S:g} s recordings, 100 Hz + 30 Hz',
            [
                'motion',
                'level',
                'calibratable',
                'share',
                'truth lost on the excerpt',
                'lap: stage 2 fails',
                'lap / truth score',
                'T_HE excerpt - whole, max mm',
                'deg',
            ],
            rows,
        ),
        f'{min(seeds)}-{max(seeds)} (protocol_seed)',
    )


if __name__ == '__main__':
    main()
