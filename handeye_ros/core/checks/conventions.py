"""Conventions checked, not assumed: stamp units, clock epochs, and how orientations were read.

Each check compares readings of the data and keeps the one that a physical motion explains; a
reading other than the one given is either applied, with a :class:`Correction` that names what
was assumed and the option that says so explicitly (the verdict is then not ``good``: the files
still hold the mistake, and other tools will read them wrong), or, when two readings explain
the data equally, refused with a message naming both.

**Stamp units** (before stage 1). A pose stream runs at 0.5 Hz to 10 kHz. Stamps in
milliseconds read as seconds make a 20 Hz stream look like 0.02 Hz; microseconds written where
nanoseconds belong make a 200 Hz MoCap look like 200 kHz. Every reading of each stream scaled by
a power of 1000 is tried; a reading is plausible when both rates are, and the two streams then
cover spans within a factor 100 of each other (a unit mistake is a factor 1000). The stamps as
given are kept whenever they are plausible.

**Clock epochs.** Stamps above 1e8 s (1973) are read as an absolute epoch (Unix, GPS), stamps
below 1e7 s (116 days) as time since boot or since the recording started. Streams on different
epochs are legitimate (two clocks are why this tool exists); stage 1 searches every lag the
recordings allow, so the offset is found either way; the epochs are named in a warning.

**Orientations** (after stage 1, before stage 2). The angular-speed magnitude that stage 1
correlates is blind to the usual mistakes: for a unit quaternion ``|w| = 2 |dq/dt|``, which any
fixed permutation of the quaternion's four numbers preserves, as does inverting the pose. A
permutation such as reading ``w x y z`` as ``x y z w`` is an improper orthogonal map of R^4,
``q -> a q* b`` for fixed unit quaternions a, b: the stream's rotations become *inverted* up to
fixed frames, so its relative rotations live in the wrong frame and AX = XB (eq. 2) has no
solution. So each reading is scored by how well AX = XB holds on the keyframe motions (eq. 6):
the rotation by aligning the motions' rotation vectors (``log R_A = R_X log R_B``), the
translation by least squares on ``(R_A - I) t_X = R_X t_B - t_A``; the score adds the median
residual of each, divided by the best reading's median. Readings tried: each stream as given,
with its quaternion's numbers rotated either way (``w x y z`` read as ``x y z w``, or the
reverse), and inverted (T_EW given for T_WE). A reading fits when its score is within a factor
3 of the best; wrong readings miss by a factor 10 to 1000 (their translations are rotated by the
wrong, time-varying rotation).

Inverting the hand explains an inverted eye exactly (the roles of T_HE and T_WG swap), so when
both fit, the one whose extrinsic is the shorter lever arm is taken if it is at most a third
of the other and at most 1 m; otherwise the data cannot tell, and the mistake is refused with
both fixes named.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np
from scipy.spatial.transform import Rotation

from ..association import associate
from ..errors import InputError, TimeAlignmentError
from ..geometry import matrix_from_quat, quat_from_matrix, relative
from ..linear.keyframes import motion_indices
from ..linear.refits import rotation_from_motions, translation_from_motions
from ..trajectory import Trajectory

#: Rates a pose stream can have, Hz (a keyframe-only estimate down to one pose in 10 s).
PLAUSIBLE_RATE_HZ = (0.1, 10_000.0)
#: Two streams of one recording cover spans within this factor of each other (a MoCap may run
#: longer than the VIO; a unit mistake is a factor 1000).
SPAN_RATIO_MAX = 100.0
#: Scale factors tried on the stamps (true = as given * factor), with the unit they imply.
UNIT_FACTORS = {
    1e-9: 'nanoseconds (where seconds were expected)',
    1e-6: 'microseconds (where seconds were expected)',
    1e-3: 'milliseconds (where seconds were expected)',
    1.0: None,
    1e3: 'microseconds (where nanoseconds were expected)',
    1e6: 'milliseconds (where nanoseconds were expected)',
    1e9: 'seconds (where nanoseconds were expected)',
}
#: Stamps above this (s) are an absolute epoch; below EPOCH_RELATIVE_S, time since boot.
EPOCH_ABSOLUTE_S = 1e8
EPOCH_RELATIVE_S = 1e7
#: A reading fits when its score is within this factor of the best one's.
FIT_FACTOR = 3.0
#: Fewest keyframe motions for the orientation check (fewer: the check is skipped).
MIN_MOTIONS = 10
#: Lever arm prior for the hand-or-eye inversion ambiguity (m, and a ratio).
LEVER_ARM_MAX_M = 1.0
LEVER_ARM_RATIO = 3.0
INT64_MAX = np.iinfo(np.int64).max


@dataclass(frozen=True)
class Correction:
    """A convention the data contradicted, and the reading that was applied instead.

    stream: 'hand' or 'eye'; what: 'stamp_unit', 'quaternion_order' or 'inverse'; assumed: the
    reading applied, in words; option: the option that states it explicitly; message: a
    warning for the user.
    """

    stream: str
    what: str
    assumed: str
    option: str
    message: str


# --------------------------------------------------------------------------------- stamps


def _scaled(traj: Trajectory, factor: float) -> Trajectory:
    """Stamps multiplied by a power of 1000 (exact integer arithmetic)."""
    if factor == 1.0:
        return traj
    if factor > 1.0:
        k = round(factor)
        if max(abs(int(traj.t_ns[0])), abs(int(traj.t_ns[-1]))) > INT64_MAX // k:
            raise OverflowError  # checked first: int64 products wrap silently
        t_ns = traj.t_ns * np.int64(k)
    else:
        k = round(1.0 / factor)
        t_ns = traj.t_ns // np.int64(k)
    if np.any(np.diff(t_ns) <= 0):  # a scale that merges stamps is no reading
        raise OverflowError
    return Trajectory(t_ns, traj.p_xyz, traj.q_xyzw, traj.name, traj.breaks, traj.notes)


def _plausible_rate(traj: Trajectory, factor: float) -> bool:
    rate = traj.rate_hz / factor
    return PLAUSIBLE_RATE_HZ[0] <= rate <= PLAUSIBLE_RATE_HZ[1]


def check_stamp_units(
    hand: Trajectory, eye: Trajectory
) -> tuple[Trajectory, Trajectory, list[Correction]]:
    """Both streams with plausible stamp units (see the module docstring). A unit stated to
    the reader is already applied; one that makes a plausible reading is kept.

    Raises
    ------
    InputError
        When no reading is plausible, or two are equally so.
    """
    options = [[f for f in UNIT_FACTORS if _plausible_rate(traj, f)] for traj in (hand, eye)]
    spans = (hand.duration_s, eye.duration_s)

    def compatible(fh: float, fe: float) -> bool:
        a, b = spans[0] * fh, spans[1] * fe
        return min(a, b) > 0 and max(a, b) / min(a, b) <= SPAN_RATIO_MAX

    readings = [(fh, fe) for fh in options[0] for fe in options[1] if compatible(fh, fe)]
    if (1.0, 1.0) in readings:
        return hand, eye, []
    if not readings:
        if (1.0 in options[0]) and (1.0 in options[1]):
            return hand, eye, []  # plausible rates, unusual spans: nothing better to offer
        msg = (
            'no reading of the stamps gives both streams a plausible rate (0.5 Hz to 10 kHz): '
            f'{hand.name} at {hand.rate_hz:.4g} Hz over {hand.duration_s:.4g} s, {eye.name} '
            f'at {eye.rate_hz:.4g} Hz over {eye.duration_s:.4g} s as read. Check the stamp '
            'units (set --hand-stamp-unit / --eye-stamp-unit)'
        )
        raise InputError(msg)
    # fewest changed streams first; among equals, the closest spans
    readings.sort(
        key=lambda r: (
            (r[0] != 1.0) + (r[1] != 1.0),
            abs(np.log10(spans[0] * r[0] / (spans[1] * r[1]))),
        )
    )
    best = readings[0]
    rivals = [
        r
        for r in readings[1:]
        if (r[0] != 1.0) + (r[1] != 1.0) == (best[0] != 1.0) + (best[1] != 1.0)
    ]
    if rivals:
        msg = (
            'the stamps of one stream are in an unexpected unit, and the data do not say '
            f'which: {hand.name} at {hand.rate_hz:.4g} Hz over {hand.duration_s:.4g} s, '
            f'{eye.name} at {eye.rate_hz:.4g} Hz over {eye.duration_s:.4g} s as read. Set '
            '--hand-stamp-unit / --eye-stamp-unit'
        )
        raise InputError(msg)
    out, corrections = [hand, eye], []
    for k, (stream, factor) in enumerate(zip(('hand', 'eye'), best, strict=True)):
        if factor == 1.0:
            continue
        traj = out[k]
        try:
            out[k] = _scaled(traj, factor)
        except OverflowError:
            msg = (
                f'{traj.name}: the stamps look like {UNIT_FACTORS[factor]} but cannot be '
                f'converted; set --{stream}-stamp-unit'
            )
            raise InputError(msg) from None
        unit = UNIT_FACTORS[factor]
        corrections.append(
            Correction(
                stream,
                'stamp_unit',
                unit,
                f'{stream}_stamp_unit',
                f'{traj.name}: the stamps were taken as {unit}: as given they make a '
                f'{traj.rate_hz:.4g} Hz stream over {traj.duration_s:.4g} s, as {unit} a '
                f'{out[k].rate_hz:.4g} Hz stream over {out[k].duration_s:.4g} s like the other '
                f'stream. If that is right, say so with --{stream}-stamp-unit (the file still '
                'holds the mistake for other tools)',
            )
        )
    return out[0], out[1], corrections


def epoch_note(hand: Trajectory, eye: Trajectory) -> str | None:
    """A warning when the two streams' stamps are on different clock epochs, else None."""

    def kind(t_ns: int) -> str | None:
        s = t_ns * 1e-9
        if s > EPOCH_ABSOLUTE_S:
            day = datetime.fromtimestamp(s, tz=UTC).strftime('%Y-%m-%d')
            return f'an absolute epoch (as Unix time: {day})'
        if 0 <= s < EPOCH_RELATIVE_S:
            return f'time since boot or since the start ({s:.1f} s)'
        return None

    kh, ke = kind(int(hand.t_ns[0])), kind(int(eye.t_ns[0]))
    if kh is None or ke is None or kh.split(' (')[0] == ke.split(' (')[0]:
        return None
    return (
        f'the streams are on different clock epochs: {hand.name} starts at {kh}, '
        f'{eye.name} at {ke}; the time offset includes the epoch difference'
    )


