"""The correlated term of the uncertainty against a known truth (issue 45, item 1): simulations
whose time offset wanders along the recording (``simulate(wander_s=...)``: a latency that changes
with the VIO's load; the truth is its mean over the recording), at the paper's noise levels.

Per level and wander: how often the truth lies within the reported 3-sigma (dt; the translation
and the rotation by their chi^2_3 99.73 % Mahalanobis distance), the root-mean-square of the dt
error over its 1-sigma, the median reported dt 1-sigma, and how often the result notes that the
offset varies along the recording. ``before``: the rule this replaced (the long-run covariance
times Birge's ratio of the blocks against their own covariances), recomputed from the same
blocks: it counted the long-run correlation twice where a block's covariance is not B times the
whole's.

Usage: python bench/wander.py [--seeds N]
"""

from __future__ import annotations

import argparse

import cases
import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
from common import covered, emit, table

from handeye_ros.core.batch import correlated
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.stages import batch as batch_stage

LEVELS = (2, 5)
WANDERS_MS = (0.0, 1.0, 3.0, 10.0)
DURATION_S = 60.0

_blocks: list[tuple[np.ndarray, np.ndarray]] = []
_varies = correlated.varies


def _spy(deviations: np.ndarray, covariances: np.ndarray) -> dict:
    _blocks.append((deviations, covariances))
    return _varies(deviations, covariances)


def _birge(deviations: np.ndarray, covariances: np.ndarray) -> dict[str, float]:
    B, out = deviations.shape[0], {}
    for group, idx in correlated.GROUPS.items():
        i = list(idx)
        if not np.all(covariances[:, i, i] > 0.0):
            continue
        ratio = sum(
            float(d[i] @ np.linalg.solve(C[np.ix_(i, i)], d[i]))
            for d, C in zip(deviations, covariances, strict=True)
        )
        out[group] = float(np.sqrt(max(1.0, ratio / (len(i) * (B - 1)))))
    return out


class _View:
    """The result as :func:`common.covered` reads it, with another covariance."""

    def __init__(self, res, cov) -> None:
        self.time_offset_s, self.p_HE, self.q_HE = res.time_offset_s, res.p_HE, res.q_HE
        self.batch = type('Batch', (), {'covariance': cov})


def rows(seeds: int) -> list[list]:
    batch_stage.varies = _spy
    out = []
    for level in LEVELS:
        for wander in WANDERS_MS:
            now, before, z_now, z_before, sd, noted = [], [], [], [], [], 0
            for k in range(seeds):
                rec = cases.protocol(level, k, duration_s=DURATION_S, wander_s=wander * 1e-3)
                _blocks.clear()
                r = calibrate(rec.hand, rec.eye)
                u = r.batch.uncertainty
                d, C = _blocks[-1]
                old = correlated.inflated(u.long_run, _birge(d, C)) + (
                    u.covariance - correlated.inflated(u.long_run, u.factors or {})
                )
                now.append(covered(r, rec.truth))
                before.append(covered(_View(r, old), rec.truth))
                e = r.time_offset_s - rec.truth.time_offset_s
                z_now.append(e / np.sqrt(u.covariance[0, 0]))
                z_before.append(e / np.sqrt(old[0, 0]))
                sd.append(np.sqrt(u.covariance[0, 0]))
                noted += 'time_offset' in u.varies
            out.append(
                [
                    level,
                    f'{wander:g}',
                    seeds,
                    ' '.join(f'{v:.0%}' for v in np.mean(before, 0)),
                    ' '.join(f'{v:.0%}' for v in np.mean(now, 0)),
                    f'{np.sqrt(np.mean(np.square(z_before))):.2f}',
                    f'{np.sqrt(np.mean(np.square(z_now))):.2f}',
                    f'{np.median(sd) * 1e3:.3f}',
                    f'{noted}/{seeds}',
                ]
            )
            print(out[-1], flush=True)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--seeds', type=int, default=20, help='simulations a case (default 20)')
    a = p.parse_args()
    emit(
        'wander',
        table(
            f'A time offset that wanders along {DURATION_S:.0f}-s recordings (rms, ms; the truth '
            'its mean): truth within 3 sigma (dt t r), rms of dt error / sigma, median dt sigma, '
            'results that note it varies',
            [
                'level',
                'wander ms',
                'seeds',
                '3-sigma before',
                '3-sigma now',
                'rms z dt before',
                'rms z dt now',
                'dt sigma ms',
                'noted',
            ],
            rows(a.seeds),
        ),
        seeds=a.seeds,
    )


if __name__ == '__main__':
    main()
