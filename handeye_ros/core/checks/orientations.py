"""How the orientations were read, checked against the motion: quaternion orders and inverted
poses (after stage 1, before stage 2). A reading other than the one given is applied with a
:class:`~.conventions.Correction`, or refused when two readings explain the data equally (as
for the other conventions, :mod:`.conventions`).

The angular-speed magnitude that stage 1 correlates is blind to the usual mistakes: for a unit
quaternion ``|w| = 2 |dq/dt|``, which any fixed permutation of the quaternion's four numbers
preserves, as does inverting the pose. A permutation such as reading ``w x y z`` as ``x y z w``
is an improper orthogonal map of R^4, ``q -> a q* b`` for fixed unit quaternions a, b: the
stream's rotations become *inverted* up to fixed frames, so its relative rotations live in the
wrong frame and AX = XB (eq. 2) has no solution. So each reading is scored by how well AX = XB
holds on the keyframe motions (eq. 6): the rotation by aligning the motions' rotation vectors
(``log R_A = R_X log R_B``), the translation by least squares on
``(R_A - I) t_X = s R_X t_B - t_A`` with the eye's scale s free (a monocular VO's is unknown
here; a wrong reading is not rescued by it, since its translations are turned by a wrong
rotation); the score adds the median residual of each, divided by the best reading's median.
Readings tried: each stream as given, with its quaternion's numbers rotated by one place either
way (a TUM file written ``w x y z``, a EuRoC one ``x y z w``, or one written ``y z w x`` through
Eigen's ``Quaterniond(x, y, z, w)``, which takes w first: each named in the order the stream was
read, :attr:`Trajectory.quaternion_order`), and inverted (T_EW given for T_WE). A reading fits
when its score is within a factor 3 of the best; wrong readings miss by a factor 10 to 1000
(their translations are rotated by the wrong, time-varying rotation).

Inverting the hand explains an inverted eye exactly (the roles of T_HE and T_WG swap), so when
both fit, the one whose extrinsic is the shorter lever arm is taken if it is at most a third
of the other and at most 1 m; otherwise the data cannot tell, and the mistake is refused with
both fixes named.

Two more readings are tried and never applied, each refused, named, when it fits best. A
stream's quaternions conjugated, its positions kept: JPL's quaternion convention (OpenVINS keeps
its state in it; Hamilton's conjugate for one rotation) or the world's rotation in the body
written beside the body's position in the world. Its rotations are inverted and fit AX = XB only
in the wrong frame, and only the conjugate explains both rotations and translations, so the
stream is named; its file must be fixed for any other tool too (evo reads Hamilton's).

And a stream's positions negated. A stream written in a left-handed frame (as Unity's), or with
one axis flipped in its positions and its quaternions converted alike (``p -> S p``,
``R -> S R S``, S a reflection), is its true trajectory with the positions negated in frames
turned by the rotation ``-S``: its rotations fit and its translations do not. Negating either
stream's positions then explains the data exactly (t_X changes sign), so which stream is
mirrored the data cannot tell, and it is refused, named.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from ..arrays import Floats, Indices
from ..association import associate
from ..errors import InputError, TimeAlignmentError
from ..geometry import matrix_from_quat, quat_from_matrix, relative
from ..linear.keyframes import motion_indices
from ..linear.refits import (
    WARN_AXIS_SPREAD_DEG,
    axis_spreads_deg,
    rotation_from_motions,
    unit_axes,
)
from ..linear.scale import translation_and_scale
from ..trajectory import Trajectory, quaternion_columns
from .conventions import Correction

#: A reading fits when its score is within this factor of the best one's.
FIT_FACTOR = 3.0
#: Fewest keyframe motions for the orientation check (fewer: the check is skipped).
MIN_MOTIONS = 10
#: Lever arm prior for the hand-or-eye inversion ambiguity (m, and a ratio).
LEVER_ARM_MAX_M = 1.0
LEVER_ARM_RATIO = 3.0


#: Readings of one stream's orientations: name -> what a correction by it is (the permutations
#: and the inverse are applied and said by :func:`in_words`; the others are refused, each by
#: its own message).
READINGS = {
    'as given': 'as given',
    'wxyz': 'quaternion_order',
    'xyzw': 'quaternion_order',
    'inverse': 'inverse',
    'mirrored': 'mirrored',
    'conjugate': 'conjugate',
}
#: Readings that are named and refused when they fit best, never applied (see the module
#: docstring).
UNAPPLIED = ('mirrored', 'conjugate')
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
    fixed = Trajectory.from_arrays(traj.t_ns, traj.p_xyz, q, traj.name)
    order = source_order(traj.quaternion_order or 'xyzw', reading)
    return replace(fixed.with_breaks(traj.breaks).with_notes(*traj.notes), quaternion_order=order)


def source_order(read: str, reading: str) -> str:
    """The order of a source's quaternion numbers (such as 'wxyz') that a permutation
    ``reading`` says, for a source read in the order ``read``."""
    where = quaternion_columns(read)  # the source's column of the x, y, z, w read
    order = [''] * 4
    for k, c in enumerate('xyzw'):
        order[where[PERMUTATIONS[reading][k]]] = c
    return ''.join(order)


def in_words(reading: str, traj: Trajectory) -> str:
    """A reading that may be applied (a permutation, the inverse) in the user's words: for a
    permutation, the source's order it says and the order it was read in (the option's
    values)."""
    if reading not in PERMUTATIONS:
        return 'its poses were the inverse (T_EW for T_WE, T_HG for T_GH)'
    read = traj.quaternion_order or 'xyzw'
    was = source_order(read, reading)
    eigen = (
        " (as Eigen's Quaterniond(x, y, z, w), whose constructor takes w first, writes them)"
        if was == 'yzwx'
        else ''
    )
    return f'its quaternion numbers were {" ".join(was)} where {" ".join(read)} was read{eigen}'


def _reread_poses(
    pose: tuple[Floats, Floats], q_xyzw: Floats, reading: str
) -> tuple[Floats, Floats]:
    """Poses (R (N, 3, 3), p (N, 3); q_xyzw: R's quaternions) under another reading than as
    given, as :func:`reread` does to a stream."""
    R, p = pose
    if reading == 'mirrored':
        return R, -p
    if reading == 'conjugate':
        return np.swapaxes(R, -1, -2), p
    if reading == 'inverse':
        Rt = np.swapaxes(R, -1, -2)
        return Rt, -np.einsum('nij,nj->ni', Rt, p)
    return matrix_from_quat(q_xyzw[:, PERMUTATIONS[reading]]), p


def _axis_spread_deg(R: Floats, i: Indices, j: Indices) -> float:
    """The spread of the rotation axes of the motions R_i^T R_j (:func:`axis_spreads_deg`).
    About one axis (a ground robot, a turntable) every reading turns the motions alike and the
    translation residuals follow the rotation about the axis that the rotations leave free:
    the check cannot tell the readings apart."""
    axes = unit_axes(Rotation.from_matrix(np.swapaxes(R[i], -1, -2) @ R[j]).as_rotvec())
    return float(axis_spreads_deg(axes, np.ones((1, len(i)), dtype=bool))[0])


@dataclass(frozen=True)
class ReadingFit:
    """How well AX = XB holds under one reading: median residuals (the translation's in the
    eye's units), the eye's scale they were fitted with (1 when none came out positive) and the
    lever arm found (m)."""

    stream: str
    reading: str
    rotation_rad: float
    translation: float
    scale: float
    lever_arm_m: float
    score: float = float('nan')

    @property
    def translation_m(self) -> float:
        """The median translation residual in metres."""
        return self.translation * self.scale


def _fit(R_A: Floats, t_A: Floats, R_B: Floats, t_B: Floats) -> tuple[float, float, float, float]:
    """Median rotation (rad) and translation residuals of AX = XB, solved apart as the linear
    stage's refit does (unweighted here), the eye's scale and |t_X| (m). The translations are
    fitted with the eye's scale free where it comes out positive (a monocular VO's is unknown
    until stage 2), else at 1: the residuals are in the eye's units either way, alike for every
    reading, which keeps the eye's positions or negates them."""
    with warnings.catch_warnings():  # one rotation axis: any fit scores alike, as it should
        warnings.simplefilter('ignore', UserWarning)
        rot, a, b = rotation_from_motions(R_A, R_B)
    res_r = np.linalg.norm(a - rot.apply(b), axis=1)
    fit = translation_and_scale(R_A, t_A, t_B, rot.as_matrix())
    scaled = bool(np.isfinite(fit.scale) and fit.scale > 0.0)
    lever = fit.p_HE if scaled else fit.p_HE_unscaled
    return (
        float(np.median(res_r)),
        fit.rms_with if scaled else fit.rms_without,
        fit.scale if scaled else 1.0,
        float(np.linalg.norm(lever)) if lever is not None else float('nan'),
    )


def reading_fits(
    hand: Trajectory, eye: Trajectory, time_offset_s: float, eta_rad: float
) -> list[ReadingFit]:
    """Scores of every reading (one stream changed at a time); empty when the motion is too
    poor to tell (too few motions, or rotation axes that spread less than
    WARN_AXIS_SPREAD_DEG)."""
    try:
        base = associate(hand, eye, time_offset_s)
    except TimeAlignmentError:
        return []
    i, j = motion_indices(base.R_GH, 'rotation', eta_rad)
    if i.size < MIN_MOTIONS or _axis_spread_deg(base.R_GH, i, j) < WARN_AXIS_SPREAD_DEG:
        return []
    fits = []
    # only the poses the motions start or end at are read (an hour of 200 Hz has 720 000
    # associated poses, its keyframe motions some 40 000 ends)
    ends = np.unique(np.concatenate((i, j)))
    i, j = np.searchsorted(ends, i), np.searchsorted(ends, j)
    poses = {'hand': (base.R_GH[ends], base.p_GH[ends]), 'eye': (base.R_WE[ends], base.p_WE[ends])}
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
    best_t = max(min(f.translation for f in fits), 1e-12)
    return [replace(f, score=f.rotation_rad / best_r + f.translation / best_t) for f in fits]


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
    as_given = next(f for f in fits if f.reading == 'as given')
    closest = min(fits, key=lambda f: f.score)
    _refuse_unapplied(closest, as_given, hand, eye)
    fitting = [f for f in fitting if f.reading not in UNAPPLIED]
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
    if len(fitting) > 1:
        named = '; or '.join(
            f'the {f.stream} stream: {in_words(f.reading, hand if f.stream == "hand" else eye)}'
            for f in fitting
        )
        msg = (
            f'the orientations do not fit AX = XB as given (median residuals '
            f'{np.degrees(as_given.rotation_rad):.1f} deg, {as_given.translation_m * 1e3:.0f} '
            f'mm), and several readings would: {named}. Say which with the options '
            '--hand-quaternion-order / --eye-quaternion-order or invert_hand / invert_eye'
        )
        raise InputError(msg)
    f = fitting[0]
    traj = hand if f.stream == 'hand' else eye
    fixed, correction = _applied(f, as_given, traj)
    if f.stream == 'hand':
        return fixed, eye, [correction]
    return hand, fixed, [correction]


def _applied(
    f: ReadingFit, as_given: ReadingFit, traj: Trajectory
) -> tuple[Trajectory, Correction]:
    """The stream ``traj`` under the reading ``f`` that alone fits, and the correction that
    names it with the option's setting that states it."""
    what = READINGS[f.reading]
    fixed = reread(traj, f.reading)
    option = f'invert_{f.stream}' if what == 'inverse' else f'{f.stream}_quaternion_order'
    setting = option if what == 'inverse' else f'{option} {fixed.quaternion_order}'
    if what != 'inverse' and traj.quaternion_order is None:
        option = ''  # none states another order for a message
        remedy = (
            'fix their source: they were not read from a file, and a pose message holds x y z '
            'w by definition (no option states another order for it)'
        )
    else:
        remedy = f'say so with {setting} (the file still holds the mistake for other tools)'
    message = (
        f'{traj.name}: {in_words(f.reading, traj)}: AX = XB holds with that reading (median '
        f'residuals {np.degrees(f.rotation_rad):.2f} deg, {f.translation_m * 1e3:.1f} mm) and '
        f'not as given ({np.degrees(as_given.rotation_rad):.1f} deg, '
        f'{as_given.translation_m * 1e3:.0f} mm), so it was applied. If that is right, {remedy}'
    )
    return fixed, Correction(f.stream, what, f.reading, option, message)


def _refuse_unapplied(
    closest: ReadingFit, as_given: ReadingFit, hand: Trajectory, eye: Trajectory
) -> None:
    """Refuse the streams when a reading that is never applied (:data:`UNAPPLIED`) fits best."""
    if closest.reading == 'mirrored':
        raise InputError(_mirrored(as_given, closest))
    if closest.reading == 'conjugate':
        name = hand.name if closest.stream == 'hand' else eye.name
        raise InputError(_conjugated(as_given, closest, name))


def _mirrored(as_given: ReadingFit, mirrored: ReadingFit) -> str:
    """The refusal of a stream whose positions are mirrored against its orientations."""
    return (
        'the positions of one stream are mirrored against its orientations (a left-handed frame, '
        "as Unity's, or one axis flipped in the positions and the quaternions alike): AX = XB "
        "holds with either stream's positions negated (median residuals "
        f'{np.degrees(mirrored.rotation_rad):.2f} deg, {mirrored.translation_m * 1e3:.1f} mm) and '
        f'not as given ({np.degrees(as_given.rotation_rad):.1f} deg, '
        f'{as_given.translation_m * 1e3:.0f} mm). Write the mirrored stream (usually the '
        "device's own, the eye) in a right-handed frame: convert its positions and quaternions "
        'together, or negate its positions'
    )


def _conjugated(as_given: ReadingFit, conjugate: ReadingFit, name: str) -> str:
    """The refusal of a stream (file ``name``) whose quaternions are the conjugates of
    Hamilton's."""
    return (
        f"{name}: the {conjugate.stream} stream's quaternions are the conjugates of Hamilton "
        "body-in-world quaternions (JPL's convention, as OpenVINS keeps its state, or the "
        "world's rotation in the body beside the body's position in the world): AX = XB holds "
        f'with them conjugated (median residuals {np.degrees(conjugate.rotation_rad):.2f} deg, '
        f'{conjugate.translation_m * 1e3:.1f} mm) and not as given '
        f'({np.degrees(as_given.rotation_rad):.1f} deg, {as_given.translation_m * 1e3:.0f} mm). '
        f'Write the {conjugate.stream} stream with Hamilton quaternions: negate qx qy qz'
    )
