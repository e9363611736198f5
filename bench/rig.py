"""One rig, many recordings (issue 36): the simulated figures.

Per seed, a rig of 10 recordings of 60 s (paper protocol, noise level 5), one T_HE, each
recording its own time offset and world (``random_truth``), calibrated alone and then as a rig
(:func:`handeye_ros.core.rig_pipeline.solve_rig`). Cases, each from the same ten clean recordings with
some replaced:

- clean: the ten as they are;
- moved 1 cm / 2 cm: recording 3's marker moved by 1 (2) cm in a random direction;
- rotated 1 deg: recording 3's marker turned by 1 deg about a random axis;
- two groups: recordings 5-9 of another marker (another random T_HE);
- weak: recording 3 turns about one axis only (``motion='one_axis'``).

Columns: the joint T_HE's translation and rotation errors and 1-sigmas (norms of the 3-vectors)
against the mean over the ten recordings alone (the ratio should be near 1/sqrt(10) = 0.32);
whether the truth lies in the joint's 3-sigma (chi-square 3 dof, 99.73 %, translation and
rotation); the mean |dt error| of the recordings alone and conditioned on the rig; who was named
(left out) and the groups.

Usage: python bench/rig.py [--seeds N]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import cases
import common  # noqa: F401 (puts the project on the path)
import numpy as np
from common import CHI2_3_9973, emit, table
from scipy.spatial.transform import Rotation
from scipy.stats import ncx2

from handeye_ros.core.checks.consistency import threshold
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.rig import Member, fuse
from handeye_ros.core.rig_pipeline import solve_rig
from handeye_ros.core.simulate import random_truth

N = 10
LEVEL = 5.0
DURATION_S = 60.0
ODD = 3  # the recording the one-off cases change
#: The odd recording's true displacement (translation [m], rotation [rad]) by case, of the
#: current seed (set by :func:`cases`).
ODD_TRUE: dict[str, np.ndarray] = {}


def _calibrated(seed: int, k: int, truth, motion: str = 'random'):
    rec = cases.recording(
        10_000 * seed + k, LEVEL, duration_s=DURATION_S, truth=truth, motion=motion
    )
    res = calibrate(rec.hand, rec.eye)
    return res, rec.truth


def _truths(seed: int):
    rng = np.random.default_rng(seed)
    base, other = random_truth(rng), random_truth(rng)
    own = [random_truth(np.random.default_rng([seed, k])) for k in range(N)]
    shared = [replace(t, q_HE=base.q_HE, p_HE=base.p_HE) for t in own]
    return rng, base, other, shared


def _errors(q, p, truth):
    e_t = p - truth.p_HE
    e_r = (Rotation.from_quat(q).inv() * Rotation.from_quat(truth.q_HE)).as_rotvec()
    return e_t, e_r


def rigs(seed: int) -> dict[str, list]:
    """Every case's ten (result, truth) pairs for one seed."""
    rng, base, other, shared = _truths(seed)
    clean = [_calibrated(seed, k, t) for k, t in enumerate(shared)]
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    turned = Rotation.from_quat(base.q_HE) * Rotation.from_rotvec(np.deg2rad(1.0) * direction)
    out = {'clean': clean}
    # in the bench's tangent: (p_odd - p, Log(R^T R_odd)) = (d, 0) or (0, angle * direction)
    ODD_TRUE['moved 1 cm'] = np.r_[0.01 * direction, 0, 0, 0]
    ODD_TRUE['moved 2 cm'] = np.r_[0.02 * direction, 0, 0, 0]
    ODD_TRUE['rotated 1 deg'] = np.r_[0, 0, 0, np.deg2rad(1.0) * direction]
    for name, t in (
        ('moved 1 cm', replace(shared[ODD], p_HE=base.p_HE + 0.01 * direction)),
        ('moved 2 cm', replace(shared[ODD], p_HE=base.p_HE + 0.02 * direction)),
        ('rotated 1 deg', replace(shared[ODD], q_HE=turned.as_quat())),
    ):
        out[name] = [*clean[:ODD], _calibrated(seed, 100 + ODD, t), *clean[ODD + 1 :]]
    out['weak'] = [
        *clean[:ODD],
        _calibrated(seed, ODD, shared[ODD], 'one_axis'),
        *clean[ODD + 1 :],
    ]
    second = [replace(t, q_HE=other.q_HE, p_HE=other.p_HE) for t in shared[5:]]
    out['two groups'] = clean[:5] + [_calibrated(seed, 200 + k, t) for k, t in enumerate(second)]
    return out, base


