"""One rig, many recordings, on real VIO (issue 36): read, not tuned.

- EuRoC: the rpg estimates vio_mono and vio_stereo on MH_01, MH_03, MH_05, V2_01, V2_02 against
  each sequence's ground truth, both in the IMU frame (truth T_HE = I): one rig per estimator.
  Each sequence's ground truth is its own estimate (they differ at the centimetre level), so the
  figures are about consistency: the rig's sigma against a single sequence's, each sequence
  inside the joint estimate's 3 sigma or named with its difference, the same named for both.
- EuRoC MH_01-MH_05, the real-time VI-SLAM runs of rpg's ``vislam_rp`` (loop-closure jumps,
  one camera frame of offset) against the ground truth: one rig (issue 45: its consistency
  test rests on the correlated term's sigmas).
- TUM-VI room1 + outdoors4, ORB-SLAM3 VIO, ``clock_drift`` (ground truth in the IMU frame,
  truth I): the rig's T_HE against I.

Per recording: its own T_HE's difference from I (mm, deg), its 1-sigma, its chi-square against
the others of the largest group, whether the rig uses it, and its verdict for purpose
evaluation alone and at the rig's T_HE (each evaluated, as ``offline_calibrate --rig`` does);
per rig: T_HE against I, its 1-sigma, the verdict for evaluation (on its recordings' figures)
and for extrinsic, with their reasons.

Usage: python bench/rig_real.py
"""

from __future__ import annotations

import cases
import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
from common import emit, table

from handeye_ros.app.rig import Own, finish, role, shared_outputs, solve, summary_of
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.geometry import difference
from handeye_ros.core.pipeline import calibrate
from handeye_ros.evaluation.outputs import evaluate_and_write

EUROC = ('MH_01', 'MH_03', 'MH_05', 'V2_01', 'V2_02')
IDENTITY = (np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3))


def rigs() -> dict[str, list[tuple[str, object]]]:
    """Per rig, its recordings' (name, own result)."""
    drift = CalibrationConfig(clock_drift=True)
    return {
        **{
            f'EuRoC vio_{kind}': [
                (seq, calibrate(*cases.run(f'EuRoC {seq} {kind}').load())) for seq in EUROC
            ]
            for kind in ('mono', 'stereo')
        },
        'EuRoC VI-SLAM': [
            (seq, calibrate(*cases.run(f'VI-SLAM {seq}').load())) for seq in cases.EUROC_GT
        ],
        'TUM-VI ORB-SLAM3': [
            (seq, calibrate(*cases.run(f'TUM-VI {seq} orbslam').load(), drift))
            for seq in ('room1', 'outdoors4')
        ],
    }


def _mm_deg(v: np.ndarray) -> tuple[float, float]:
    return float(np.linalg.norm(v[:3]) * 1e3), float(np.degrees(np.linalg.norm(v[3:])))


def _evaluated_label(res) -> str:
    """A recording's verdict alone, its figures judged (purpose evaluation)."""
    return evaluate_and_write(res, res.to_dict()).quality.label(' ')


def main() -> None:
    rows, summary = [], []
    for name, runs in rigs().items():
        owns = [Own(seq, res.to_dict(), res) for seq, res in runs]
        rig = solve([summary_of(own) for own in owns])
        docs = [shared_outputs(own, rig.joint, *role(rig, own.name), None, False) for own in owns]
        rig_doc = finish(rig, [own.name for own in owns], docs, None)
        quality = rig_doc['rig']['quality']
        index = {m.name: k for k, m in enumerate(rig.members)}
        for (seq, res), doc in zip(runs, docs, strict=True):
            k = index[seq]  # every real recording here gives a member
            m, test = rig.members[k], rig.split.tests[k]
            own = difference(m.q_HE, m.p_HE, *IDENTITY)
            q = doc['quality']
            rows.append(
                [
                    name,
                    seq,
                    ' '.join(f'{v * 1e3:+.1f}' for v in m.p_HE),
                    *_mm_deg(own),
                    np.linalg.norm(np.sqrt(m.extrinsic_covariance.diagonal()[:3])) * 1e3,
                    np.degrees(np.linalg.norm(np.sqrt(m.extrinsic_covariance.diagonal()[3:]))),
                    '-' if test is None else test.chi2,
                    'yes' if seq in rig.used else 'NO',
                    _evaluated_label(res),
                    ' '.join([q['verdict'], *q['for_evaluation']['codes']])
                    if seq in rig.used
                    else '-',
                ]
            )
        joint = difference(rig.joint.q_HE, rig.joint.p_HE, *IDENTITY)
        alone = np.median(
            [np.linalg.norm(np.sqrt(m.extrinsic_covariance.diagonal()[:3])) for m in rig.members]
        )
        summary.append(
            [
                name,
                ' '.join(f'{v * 1e3:+.1f}' for v in rig.joint.p_HE),
                *_mm_deg(joint),
                np.linalg.norm(rig.joint.std[:3]) * 1e3,
                np.degrees(np.linalg.norm(rig.joint.std[3:])),
                np.linalg.norm(rig.joint.std[:3]) / alone,
                rig.split.threshold,
                ' '.join(rig.used),
                ' '.join([quality['verdict'], *quality['for_evaluation']['codes']]),
                ' '.join(
                    [quality['for_extrinsic']['verdict'], *quality['for_extrinsic']['codes']]
                ),
            ]
        )
    emit(
        'rig_real_recordings',
        table(
            'Real rigs: each recording alone (T_HE against the truth I)',
            (
                'rig',
                'recording',
                'own t mm',
                'own err mm',
                'own err deg',
                'sigma mm',
                'sigma deg',
                'chi2',
                'used',
                'alone: evaluation',
                "at the rig's T_HE: evaluation",
            ),
            rows,
        ),
    )
    emit(
        'rig_real',
        table(
            'Real rigs: the joint T_HE (against the truth I)',
            (
                'rig',
                't mm',
                'err mm',
                'err deg',
                'sigma mm',
                'sigma deg',
                'sigma / median alone',
                'chi2 limit',
                'used',
                'evaluation',
                'extrinsic',
            ),
            summary,
        ),
    )


if __name__ == '__main__':
    main()