# --------------------------------------------------------------------------------- orientations

#: Readings of one stream's orientations: name -> (what, how the user would say it).
READINGS = {
    'as given': None,
    'wxyz': ('quaternion_order', 'its quaternion numbers were w x y z where x y z w was read'),
    'xyzw': ('quaternion_order', 'its quaternion numbers were x y z w where w x y z was read'),
    'inverse': ('inverse', 'its poses were the inverse (T_EW for T_WE, T_HG for T_GH)'),
}
#: The permutations that undo each quaternion misreading (rows of the read x y z w).
PERMUTATIONS = {'wxyz': [1, 2, 3, 0], 'xyzw': [3, 0, 1, 2]}


def reread(traj: Trajectory, reading: str) -> Trajectory:
    """The trajectory under another reading of its orientations (see :data:`READINGS`)."""
    if reading == 'as given':
        return traj
    if reading == 'inverse':
        r = Rotation.from_quat(traj.q_xyzw).inv()
        return (
            Trajectory.from_arrays(traj.t_ns, -r.apply(traj.p_xyz), r.as_quat(), traj.name)
            .with_breaks(traj.breaks)
            .with_notes(*traj.notes)
        )
    q = traj.q_xyzw[:, PERMUTATIONS[reading]]
    return (
        Trajectory.from_arrays(traj.t_ns, traj.p_xyz, q, traj.name)
        .with_breaks(traj.breaks)
        .with_notes(*traj.notes)
    )


