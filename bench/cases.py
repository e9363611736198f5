"""The cases the benchmarks draw from, one registry: simulated recordings with known truth and
the real runs of ../shared/data/real (its SOURCES.md).

Simulated (handeye_ros.core.simulate): :func:`recording` at a noise level of the paper
(``noise_level``: 0-10), :func:`protocol` the paper's protocol (hand 100 Hz, eye 20 Hz, 60 s,
every (level, k) its own seed: :func:`protocol_seed`).

Real, all in the IMU frame unless moved (:data:`RUNS`, looked up by :func:`run`):

- ``EuRoC <seq> <estimator>``: EuRoC ground truths (IMU frame B in the Vicon world) against
  published VIO estimates of the same flights (:data:`PAIRS`): truth T_HE = I, dt ~ 0.
  :func:`to_marker_frame` makes a MoCap-style case of one: the hand moved to the Vicon marker
  frame S with EuRoC's published ``T_BS`` (T_GH = T_GB T_BS, so the true T_HE = T_BS^-1,
  :func:`true_extrinsic`) and its clock shifted by a known amount (hand stamps - shift, so the
  true dt = +shift, up to the few ms by which the original streams already differ).
- ``VI-SLAM MH_0k``: the real-time VI-SLAM runs (loop closures): the eye's clock one camera
  frame (50 ms) ahead of the ground truth's (:attr:`RealRun.reference_s`).
- ``TUM-VI <seq> <estimator>``: TUM-VI room1 and outdoors4, Basalt and ORB-SLAM3 VIO.

Data quirks handled here, not in the package readers (which refuse them, as they should): the
rpg estimates start with an identity placeholder row, and evo's V102.txt repeats four stamps.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from handeye_ros.core.geometry import compose, inverse, matrix_from_quat, quat_from_matrix
from handeye_ros.core.simulate import Recording, Truth, noise_level, simulate
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.formats import read_trajectory

ROOT = Path(__file__).resolve().parents[1]
REAL_DATA = ROOT.parent / 'shared' / 'data' / 'real'


# --- simulated ----------------------------------------------------------------------------


def recording(seed: int, level: float, **kw: object) -> Recording:
    """A simulated recording at one of the paper's noise levels (other ``simulate`` keywords
    as given)."""
    nm, nd = noise_level(level)
    return simulate(seed, noise_m=nm, noise_deg=nd, **kw)  # type: ignore[arg-type]


def protocol_seed(level: float, k: int) -> int:
    """Seed of the k-th recording at a noise level of the paper protocol: every (level, k) is
    its own draw (the same seed at every level would make the levels' errors correlated)."""
    return int(1000 * level) + k


#: How the seeds were chosen, for a benchmark's provenance line.
PROTOCOL_SEEDS = 'simulator seed 1000 x level + k, k = 0..seeds-1'


def protocol(level: float, k: int, **kw: object) -> Recording:
    """The k-th recording of the paper's protocol at a noise level (hand 100 Hz, eye 20 Hz,
    60 s unless ``kw`` says otherwise)."""
    return recording(protocol_seed(level, k), level, **kw)


# --- real -----------------------------------------------------------------------------------

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
#: quaternions, 1.4e-6 apart, which would move results by up to 2.5 um between the two).
_R_BS = _nearest_rotation(T_BS[:3, :3])

_EUROC = 'open_vins/ov_data/euroc_mav'
_RPG = 'rpg_trajectory_evaluation/results/euroc_mono_stereo/laptop'
_VISLAM = 'rpg_trajectory_evaluation/results/euroc_vislam_mono/laptop/vislam_rp'
#: TUM-VI's ground truths (``<seq>_GT.tum``) and estimates (``<estimator>-<seq>-<kind>.*``).
TUMVI = REAL_DATA / 'VSLAM-comparison' / 'Trajectory-files' / 'tum-vi'
_TUMVI = 'VSLAM-comparison/Trajectory-files/tum-vi'


@dataclass(frozen=True)
class RealPair:
    """One EuRoC flight: ground truth (hand) and a VIO estimate (eye), paths under REAL_DATA."""

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

#: EuRoC's Machine Hall ground truths by sequence.
EUROC_GT = {
    'MH_01': 'MH_01_easy',
    'MH_02': 'MH_02_easy',
    'MH_03': 'MH_03_medium',
    'MH_04': 'MH_04_difficult',
    'MH_05': 'MH_05_difficult',
}


@dataclass(frozen=True)
class RealRun:
    """One real run: a reference (hand) and an estimate (eye), paths under REAL_DATA, both in
    the IMU frame (truth T_HE = I); the truth's dt is ``reference_s``. ``quirks``: the estimate
    is read by :func:`load_estimate` (a placeholder row, repeated stamps)."""

    name: str
    hand: str
    eye: str
    reference_s: float = 0.0
    quirks: bool = False

    def load(self, root: Path = REAL_DATA) -> tuple[Trajectory, Trajectory]:
        """(hand, eye)."""
        read_eye = load_estimate if self.quirks else read_trajectory
        return read_trajectory(root / self.hand), read_eye(root / self.eye)


def euroc(pair: RealPair) -> RealRun:
    """A EuRoC pair as a real run, both in the IMU frame."""
    return RealRun(f'EuRoC {pair.name}', pair.ground_truth, pair.estimate, quirks=True)


def tumvi(seq: str, estimate: str) -> RealRun:
    """A TUM-VI estimate (a file name of :data:`TUMVI`) against its sequence's ground truth."""
    return RealRun(
        f'TUM-VI {seq} {estimate.split("-")[0]}', f'{_TUMVI}/{seq}_GT.tum', f'{_TUMVI}/{estimate}'
    )


#: Every real run with its own reference, in the order the tables list them.
RUNS = (
    *(euroc(p) for p in PAIRS),
    *(
        RealRun(
            f'VI-SLAM {seq}',
            f'{_EUROC}/{gt}.txt',
            f'{_VISLAM}/laptop_vislam_rp_{seq}/stamped_traj_estimate0.txt',
            0.05,
        )
        for seq, gt in EUROC_GT.items()
    ),
    tumvi('room1', 'basalt-room1-vio.tum'),
    tumvi('room1', 'orbslam-room1-vio.tum'),
    tumvi('outdoors4', 'basalt-outdoors4-vio.txt'),
    tumvi('outdoors4', 'orbslam-outdoors4-vio.tum'),
)


def run(name: str) -> RealRun:
    """The real run of that name (a KeyError naming those there are otherwise)."""
    for r in RUNS:
        if r.name == name:
            return r
    raise KeyError(f'no real run {name!r}; there are {[r.name for r in RUNS]}')


def tumvi_estimates() -> list[RealRun]:
    """Every TUM-VI estimate in the data (VIO and VO, as published), against its sequence's
    ground truth."""
    return [
        tumvi('room1' if '-room1-' in p.name else 'outdoors4', p.name)
        for p in sorted(TUMVI.glob('*-*-*.*'))
    ]


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
    """(ground truth, estimate) of a EuRoC pair, both in the IMU frame."""
    return euroc(pair).load(root)


def pair(name: str) -> RealPair:
    """The EuRoC pair of that name (``'V2_01 mono'``; a KeyError naming those there are
    otherwise)."""
    for p in PAIRS:
        if p.name == name:
            return p
    raise KeyError(f'no EuRoC pair {name!r}; there are {[p.name for p in PAIRS]}')


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


#: The clock shift (s) of the marker-frame cases (:func:`marker_case`).
SHIFT_S = 0.0873


def marker_case(pair: RealPair, shift_s: float = SHIFT_S) -> tuple[Trajectory, Trajectory, Truth]:
    """A EuRoC pair as a MoCap would give it: (the hand in the marker frame on a clock
    ``shift_s`` behind, the estimate, the truth: dt = shift_s, T_HE = T_BS^-1)."""
    gt, est = load(pair)
    q, p = true_extrinsic()
    return to_marker_frame(gt, shift_s), est, Truth(shift_s, q, p, q, p)


def true_extrinsic() -> tuple[np.ndarray, np.ndarray]:
    """T_HE = T_SB = T_BS^-1 as (quaternion x y z w, translation m) of the marker-frame case."""
    R_SB, p_SB = inverse((_R_BS, T_BS[:3, 3]))
    return quat_from_matrix(R_SB), p_SB
