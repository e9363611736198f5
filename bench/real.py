"""Every real run of the development data (cases.RUNS), each calibrated once with the default
options, all in the IMU frame (truth T_HE = I, dt = 0; +50 ms for the real-time VI-SLAM runs,
whose eye clock is one camera frame ahead): what the verdict says for each purpose (issue 66)
and whether the reported 1-sigma holds on real VIO (issue 34).

Seven tables:

- ``purpose_real``: the verdict for purpose evaluation (the figures judged, as every front end
  does) and for extrinsic, the largest share of an APE/RPE figure that the calibration's 1-sigma
  is, the errors, whether the run is accurate (within 5 ms / 20 mm / 1 deg of the truth), and
  how far the APE (translation, rotation) at the truth lies from the reported APE in its
  calibration 1-sigmas (whether the error bars an evaluation reads hold).
- ``uncertainty_errors``: the verdict, the error and the reported 1-sigma (norms), the groups
  noted to vary along the recording, the eye's scale against the VIO's own Sim(3) scale, and per
  axis the rms of error / sigma.
- ``uncertainty_common``: the same runs by the reference they share (SHARED): the error common
  to a set's runs, and the rms of error / sigma against I and against the set's other runs.
- ``uncertainty_pairs``: every pair of estimates of one recording, TUM-VI outdoors4 (Basalt
  VIO, ORB-SLAM3 VIO, Basalt VO; ``clock_drift``, as the tool asks there) and EuRoC MH_01,
  MH_03, MH_05, V2_01, V2_02 (vio_mono against vio_stereo): per axis of T_HE's translation and
  for dt, the difference over the combined sigma, with the long-run covariance alone (before)
  and with the reported one (now); the largest of each pair.
- ``uncertainty_terms``: each of those estimates' reported 1-sigma per group, the term that
  dominates it (white, correlated, scale: core/batch/correlated.py), the blocks' factors and the
  eye's scale, and the verdict.
- ``rig_real_recordings``, ``rig_real``: one rig, many recordings (issue 36), read, not tuned:
  the EuRoC estimates vio_mono and vio_stereo on MH_01, MH_03, MH_05, V2_01, V2_02 (one rig per
  estimator; each sequence's ground truth is its own estimate, centimetres apart, so the figures
  are about consistency), the VI-SLAM runs of MH_01-MH_05 (their consistency test rests on the
  correlated term's sigmas), and TUM-VI room1 + outdoors4, ORB-SLAM3 VIO with ``clock_drift``.
  Per recording: its own T_HE's difference from I, its 1-sigma, its chi-square against the others
  of the largest group, whether the rig uses it, its verdict for evaluation alone and at the
  rig's T_HE (as ``offline_calibrate --rig`` evaluates it); per rig: T_HE against I, its
  1-sigma, the verdict for evaluation (on its recordings' figures) and for extrinsic.

Usage: python bench/real.py
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import cases
import common  # noqa: F401  (first: puts the project on sys.path)
import numpy as np
from common import emit, judged, sim3_scale, table, truth_within
from scipy.spatial.transform import Rotation

from handeye_ros.app.rig import Own, finish, role, shared_outputs, solve, summary_of
from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.geometry import difference
from handeye_ros.core.pipeline import calibrate
from handeye_ros.core.result import CalibrationResult
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.evaluation.outputs import JUDGED, evaluate_and_write

#: What counts as an accurate answer (issue 66's figure): dt [s], T_HE [m], [deg].
ACCURATE = (5e-3, 0.020, 1.0)
#: TUM-VI outdoors4's estimates by the names the pairs' tables give them.
OUTDOORS4 = {
    'basalt vio': 'basalt-outdoors4-vio.txt',
    'orbslam vio': 'orbslam-outdoors4-vio.tum',
    'basalt vo': 'basalt-outdoors4-vo.txt',
}
EUROC = ('MH_01', 'MH_03', 'MH_05', 'V2_01', 'V2_02')
#: The sets whose runs share a reference (the ground truth's own MoCap and its body frame):
#: EuRoC's Vicon room (V1, V2) and its Machine Hall (a Leica laser tracker), TUM-VI.
SHARED = {
    'EuRoC Vicon room': ('EuRoC V',),
    'EuRoC Machine Hall': ('EuRoC MH',),
    'VI-SLAM (Machine Hall)': ('VI-SLAM',),
    'Machine Hall, both': ('EuRoC MH', 'VI-SLAM'),
    'TUM-VI': ('TUM-VI',),
}
_IDENTITY = np.r_[0, 0, 0, 1.0]
IDENTITY = (_IDENTITY, np.zeros(3))


@dataclass(frozen=True)
class Calibrated:
    """One real run and its calibration with the default options (None: refused, ``why``)."""

    run: cases.RealRun
    hand: Trajectory
    eye: Trajectory
    result: CalibrationResult | None
    why: str = ''


def calibrated_runs() -> list[Calibrated]:
    out = []
    for run in cases.RUNS:
        hand, eye = run.load()
        try:
            out.append(Calibrated(run, hand, eye, calibrate(hand, eye)))
        except HandeyeError as err:  # Basalt room1: its quaternion columns as published
            out.append(Calibrated(run, hand, eye, None, str(err)))
    return out


# --- purpose_real ---------------------------------------------------------------------------


def largest_share(ev) -> str:
    """The largest share of a figure its calibration 1-sigma is, with the figure and the part
    of the calibration that moves it most (``CalibrationSigmas.through``; '-' none named, or
    without error bars)."""
    shares = [
        (ev.sigmas.sigmas[key]['rmse'] / getattr(ev.calibrated, key).rmse, key)
        for key, *_ in JUDGED
        if ev.sigmas is not None
        and ev.sigmas.sigmas[key]['rmse'] is not None
        and getattr(ev.calibrated, key).rmse > 0
    ]
    if not shares:
        return '-'
    share, key = max(shares)
    return f'{share:.1%} {key} ({ev.sigmas.through.get(key) or "-"})'


def purpose_rows(runs: list[Calibrated]) -> list[list[object]]:
    rows: list[list[object]] = []
    for c in runs:
        if c.result is None:
            rows.append([c.run.name, 'refused', '-', '-', '-', '-', '-', c.why[:50]])
            continue
        dt_ref = c.run.reference_s
        r, ev = judged(c.result)
        within = truth_within(c.result, ev, dt_ref, _IDENTITY, np.zeros(3))
        share = '-' if ev is None else largest_share(ev)
        errors = (
            abs(r.time_offset_s - dt_ref),
            float(np.linalg.norm(r.p_HE)),
            float(np.degrees(Rotation.from_quat(r.q_HE).magnitude())),
        )
        accurate = all(e <= a for e, a in zip(errors, ACCURATE, strict=True))
        rows.append(
            [
                c.run.name,
                r.quality.label(),
                r.quality.other.label(),
                share,
                f'{errors[0] * 1e3:.1f} / {errors[1] * 1e3:.1f} / {errors[2]:.2f}',
                'yes' if accurate else 'no',
                ' / '.join('-' if w is None else f'{w:.2f}' for w in within),
                '',
            ]
        )
    return rows


# --- uncertainty_errors, uncertainty_common -------------------------------------------------


def error_rows(runs: list[Calibrated]) -> tuple[list[list], np.ndarray, np.ndarray, list[str]]:
    """A row per real run, the (runs, 6) errors of T_HE (m, rotation vector rad) and their
    reported 1-sigmas, and each such run's name."""
    rows, errors, sigmas, names = [], [], [], []
    for c in runs:
        name, r = c.run.name, c.result
        if r is None:
            rows.append([name, 'refused', '-', '-', '-', c.why[:60], '-'])
            continue
        if r.batch is None:
            rows.append([name, r.quality.label(), '-', '-', '-', '-', '-'])
            continue
        sd = r.batch.std
        err = np.r_[r.p_HE, Rotation.from_quat(r.q_HE).as_rotvec()]
        errors.append(err)
        sigmas.append(sd[1:7])
        names.append(name)
        fit = r.batch.uncertainty.scale
        sim3 = (
            sim3_scale(c.hand, c.eye.shifted(-r.time_offset_ns))
            if 'outdoors4' not in name
            else 0.0
        )
        varies = ' '.join(g.split('_')[0] for g in r.batch.uncertainty.varies) or '-'
        rows.append(
            [
                name,
                r.quality.label(),
                f'{r.time_offset_s * 1e3:.2f} +- {sd[0] * 1e3:.2f}',
                f'{np.linalg.norm(err[:3]) * 1e3:.1f} / {np.linalg.norm(sd[1:4]) * 1e3:.1f}',
                (
                    f'{np.degrees(np.linalg.norm(err[3:])):.3f} / '
                    f'{np.degrees(np.linalg.norm(sd[4:7])):.3f}'
                ),
                varies,
                f'{fit[0]:.4f} / ' + (f'{sim3:.4f}' if sim3 else '-') if fit else '-',
            ]
        )
    z = np.array(errors) / np.array(sigmas)
    for tag in ('EuRoC', 'VI-SLAM', 'TUM-VI', ''):
        rms = np.sqrt(np.mean(z[[s.startswith(tag) for s in names]] ** 2, axis=0))
        rows.append(
            [
                f'rms error / sigma, {tag or "all"} (x y z, rx ry rz)',
                '',
                '',
                ' '.join(f'{v:.2f}' for v in rms[:3]),
                ' '.join(f'{v:.2f}' for v in rms[3:]),
                '',
                '',
            ]
        )
    return rows, np.array(errors), np.array(sigmas), names