def _reread_poses(
    pose: tuple[np.ndarray, np.ndarray], q_xyzw: np.ndarray, reading: str
) -> tuple[np.ndarray, np.ndarray]:
    """Poses (R (N, 3, 3), p (N, 3); q_xyzw: R's quaternions) under another reading than as
    given, as :func:`reread` does to a stream."""
    R, p = pose
    if reading == 'inverse':
        Rt = np.swapaxes(R, -1, -2)
        return Rt, -np.einsum('nij,nj->ni', Rt, p)
    return matrix_from_quat(q_xyzw[:, PERMUTATIONS[reading]]), p


@dataclass(frozen=True)
class ReadingFit:
    """How well AX = XB holds under one reading: median residuals and the lever arm found."""

    stream: str
    reading: str
    rotation_rad: float
    translation_m: float
    lever_arm_m: float
    score: float = float('nan')


def _fit(
    R_A: np.ndarray, t_A: np.ndarray, R_B: np.ndarray, t_B: np.ndarray
) -> tuple[float, float, float]:
    """Median rotation (rad) and translation (m) residuals of AX = XB, solved apart as the
    linear stage's refit does (unweighted here), and |t_X|."""
    with warnings.catch_warnings():  # one rotation axis: any fit scores alike, as it should
        warnings.simplefilter('ignore', UserWarning)
        rot, a, b = rotation_from_motions(R_A, R_B)
    res_r = np.linalg.norm(a - rot.apply(b), axis=1)
    t_X, res_t = translation_from_motions(R_A, t_A, t_B, rot.as_matrix())
    return (
        float(np.median(res_r)),
        float(np.median(np.linalg.norm(res_t, axis=1))),
        float(np.linalg.norm(t_X)),
    )


