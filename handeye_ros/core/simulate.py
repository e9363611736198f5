"""Simulated recordings with known truth, following the paper's protocol (Section IV-A).

A smooth random motion (cubic B-splines of position and rotation vector) is sampled as the hand
``T_GH`` at ``hand_rate_hz`` (paper: 100 Hz) on the hand clock and as the eye
``T_WE(t) = T_WG T_GH(t - dt) T_HE`` at ``eye_rate_hz`` (paper: 20 Hz) on the eye clock. The eye
gets a frame-wise cumulative error, as a VIO drifts: every relative motion between consecutive
eye frames is perturbed in the body frame by a rotation and a translation drawn with per-axis
standard deviations ``noise_deg`` and ``noise_m``, and the poses are the running product.
:func:`noise_level` gives the paper's ten levels (0.5 mm / 0.02 deg per level, up to 5 mm /
0.2 deg).

``motion`` shapes the hand's path for the degenerate and hard cases users meet (see
:data:`MOTIONS`): a ground robot (``planar``: rotation about the world z axis only, translation
in the x-y plane), a turntable or pan unit (``one_axis``: rotation about one fixed axis, no
translation), a periodic back-and-forth (``repetitive``: the same 2 s pattern over and over,
whose angular speed repeats exactly), a programmed loop (``loops``: a 3-minute lap flown
again and again, each lap a little off the first), a slow hand (``slow``: ~3 deg/s, a tenth of the
default, turning through large angles nonetheless), and a rig turned about all axes without
moving through space (``in_place``: the marker stays put; a monocular scale is unobservable),
and a recording that starts poor and becomes rich (``planar_start``: planar for its first
third, then about every axis, as a person who first only turns the device about one axis).

Real recordings also come incomplete, which :func:`keyframes_only`, :func:`with_dropouts` and
:func:`two_windows` make of a simulated one: an eye that keeps only keyframes at irregular
stamps, a MoCap with occlusions, a MoCap that covers only the start and the end.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import BSpline
from scipy.spatial.transform import Rotation

from .arrays import Floats, Stamps
from .errors import InputError
from .geometry import Pose, compose, inverse, quat_from_matrix
from .time.clock import linear_clock
from .trajectory import Trajectory

#: Hand clock origin of simulated stamps: a realistic epoch, so that the int64 ns handling
#: of stamps is exercised as with real recordings.
EPOCH_NS = 1_700_000_000_000_000_000
#: The most poses, hand and eye together, one simulated recording holds: an hour at 1 kHz +
#: 200 Hz, the longest recording bench/runtime.py calibrates (within 2 GB). A longer one is
#: refused before any array is made, where it would run out of memory.
MAX_POSES = 4_320_000
#: The paper's noise levels (:func:`noise_level`).
MAX_LEVEL = 10.0


@dataclass(frozen=True)
class Truth:
    """The values a calibration should recover (conventions of the package docstring)."""

    time_offset_s: float
    q_HE: Floats
    p_HE: Floats
    q_WG: Floats
    p_WG: Floats
    clock_drift: float = 0.0
    time_offset_stamp_ns: int = 0
    scale: float = 1.0

    def time_offset_at(self, t_eye_ns: Stamps) -> Floats:
        """The true dt(t) [s] at eye stamps [ns] (the linear clock of :mod:`.time.clock`)."""
        return linear_clock(
            self.time_offset_s, self.clock_drift, self.time_offset_stamp_ns, t_eye_ns
        )


@dataclass(frozen=True)
class Recording:
    """A simulated hand/eye recording and its truth."""

    hand: Trajectory
    eye: Trajectory
    truth: Truth


@dataclass(frozen=True)
class CalibrationError:
    """How far an estimate is from the truth: |dt error| (s), translation (m), rotation (deg)."""

    time_offset_s: float
    translation_m: float
    rotation_deg: float


def calibration_error(
    truth: Truth, time_offset_s: float, q_HE: Floats, p_HE: Floats
) -> CalibrationError:
    """Errors of an estimated (dt, T_HE) against the truth (rotation: geodesic angle)."""
    rot = Rotation.from_quat(q_HE).inv() * Rotation.from_quat(truth.q_HE)
    return CalibrationError(
        time_offset_s=abs(time_offset_s - truth.time_offset_s),
        translation_m=float(np.linalg.norm(np.asarray(p_HE) - truth.p_HE)),
        rotation_deg=float(np.degrees(rot.magnitude())),
    )


def noise_level(level: float) -> tuple[float, float]:
    """Per-frame eye noise (metres, degrees) of the paper's level 0..10 (InputError for any
    other)."""
    if not 0.0 <= level <= MAX_LEVEL:
        raise InputError(f"the noise level is one of the paper's, 0-{MAX_LEVEL:g}, not {level}")
    return 0.0005 * level, 0.02 * level


def random_truth(rng: np.random.Generator, max_time_offset_s: float = 0.1) -> Truth:
    """A random extrinsic (~0.1 m lever arm), world alignment and time offset."""
    return Truth(
        time_offset_s=float(rng.uniform(-max_time_offset_s, max_time_offset_s)),
        q_HE=Rotation.random(random_state=rng).as_quat(),
        p_HE=rng.normal(0.0, 0.1, 3),
        q_WG=Rotation.random(random_state=rng).as_quat(),
        p_WG=rng.normal(0.0, 1.0, 3),
    )


#: Hand motion shapes of :func:`simulate` (see the module docstring).
MOTIONS = (
    'random',
    'planar',
    'one_axis',
    'repetitive',
    'loops',
    'slow',
    'in_place',
    'planar_start',
)
#: Period of the ``repetitive`` motion, seconds.
REPETITIVE_PERIOD_S = 2.0
#: Period of the ``loops`` motion (s), and how much each lap departs from the first (a
#: fraction of the motion's own spread).
LOOP_PERIOD_S = 180.0
LOOP_VARIATION = 0.1


def smooth_motion(
    rng: np.random.Generator,
    duration_s: float,
    knot_spacing_s: float = 0.5,
    position_std_m: float = 0.2,
    rotation_std_rad: float = 0.2,
    motion: str = 'random',
) -> tuple[BSpline, BSpline]:
    """Cubic B-splines (seconds -> position [m], rotation vector [rad]) of a hand-held motion.

    The defaults give mean speeds of ~0.5 m/s and ~30 deg/s about all axes: between the EuRoC
    flights (10-36 deg/s) and the hand-held TUM-VI room sequence (~80 deg/s). ``motion``: one of
    :data:`MOTIONS`.
    """
    if motion not in MOTIONS:
        msg = f'motion must be one of {", ".join(MOTIONS)}, got {motion!r}'
        raise ValueError(msg)
    k = 3
    n_ctrl = int(np.ceil(duration_s / knot_spacing_s)) + k + 2
    knots = (np.arange(n_ctrl + k + 1) - k) * knot_spacing_s - knot_spacing_s
    pos_ctrl: Floats = rng.normal(0.0, position_std_m, (n_ctrl, 3))
    rot_ctrl: Floats = rng.normal(0.0, rotation_std_rad, (n_ctrl, 3))
    if motion == 'planar_start':
        # the first third planar (yaw only, in the x-y plane), the rest about every axis,
        # continuing from where the planar part left off
        k0 = n_ctrl // 3
        pos_ctrl[:k0, 2] = 0.0
        yaw = np.cumsum(rng.normal(0.0, 2.0 * rotation_std_rad, k0))
        rot_ctrl[:k0] = 0.0
        rot_ctrl[:k0, 2] = yaw
        rot_ctrl[k0:, 2] += yaw[-1]
    elif motion == 'planar':
        pos_ctrl[:, 2] = 0.0
        # yaw only, but with a larger swing: a ground robot turns through whole circles
        rot_ctrl = np.zeros((n_ctrl, 3))
        rot_ctrl[:, 2] = np.cumsum(rng.normal(0.0, 2.0 * rotation_std_rad, n_ctrl))
    elif motion == 'one_axis':
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        pos_ctrl = np.zeros((n_ctrl, 3))
        rot_ctrl = np.cumsum(rng.normal(0.0, 2.0 * rotation_std_rad, n_ctrl))[:, None] * axis
    elif motion == 'repetitive':
        # one period of random control points, tiled: the spline repeats exactly
        per = round(REPETITIVE_PERIOD_S / knot_spacing_s)
        pos_ctrl, rot_ctrl = _laps(pos_ctrl, per), _laps(rot_ctrl, per)
    elif motion == 'loops':
        # one lap of random control points flown again and again, each lap a little off the
        # first (a drone's or a robot arm's programmed loop)
        per = round(LOOP_PERIOD_S / knot_spacing_s)
        off = LOOP_VARIATION * rng.normal(0.0, 1.0, (2, n_ctrl, 3))
        pos_ctrl = _laps(pos_ctrl, per) + position_std_m * off[0]
        rot_ctrl = _laps(rot_ctrl, per) + rotation_std_rad * off[1]
    elif motion == 'in_place':
        pos_ctrl = np.zeros((n_ctrl, 3))
    elif motion == 'slow':
        # a slow drift of the orientation (~3 deg/s) rather than a small swing: the rig does
        # turn through large angles, only slowly
        rot_ctrl = np.cumsum(rng.normal(0.0, 0.1 * rotation_std_rad, (n_ctrl, 3)), axis=0)
        pos_ctrl *= 0.3
    return BSpline(knots, pos_ctrl, k), BSpline(knots, rot_ctrl, k)


def _laps(ctrl: Floats, per: int) -> Floats:
    """The first ``per`` control points (rows) repeated to the length of ``ctrl``."""
    return np.tile(ctrl[:per], (int(np.ceil(len(ctrl) / per)), 1))[: len(ctrl)]


def cumulative_compose(R: Floats, p: Floats) -> Pose:
    """Prefix products ``T_0 T_1 ... T_k`` of a pose stack, by a parallel scan (log2 N passes)."""
    R, p = R.copy(), p.copy()
    s = 1
    while s < R.shape[0]:
        R_new, p_new = compose((R[:-s], p[:-s]), (R[s:], p[s:]))
        R[s:], p[s:] = R_new, p_new
        s *= 2
    return R, p


def _with_white_noise(
    rng: np.random.Generator, poses: Pose, noise_m: float, noise_deg: float
) -> Pose:
    """The poses with white noise of these standard deviations per axis (a MoCap's), the
    rotation's on the right (body frame); unchanged (and no draw) without noise."""
    R, p = poses
    if not (noise_m or noise_deg):
        return R, p
    n = len(p)
    R = np.matmul(
        R, Rotation.from_rotvec(rng.normal(0.0, np.deg2rad(noise_deg), (n, 3))).as_matrix()
    )
    return R, p + rng.normal(0.0, noise_m, (n, 3))


def _check(
    seed: int, duration_s: float, rates_hz: tuple[float, float], noise: tuple[float, ...]
) -> None:
    """InputError, saying which, for a simulation :func:`simulate` cannot make: a seed below 0,
    a rate that is not a positive number, a noise below 0, a duration too short for three eye
    poses or so long that the recording would hold more than MAX_POSES."""
    hand_hz, eye_hz = rates_hz
    if not (isinstance(seed, (int, np.integer)) and seed >= 0):
        raise InputError(f'the seed is an integer >= 0, not {seed}')
    if not all(np.isfinite(r) and r > 0.0 for r in rates_hz):
        raise InputError(f'the pose rates are positive numbers of Hz, not {hand_hz} and {eye_hz}')
    if not all(np.isfinite(n) and n >= 0.0 for n in noise):
        raise InputError(f'the noise amounts are numbers >= 0, not {", ".join(map(str, noise))}')
    if not (np.isfinite(duration_s) and (duration_s - 2.0) * eye_hz >= 2.0):
        raise InputError(
            f'a simulated recording of {duration_s} s holds no eye poses: the eye covers the '
            'span less 1 s at each end, so it needs at least 2 s plus two eye periods (three '
            'eye poses)'
        )
    if duration_s * (hand_hz + eye_hz) > MAX_POSES:
        raise InputError(
            f'a simulated recording of {duration_s:g} s at {hand_hz:g} + {eye_hz:g} Hz would '
            f'hold {duration_s * (hand_hz + eye_hz):.3g} poses, more than the {MAX_POSES:,} of '
            'an hour at 1 kHz + 200 Hz that a calibration is measured on: simulate less'
        )


def _eye_stamps(seed: int, duration_s: float, eye_rate_hz: float, dt_ns: int) -> Stamps:
    """The eye's stamps (int64 ns, its clock): the hand's span less 1 s at each end, shifted by
    dt, its first frame at an arbitrary phase of its period, as two free-running sensors are
    (drawn apart, so that a seed's other draws do not change)."""
    n_eye = int((duration_s - 2.0) * eye_rate_hz) + 1
    phase_ns = int(np.random.default_rng([seed, 1]).integers(0, int(1e9 / eye_rate_hz)))
    out: Stamps = (
        EPOCH_NS
        + 1_000_000_000
        + dt_ns
        + phase_ns
        + np.rint(np.arange(n_eye) * 1e9 / eye_rate_hz).astype(np.int64)
    )
    return out


def simulate(
    seed: int = 0,
    *,
    duration_s: float = 60.0,
    hand_rate_hz: float = 100.0,
    eye_rate_hz: float = 20.0,
    noise_m: float = 0.0,
    noise_deg: float = 0.0,
    hand_noise_m: float = 0.0,
    hand_noise_deg: float = 0.0,
    truth: Truth | None = None,
    motion: str = 'random',
    clock_drift: float = 0.0,
    scale: float = 1.0,
    wander_s: float = 0.0,
) -> Recording:
    """Simulate one recording.

    The eye stream covers the hand stream's span less 1 s at each end, so that every eye pose
    has hand poses around it whatever the offset (|dt| < 1 s, ends included). ``hand_noise_*``
    adds white MoCap noise (the paper's protocol has none). ``motion``: one of :data:`MOTIONS`.
    ``clock_drift`` [s/s]: the eye's clock runs at (1 + clock_drift) times the hand's, with
    ``time_offset`` the offset at the eye's middle stamp (``truth.time_offset_stamp_ns``).
    ``scale``: the eye's positions are metric / scale (a monocular VO; what a calibration should
    find). ``wander_s`` [s]: the offset wanders about ``time_offset`` by this rms (:func:`_wander`).
    """
    noise = (noise_m, noise_deg, hand_noise_m, hand_noise_deg)
    _check(seed, duration_s, (hand_rate_hz, eye_rate_hz), noise)
    rng = np.random.default_rng(seed)
    truth = truth if truth is not None else random_truth(rng)
    pos, rot = smooth_motion(rng, duration_s + 2.0, motion=motion)

    def hand_pose(t_s: Floats) -> Pose:
        return Rotation.from_rotvec(rot(t_s)).as_matrix(), pos(t_s)

    n_hand = int(duration_s * hand_rate_hz) + 1
    t_hand_ns = EPOCH_NS + np.rint(np.arange(n_hand) * 1e9 / hand_rate_hz).astype(np.int64)
    R_GH, p_GH = _with_white_noise(
        rng, hand_pose((t_hand_ns - EPOCH_NS) * 1e-9), hand_noise_m, hand_noise_deg
    )

    dt_ns = round(truth.time_offset_s * 1e9)
    t_eye_ns = _eye_stamps(seed, duration_s, eye_rate_hz, dt_ns)
    X = (Rotation.from_quat(truth.q_HE).as_matrix(), truth.p_HE)
    T_WG = (Rotation.from_quat(truth.q_WG).as_matrix(), truth.p_WG)
    mid_ns = int(t_eye_ns[t_eye_ns.size // 2])
    # hand time of each eye stamp: t - dt(t), dt(t) = dt + drift (t - mid) + wander(t)
    t_at_hand = (t_eye_ns - dt_ns - EPOCH_NS) * 1e-9 - clock_drift * (t_eye_ns - mid_ns) * 1e-9
    t_at_hand -= _wander(rng, (t_eye_ns - t_eye_ns[0]) * 1e-9, wander_s)
    R_WE, p_WE = compose(compose(T_WG, hand_pose(t_at_hand)), X)
    if noise_m or noise_deg:
        R_WE, p_WE = _add_cumulative_error(rng, R_WE, p_WE, noise_m, noise_deg)
    p_WE = p_WE / scale
    truth = replace(truth, clock_drift=clock_drift, time_offset_stamp_ns=mid_ns, scale=scale)
    hand = Trajectory.from_arrays(t_hand_ns, p_GH, quat_from_matrix(R_GH), 'simulated hand')
    eye = Trajectory.from_arrays(t_eye_ns, p_WE, quat_from_matrix(R_WE), 'simulated eye')
    return Recording(hand, eye, truth)


def _wander(rng: np.random.Generator, t_s: Floats, rms_s: float) -> Floats:
    """(N,) [s] a smooth wander at the eye's times ``t_s`` [s] (a VIO's latency that changes
    with its load): three sinusoids of random phases and of periods between a quarter of the
    span and all of it, of zero mean over ``t_s`` (so that the time offset is its mean) and
    root-mean-square ``rms_s``; zeros (no draw from ``rng``) when that is 0."""
    if not rms_s:
        return np.zeros(t_s.size)
    span = float(t_s[-1] - t_s[0]) or 1.0
    periods = rng.uniform(0.25, 1.0, 3) * span
    phases = rng.uniform(0.0, 2.0 * np.pi, 3)
    w = np.sin(2.0 * np.pi * t_s[:, None] / periods + phases).sum(axis=1)
    w -= w.mean()
    out: Floats = rms_s * w / np.sqrt(np.mean(w**2))
    return out


def _add_cumulative_error(
    rng: np.random.Generator, R: Floats, p: Floats, noise_m: float, noise_deg: float
) -> Pose:
    """Perturb every consecutive relative motion in its body frame and re-chain the poses."""
    n = R.shape[0]
    rel = compose(inverse((R[:-1], p[:-1])), (R[1:], p[1:]))
    err = (
        Rotation.from_rotvec(rng.normal(0.0, np.deg2rad(noise_deg), (n - 1, 3))).as_matrix(),
        rng.normal(0.0, noise_m, (n - 1, 3)),
    )
    rel = compose(rel, err)
    steps_R = np.concatenate((R[:1], rel[0]))
    steps_p = np.concatenate((p[:1], rel[1]))
    return cumulative_compose(steps_R, steps_p)


def keyframes_only(
    eye: Trajectory, rng: np.random.Generator, rate_hz: tuple[float, float] = (0.3, 3.0)
) -> Trajectory:
    """The eye's poses a SLAM system that writes keyframes only would keep: each next one at an
    interval drawn uniformly between 1 / rate_hz[1] and 1 / rate_hz[0] seconds."""
    t = eye.seconds(int(eye.t_ns[0]))
    keep, due = [], 0.0
    for k, tk in enumerate(t):
        if tk >= due:
            keep.append(k)
            due = tk + rng.uniform(1.0 / rate_hz[1], 1.0 / rate_hz[0])
    return eye.select(np.array(keep))


def with_dropouts(
    hand: Trajectory,
    rng: np.random.Generator,
    fraction: float,
    length_s: tuple[float, float] = (0.2, 5.0),
) -> Trajectory:
    """The hand with occlusions: gaps of uniform length in ``length_s`` at random places until
    ``fraction`` of its span is gone."""
    t = hand.seconds(int(hand.t_ns[0]))
    gone = np.zeros(t.size, bool)
    while gone.mean() < fraction:
        length = rng.uniform(*length_s)
        start = rng.uniform(t[0], t[-1] - length)
        gone |= (t >= start) & (t < start + length)
    return hand.select(~gone)


def two_windows(hand: Trajectory, window_s: float) -> Trajectory:
    """The hand during its first and last ``window_s`` seconds only (a MoCap room left and
    re-entered)."""
    t = hand.seconds(int(hand.t_ns[0]))
    return hand.select((t <= window_s) | (t >= t[-1] - window_s))