def common_rows(errors: np.ndarray, sigmas: np.ndarray, names: list[str]) -> list[list]:
    """Per set of SHARED: the error its runs have in common (their inverse-variance mean per
    axis, with its 1-sigma) and, per axis, the rms of each run's error / sigma against the
    truth I and against the other runs' common one (leave one out: e_i minus the others' mean,
    over the root of sigma_i^2 plus that mean's variance): what a run's sigma says of its own
    error once an error common to every run of the set (a reference's body frame, which one
    recording cannot see) is left aside."""
    out = []
    for label, prefixes in SHARED.items():
        k = [i for i, n in enumerate(names) if n.startswith(prefixes)]
        e, sd = errors[k], sigmas[k]
        w = 1.0 / sd**2
        mean, mean_sd = np.sum(w * e, 0) / np.sum(w, 0), 1.0 / np.sqrt(np.sum(w, 0))
        z = []
        for i in range(len(k)):
            o = np.arange(len(k)) != i
            m = np.sum(w[o] * e[o], 0) / np.sum(w[o], 0)
            z.append((e[i] - m) / np.sqrt(sd[i] ** 2 + 1.0 / np.sum(w[o], 0)))
        rms_truth = np.sqrt(np.mean((e / sd) ** 2, 0))
        rms_common = np.sqrt(np.mean(np.array(z) ** 2, 0))
        out.append(
            [
                label,
                len(k),
                ' '.join(f'{m * 1e3:+.1f}' for m in mean[:3])
                + f' (+- {np.linalg.norm(mean_sd[:3]) * 1e3:.1f})',
                ' '.join(f'{v:.2f}' for v in rms_truth[:3]),
                ' '.join(f'{v:.2f}' for v in rms_common[:3]),
                ' '.join(f'{v:.2f}' for v in rms_truth[3:]),
                ' '.join(f'{v:.2f}' for v in rms_common[3:]),
            ]
        )
    return out


