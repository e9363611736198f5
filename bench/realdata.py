"""Semi-synthetic real cases from ../shared/data/real (see its SOURCES.md).

Each pair holds a EuRoC ground truth (IMU frame B in the Vicon world, the hand) and a real VIO
estimate of the same flight (IMU frame, the eye): real noise and drift, identity extrinsic and
~0 offset. To make a real MoCap-style case the hand is moved to the Vicon marker frame S with
EuRoC's published ``T_BS`` (T_GH = T_GB T_BS, so the true T_HE = T_BS^-1) and its clock is
shifted by a known amount (hand stamps - shift, so the true dt = +shift, up to the few ms by
which the original streams already differ).

Data quirks handled here, not in the package readers (which refuse them, as they should):
the rpg estimates start with an identity placeholder row, and evo's V102.txt repeats four
stamps.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from handeye_ros.core.geometry import compose, inverse, matrix_from_quat, quat_from_matrix
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.formats import read_trajectory

ROOT = Path(__file__).resolve().parents[1]
REAL_DATA = ROOT.parent / 'shared' / 'data' / 'real'

#: EuRoC vicon0 T_BS: the Vicon marker frame S in the IMU frame B (SOURCES.md).
T_BS = np.array(
    [
        [0.33638, -0.01749, 0.94156, 0.06901],
        [-0.02078, -0.99972, -0.01114, -0.02781],
        [0.94150, -0.01582, -0.33665, -0.12395],
        [0.0, 0.0, 0.0, 1.0],
    ]
)


def _nearest_rotation(M: np.ndarray) -> np.ndarray:
    U, _, Vt = np.linalg.svd(M)
    return U @ Vt


#: T_BS's rotation as published is orthonormal to ~1e-4 only: its nearest rotation, used for
#: the hand and the truth alike (scipy 1.11 and 1.17 turn the published matrix into different
#: quaternions, 1.4e-6 apart, which moved results by up to 2.5 um between the two).
_R_BS = _nearest_rotation(T_BS[:3, :3])

_EUROC = 'open_vins/ov_data/euroc_mav'
_RPG = 'rpg_trajectory_evaluation/results/euroc_mono_stereo/laptop'


@dataclass(frozen=True)
class RealPair:
    """One flight: ground truth (hand) and a VIO estimate (eye), paths under REAL_DATA."""

    name: str
    ground_truth: str
    estimate: str
    vicon_room: bool  # V1_*/V2_* (small room); False for the Machine Hall (MH_*, ~80 m paths)


def _rpg(kind: str, seq: str, gt: str) -> RealPair:
    return RealPair(
        f'{seq} {kind}',
        f'{_EUROC}/{gt}.txt',
        f'{_RPG}/vio_{kind}/laptop_vio_{kind}_{seq}/stamped_traj_estimate.txt',
        seq.startswith('V'),
    )


PAIRS = (
    # The re-generated V1_01 ground truth (20 Hz): the original one differs from it by a body
    # rotation of 5.2 deg and 43 mm (calibrating one against the other), an error of the
    # original, not of the estimate.
    RealPair(
        'V1_01 openvins', f'{_EUROC}/V1_01_easy.txt', 'evo/test/data/V101_openvins.txt', True
    ),
    RealPair('V1_02 evo', 'evo/test/data/V102_groundtruth.csv', 'evo/test/data/V102.txt', True),
    *(
        _rpg(kind, seq, gt)
        for seq, gt in (('V2_01', 'V2_01_easy'), ('V2_02', 'V2_02_medium'))
        for kind in ('mono', 'stereo')
    ),
    *(
        _rpg(kind, seq, gt)
        for seq, gt in (
            ('MH_01', 'MH_01_easy'),
            ('MH_03', 'MH_03_medium'),
            ('MH_05', 'MH_05_difficult'),
        )
        for kind in ('mono', 'stereo')
    ),
)


def available(root: Path = REAL_DATA) -> bool:
    """Whether the real data folder is present."""
    return (root / 'SOURCES.md').is_file()


def load_estimate(path: Path) -> Trajectory:
    """A VIO estimate in TUM form, without the placeholder row and repeated stamps."""
    rows = np.loadtxt(path, comments='#', ndmin=2)
    if np.allclose(rows[0, 1:], [0, 0, 0, 0, 0, 0, 1]):
        rows = rows[1:]
    # stamps like 1.403715529112143517e+09 carry ~0.2 us of float64 rounding: far below a ms
    t_ns = np.rint(rows[:, 0] * 1e9).astype(np.int64)
    keep = np.concatenate(([True], np.diff(t_ns) > 0))
    return Trajectory.from_arrays(t_ns[keep], rows[keep, 1:4], rows[keep, 4:8], str(path))


def load(pair: RealPair, root: Path = REAL_DATA) -> tuple[Trajectory, Trajectory]:
    """(ground truth, estimate) of a pair, both in the IMU frame."""
    return read_trajectory(root / pair.ground_truth), load_estimate(root / pair.estimate)


def to_marker_frame(gt: Trajectory, clock_shift_s: float) -> Trajectory:
    """The hand a MoCap would give: T_GH = T_GB T_BS, stamps moved by -clock_shift_s.

    The true calibration is then dt = clock_shift_s and T_HE = T_BS^-1.
    """
    X = (_R_BS, T_BS[:3, 3])
    R, p = compose((matrix_from_quat(gt.q_xyzw), gt.p_xyz), X)
    shift_ns = np.int64(round(clock_shift_s * 1e9))
    return Trajectory.from_arrays(
        gt.t_ns - shift_ns, p, quat_from_matrix(R), gt.name + ' (marker)'
    )


def true_extrinsic() -> tuple[np.ndarray, np.ndarray]:
    """T_HE = T_SB = T_BS^-1 as (quaternion x y z w, translation m).

    T_BS as published is orthonormal to ~1e-4 only; the quaternion of its nearest rotation is
    used.
    """
    R_SB, p_SB = inverse((_R_BS, T_BS[:3, 3]))
    return quat_from_matrix(R_SB), p_SB