def row(case: str, seed: int, runs: list, base) -> list:
    members, failed, followers = [], {}, []
    for k, (res, _) in enumerate(runs):
        if res.batch is None:  # as the application: no covariance of its own, it follows
            followers.append(f'r{k}')
            continue
        try:
            member = Member.from_document(f'r{k}', res.to_dict())
        except ValueError as err:
            failed[f'r{k}'] = str(err)
            continue
        if member.holds_rotation:  # as the application: turned in place, it follows
            followers.append(f'r{k}')
        else:
            members.append(member)
    t0 = time.perf_counter()
    rig = solve_rig(members, failed, tuple(followers))
    seconds = time.perf_counter() - t0
    power = float('nan')
    if case in ODD_TRUE and f'r{ODD}' in {m.name for m in rig.members}:
        # the chance the test had to name it: noncentral chi-square of its true displacement
        # against both covariances (the rig's without it, its own)
        odd = next(m for m in rig.members if m.name == f'r{ODD}')
        others = fuse([m for m in rig.members if m.name != odd.name])
        d = ODD_TRUE[case]
        lam = d @ np.linalg.solve(odd.extrinsic_covariance + others.covariance, d)
        power = float(ncx2.sf(threshold(len(rig.members)), 6, lam))
    e_t, e_r = _errors(rig.joint.q_HE, rig.joint.p_HE, base)
    C = rig.joint.covariance
    inside = (
        e_t @ np.linalg.solve(C[:3, :3], e_t) <= CHI2_3_9973
        and e_r @ np.linalg.solve(C[3:, 3:], e_r) <= CHI2_3_9973
    )
    ref = [runs[k] for k in range(5) if k != ODD]  # clean in every case
    alone_t = np.mean([np.linalg.norm(_errors(r.q_HE, r.p_HE, base)[0]) for r, _ in ref])
    alone_st = np.mean([np.linalg.norm(r.batch.std[1:4]) for r, _ in ref])
    alone_r = np.mean([np.linalg.norm(_errors(r.q_HE, r.p_HE, base)[1]) for r, _ in ref])
    alone_sr = np.mean([np.linalg.norm(r.batch.std[4:7]) for r, _ in ref])
    dt_alone, dt_joint = [], []
    for m, shared in zip(rig.members, rig.shared, strict=True):
        if shared is None:
            continue
        res, truth = runs[int(m.name[1:])]
        dt_alone.append(abs(res.time_offset_s - truth.time_offset_s))
        dt_joint.append(abs(shared.values['time_offset'] - truth.time_offset_s))
    named = sorted(set(rig.why_not))
    return [
        case,
        seed,
        np.linalg.norm(e_t) * 1e3,
        np.linalg.norm(rig.joint.std[:3]) * 1e3,
        alone_t * 1e3,
        alone_st * 1e3,
        np.degrees(np.linalg.norm(e_r)),
        np.degrees(np.linalg.norm(rig.joint.std[3:])),
        np.degrees(alone_r),
        np.degrees(alone_sr),
        'yes' if inside else 'NO',
        np.mean(dt_alone) * 1e3,
        np.mean(dt_joint) * 1e3,
        ' '.join(named) or '-',
        ' '.join(rig.followers) or '-',
        power,
        '/'.join(str(len(g)) for g in rig.split.groups),
        str(rig.quality.verdict),
        seconds * 1e3,
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seeds', type=int, default=10)
    args = ap.parse_args()
    seeds = list(range(1, args.seeds + 1))
    rows = []
    for seed in seeds:
        runs, base = rigs(seed)
        rows += [row(case, seed, r, base) for case, r in runs.items()]
    order = list(dict.fromkeys(r[0] for r in rows))
    rows.sort(key=lambda r: (order.index(r[0]), r[1]))
    header = (
        'case',
        'seed',
        'err mm',
        'sigma mm',
        'alone err mm',
        'alone sigma mm',
        'err deg',
        'sigma deg',
        'alone err deg',
        'alone sigma deg',
        'in 3sigma',
        'dt alone ms',
        'dt rig ms',
        'named',
        'follow',
        'power',
        'groups',
        'verdict',
        'rig ms',
    )
    emit('rig', table('One rig, ten recordings of 60 s, noise level 5', header, rows), seeds)
    summary = []
    for case in dict.fromkeys(r[0] for r in rows):
        rs = [r for r in rows if r[0] == case]
        summary.append(
            [
                case,
                np.mean([r[2] / r[4] for r in rs]),
                np.mean([r[3] / r[5] for r in rs]),
                np.mean([r[6] / r[8] for r in rs]),
                np.mean([r[7] / r[9] for r in rs]),
                f'{sum(r[10] == "yes" for r in rs)}/{len(rs)}',
                np.mean([r[11] for r in rs]),
                np.mean([r[12] for r in rs]),
                f'{sum(r[13] == f"r{ODD}" for r in rs)}/{len(rs)}',
                np.mean([r[15] for r in rs]),
                f'{sum(r[14] == f"r{ODD}" for r in rs)}/{len(rs)}',
                f'{sum(r[16] == "5/5" for r in rs)}/{len(rs)}',
            ]
        )
    emit(
        'rig_summary',
        table(
            'One rig: joint over alone (means over seeds)',
            (
                'case',
                'err t ratio',
                'sigma t ratio',
                'err r ratio',
                'sigma r ratio',
                'in 3sigma',
                'dt alone ms',
                'dt rig ms',
                f'only r{ODD} named',
                'expected power',
                f'r{ODD} follows',
                '5/5 groups',
            ),
            summary,
        ),
        seeds,
    )


if __name__ == '__main__':
    main()