def reading_fits(
    hand: Trajectory, eye: Trajectory, time_offset_s: float, eta_rad: float
) -> list[ReadingFit]:
    """Scores of every reading (one stream changed at a time); empty when the motion is too
    poor to tell."""
    try:
        base = associate(hand, eye, time_offset_s)
    except TimeAlignmentError:
        return []
    i, j = motion_indices(base.R_GH, 'rotation', eta_rad)
    if i.size < MIN_MOTIONS:
        return []
    fits = []
    poses = {'hand': (base.R_GH, base.p_GH), 'eye': (base.R_WE, base.p_WE)}
    given = {name: relative(pose, i, j) for name, pose in poses.items()}
    for stream in ('hand', 'eye'):
        q = quat_from_matrix(poses[stream][0])
        for reading in READINGS:
            if stream == 'hand' and reading == 'as given':
                continue  # the same as the eye as given
            # each reading applied to the associated poses rather than to the streams: slerp
            # commutes with a permutation or conjugation of the quaternion's numbers (both
            # keep dot products), so only the inverse's interpolated positions differ, at
            # second order in the sampling interval (an hour of 1 kHz MoCap is not re-read)
            moved = (
                given[stream]
                if reading == 'as given'
                else relative(_reread_poses(poses[stream], q, reading), i, j)
            )
            A = moved if stream == 'hand' else given['hand']
            B = moved if stream == 'eye' else given['eye']
            fits.append(
                ReadingFit(
                    stream if reading != 'as given' else 'both',
                    reading,
                    *_fit(A[0], A[1], B[0], B[1]),
                )
            )
    best_r = max(min(f.rotation_rad for f in fits), 1e-12)
    best_t = max(min(f.translation_m for f in fits), 1e-12)
    return [
        ReadingFit(
            f.stream,
            f.reading,
            f.rotation_rad,
            f.translation_m,
            f.lever_arm_m,
            f.rotation_rad / best_r + f.translation_m / best_t,
        )
        for f in fits
    ]


def check_orientations(
    hand: Trajectory, eye: Trajectory, time_offset_s: float, eta_rad: float
) -> tuple[Trajectory, Trajectory, list[Correction]]:
    """Both streams under the reading of their orientations that AX = XB explains (see the
    module docstring).

    Raises
    ------
    InputError
        When the streams as given do not fit and two other readings fit equally.
    """
    fits = reading_fits(hand, eye, time_offset_s, eta_rad)
    if not fits:
        return hand, eye, []
    best = min(f.score for f in fits)
    fitting = [f for f in fits if f.score <= FIT_FACTOR * best]
    if any(f.reading == 'as given' for f in fitting):
        return hand, eye, []
    if len(fitting) == 2 and {(f.stream, f.reading) for f in fitting} == {
        ('hand', 'inverse'),
        ('eye', 'inverse'),
    }:
        short, long = sorted(fitting, key=lambda f: f.lever_arm_m)
        if (
            short.lever_arm_m <= LEVER_ARM_MAX_M
            and short.lever_arm_m * LEVER_ARM_RATIO <= long.lever_arm_m
        ):
            fitting = [short]
    as_given = next(f for f in fits if f.reading == 'as given')
    if len(fitting) > 1:
        named = '; or '.join(f'the {f.stream} stream: {READINGS[f.reading][1]}' for f in fitting)
        msg = (
            f'the orientations do not fit AX = XB as given (median residuals '
            f'{np.degrees(as_given.rotation_rad):.1f} deg, {as_given.translation_m * 1e3:.0f} '
            f'mm), and several readings would: {named}. Say which with the options '
            '--hand-quaternion-order / --eye-quaternion-order or invert_hand / invert_eye'
        )
        raise InputError(msg)
    f = fitting[0]
    what, words = READINGS[f.reading]
    option = ('invert_' + f.stream) if what == 'inverse' else f'{f.stream}_quaternion_order'
    traj = hand if f.stream == 'hand' else eye
    fixed = reread(traj, f.reading)
    message = (
        f'{traj.name}: {words}: AX = XB holds with that reading (median residuals '
        f'{np.degrees(f.rotation_rad):.2f} deg, {f.translation_m * 1e3:.1f} mm) and not '
        f'as given ({np.degrees(as_given.rotation_rad):.1f} deg, '
        f'{as_given.translation_m * 1e3:.0f} mm), so it was applied. If that is right, '
        f'say so with {option} (the file still holds the mistake for other tools)'
    )
    correction = Correction(f.stream, what, f.reading, option, message)
    if f.stream == 'hand':
        return fixed, eye, [correction]
    return hand, fixed, [correction]