# --- uncertainty_pairs, uncertainty_terms ---------------------------------------------------


def estimates(
    by_name: dict[str, CalibrationResult],
) -> dict[str, list[tuple[str, CalibrationResult]]]:
    """Per recording with two or three estimates, its estimates' (name, result): the EuRoC
    runs as calibrated above (``by_name``), outdoors4's with ``clock_drift``."""
    drift = CalibrationConfig(clock_drift=True)
    out: dict[str, list[tuple[str, CalibrationResult]]] = {
        'TUM-VI outdoors4': [
            (label, calibrate(*cases.tumvi('outdoors4', f).load(), drift))
            for label, f in OUTDOORS4.items()
        ]
    }
    for seq in EUROC:
        out[f'EuRoC {seq}'] = [
            (f'vio_{kind}', by_name[f'EuRoC {seq} {kind}']) for kind in ('mono', 'stereo')
        ]
    return out


def _z(a, b, cov_a, cov_b) -> np.ndarray:
    """|a - b| / combined sigma for (dt, x, y, z)."""
    d = np.r_[a.time_offset_s - b.time_offset_s, a.p_HE - b.p_HE]
    s = np.sqrt(np.diag(cov_a)[:4] + np.diag(cov_b)[:4])
    return np.abs(d) / s


def pair_rows(ests: dict) -> list[list]:
    rows = []
    for rec, named in ests.items():
        for (na, a), (nb, b) in itertools.combinations(named, 2):
            ua, ub = a.batch.uncertainty, b.batch.uncertainty
            before = _z(a, b, ua.long_run, ub.long_run)
            now = _z(a, b, ua.covariance, ub.covariance)
            d = (a.p_HE - b.p_HE) * 1e3
            rows.append(
                [
                    rec,
                    f'{na} / {nb}',
                    ' '.join(f'{v:+.1f}' for v in d),
                    f'{(a.time_offset_s - b.time_offset_s) * 1e3:+.2f}',
                    ' '.join(f'{v:.1f}' for v in before[1:]),
                    f'{before[0]:.1f}',
                    ' '.join(f'{v:.1f}' for v in now[1:]),
                    f'{now[0]:.1f}',
                    f'{before.max():.1f}',
                    f'{now.max():.1f}',
                ]
            )
    return rows


def term_rows(ests: dict) -> list[list]:
    rows = []
    for rec, named in ests.items():
        for name, r in named:
            u = r.batch.uncertainty
            t, dom = u.terms(), u.dominant()
            f = u.factors or {}
            rows.append(
                [
                    rec,
                    name,
                    f'{t["time_offset"]["white"] * 1e3:.2f} -> {r.batch.std[0] * 1e3:.2f}',
                    (
                        f'{t["translation"]["white"] * 1e3:.1f} -> '
                        f'{np.linalg.norm(r.batch.std[1:4]) * 1e3:.1f}'
                    ),
                    (
                        f'{np.degrees(t["rotation"]["white"]):.3f} -> '
                        f'{np.degrees(np.linalg.norm(r.batch.std[4:7])):.3f}'
                    ),
                    f'{dom["time_offset"]} / {dom["translation"]} / {dom["rotation"]}',
                    ' '.join(
                        f'{f.get(g, float("nan")):.2f}'
                        for g in ('time_offset', 'translation', 'rotation')
                    ),
                    '-' if u.scale is None else f'{u.scale[0]:.4f}',
                    r.quality.label(),
                ]
            )
    return rows


# --- rig_real_recordings, rig_real -----------------------------------------------------------


def rigs(
    by_name: dict[str, CalibrationResult], ests: dict[str, list[tuple[str, CalibrationResult]]]
) -> dict[str, list[tuple[str, CalibrationResult]]]:
    """Per rig, its recordings' (name, own result): the runs as calibrated above
    (``by_name``), TUM-VI's with ``clock_drift`` (outdoors4's from the pairs' estimates)."""
    room1 = calibrate(
        *cases.run('TUM-VI room1 orbslam').load(), CalibrationConfig(clock_drift=True)
    )
    outdoors4 = dict(ests['TUM-VI outdoors4'])['orbslam vio']
    return {
        **{
            f'EuRoC vio_{kind}': [(seq, by_name[f'EuRoC {seq} {kind}']) for seq in EUROC]
            for kind in ('mono', 'stereo')
        },
        'EuRoC VI-SLAM': [(seq, by_name[f'VI-SLAM {seq}']) for seq in cases.EUROC_GT],
        'TUM-VI ORB-SLAM3': [('room1', room1), ('outdoors4', outdoors4)],
    }


def _mm_deg(v: np.ndarray) -> tuple[float, float]:
    return float(np.linalg.norm(v[:3]) * 1e3), float(np.degrees(np.linalg.norm(v[3:])))


def rig_rows(rigs: dict[str, list[tuple[str, CalibrationResult]]]) -> tuple[list, list]:
    """A row per recording of each rig, and a row per rig."""
    rows, summary = [], []
    for name, named in rigs.items():
        owns = [Own(seq, res.to_dict(), res) for seq, res in named]
        rig = solve([summary_of(own) for own in owns])
        docs = [shared_outputs(own, rig.joint, *role(rig, own.name), None, False) for own in owns]
        quality = finish(rig, [own.name for own in owns], docs, None)['rig']['quality']
        index = {m.name: k for k, m in enumerate(rig.members)}
        for (seq, res), doc in zip(named, docs, strict=True):
            k = index[seq]  # every real recording here gives a member
            m, test = rig.members[k], rig.split.tests[k]
            sd = np.sqrt(m.extrinsic_covariance.diagonal())
            q = doc['quality']
            rows.append(
                [
                    name,
                    seq,
                    ' '.join(f'{v * 1e3:+.1f}' for v in m.p_HE),
                    *_mm_deg(difference(m.q_HE, m.p_HE, *IDENTITY)),
                    np.linalg.norm(sd[:3]) * 1e3,
                    np.degrees(np.linalg.norm(sd[3:])),
                    '-' if test is None else test.chi2,
                    'yes' if seq in rig.used else 'NO',
                    evaluate_and_write(res, res.to_dict()).quality.label(' '),
                    ' '.join([q['verdict'], *q['for_evaluation']['codes']])
                    if seq in rig.used
                    else '-',
                ]
            )
        alone = np.median(
            [np.linalg.norm(np.sqrt(m.extrinsic_covariance.diagonal()[:3])) for m in rig.members]
        )
        summary.append(
            [
                name,
                ' '.join(f'{v * 1e3:+.1f}' for v in rig.joint.p_HE),
                *_mm_deg(difference(rig.joint.q_HE, rig.joint.p_HE, *IDENTITY)),
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
    return rows, summary


def main() -> None:
    if not cases.available():
        print(f'no real data at {cases.REAL_DATA}: nothing to measure')
        return
    runs = calibrated_runs()
    emit(
        'purpose_real',
        table(
            'Every real run, default options: the verdict for each purpose (evaluation '
            'with its figures judged), the largest share of a figure that is the '
            "calibration's 1-sigma (the part that moves it most), the errors (dt ms / T_HE mm / deg) and whether the run "
            'is accurate (5 ms / 20 mm / 1 deg)',
            [
                'run',
                'for evaluation',
                'for extrinsic',
                'largest share',
                'errors',
                'accurate',
                'APE at truth / sigma (t / r)',
                'note',
            ],
            purpose_rows(runs),
        ),
    )
    rows, errors, sigmas, names = error_rows(runs)
    emit(
        'uncertainty_errors',
        table(
            'Every real run with the default options against T_HE = I: the verdict, dt '
            "and its 1-sigma, the translation's and the rotation's error / 1-sigma (norms), "
            "the groups noted to vary along the recording, and the eye's scale as the "
            "batch stage fits it beside T_HE against the VIO's own Sim(3) scale of its "
            'positions (no calibration in it; - where the MoCap has a gap of minutes)',
            [
                'run',
                'verdict',
                'dt ms',
                'translation mm',
                'rotation deg',
                'varies',
                's fit / Sim(3)',
            ],
            rows,
        ),
    )
    emit(
        'uncertainty_common',
        table(
            'The same runs by the reference they share: the error common to its runs '
            "(inverse-variance mean of T_HE's translation, mm, and its 1-sigma) and the rms "
            'of error / sigma per axis against the truth I and against the other runs of '
            'the set (leave one out)',
            [
                'set',
                'runs',
                'common error mm',
                'xyz vs I',
                'xyz vs the others',
                'rxryrz vs I',
                'rxryrz vs the others',
            ],
            common_rows(errors, sigmas, names),
        ),
    )
    by_name = {c.run.name: c.result for c in runs if c.result is not None}
    ests = estimates(by_name)
    emit(
        'uncertainty_pairs',
        table(
            'Two estimates of one recording: difference over the combined 1-sigma (x y z of '
            "T_HE's translation; dt), with the long-run covariance (before) and the reported "
            'one (now)',
            [
                'recording',
                'estimates',
                'diff mm',
                'diff ms',
                'before xyz',
                'dt',
                'now xyz',
                'dt',
                'max before',
                'max now',
            ],
            pair_rows(ests),
        ),
    )
    emit(
        'uncertainty_terms',
        table(
            'Each estimate: white -> reported 1-sigma (dt ms, translation mm, rotation deg; '
            "norms over the axes), the dominant term, the blocks' factors (dt t r) and the "
            "eye's scale",
            [
                'recording',
                'estimate',
                'dt',
                'translation',
                'rotation',
                'dominant',
                'block factors',
                'scale',
                'verdict',
            ],
            term_rows(ests),
        ),
    )
    rows, summary = rig_rows(rigs(by_name, ests))
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
