"""Screening of one pose stream before stage 1: isolated pose outliers.

Real recordings carry poses that no motion produced: an identity placeholder written before the
first estimate, a MoCap marker swap (the rigid body fitted to the wrong markers for one frame),
a MoCap dropout written as zeros, a VIO glitch. One such pose is enough to put a spike into the
angular speed of stage 1 and a wrong motion into stages 2 and 3. They are found here, on each
stream alone, and removed (and counted, with their stamps, in the result).

The test (a Hampel test on the interpolation residual): each pose is compared with
the interpolation of its two neighbours at its stamp (positions linearly, orientations by
SLERP; at the two ends, the extrapolation of the two nearest poses): the residual is exact
zero on a straight, steady motion and ``a dt^2 / 8`` on a curved one, so a pose no motion
produced stands out. Its residual is tested against the stream's own spread: a running
median ``m`` and median absolute deviation ``s`` of the residuals over about 2 s (at least
31 poses); the pose is a candidate when its residual exceeds ``m + n_sigma * 1.4826 * s``
(``outlier_threshold``, default 6: on Gaussian noise a good pose reaches this about once in
10^7) and an absolute floor: 1 mm / 0.1 deg (below which a wrong pose cannot matter to the
calibration), or what the file's own rounding can produce when it is coarser (positions
written to the millimetre move a residual by up to sqrt(3) mm). A wild pose also
lifts its neighbours' residuals (to about half its own), so a candidate is an outlier only
if it disagrees with the extrapolations from *both* sides (from its two previous and from
its two next poses, at three times the threshold: extrapolation errs more): a good pose
beside a wild one agrees with its other side, and a pose next to a step (a reset) agrees
with its own side, and both stay. The test runs again on what is left (up to five rounds),
so that wild poses in a row go one after the other. The test runs at three scales: against
the poses 1, 2 and 3 away on each side, since the inner poses of a run of identical wild
poses agree with each other at scale 1 (runs of up to five are found).

Before it, *damaged* rows are removed: rows whose position is physically absurd (beyond
:data:`ABSURD_POSITION_M`, a corrupted column as in some published DSO files, where whole
blocks of rows hold x ~ 1e9 m); :func:`describe_damage` says how many, where and what. Then
rows written exactly as the identity pose (``0 0 0`` and ``0 0 0 1``) in a stream
that is elsewhere are removed as placeholders, runs of any length: the convention of
evaluation toolboxes for "no estimate yet" and of MoCap drivers for "body lost". So are the
copies in a run of poses repeated bit for bit that ends in a jump (:func:`held_poses`): a
driver that repeats its last pose while it has lost the body, the body found again elsewhere.
A run at rest is kept: a slow rig written to the millimetre repeats its poses legitimately,
and leaves its rest by steps like the ones that follow.

Resets (a jump of the eye's world frame that persists) are not outliers and are not removed
here; they are found after stage 2 against the hand (:mod:`.breaks`), where the
motion expected of the eye is known, and split the eye stream into segments.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..arrays import Floats, Indices, Mask, Stamps
from ..chunked import chunked
from ..geometry import quat_angle, quat_slerp, row_norms
from ..trajectory import Trajectory
from .running_median import running_median

#: Span of the running median and MAD of the residuals, seconds, and its fewest poses.
SCALE_WINDOW_S = 2.0
SCALE_WINDOW_MIN = 31
#: A run of poses repeated bit for bit (at least REPEATED_MIN of them) is held by a driver
#: that lost the body when its step out is HELD_JUMP times the median of the AFTER_STEPS steps
#: that follow (:func:`held_poses`): n copies while moving end in a jump of about n steps, so
#: the shortest held run jumps by 3; a rig leaving its rest accelerates over steps like these.
REPEATED_MIN = 3
HELD_JUMP = 3.0
AFTER_STEPS = 5
#: Residuals below these never make an outlier (m, rad): 1 mm, 0.1 deg.
FLOOR_TRANSLATION_M = 1e-3
FLOOR_ROTATION_RAD = np.deg2rad(0.1)
#: An extrapolation from two poses errs more than an interpolation between them (a curved
#: motion: ``a dt^2`` against ``a dt^2 / 8`` at equal spacing, plus the noise of a lever).
EXTRAPOLATION_FACTOR = 3.0
#: Rounds of the test.
HAMPEL_ROUNDS = 5
#: Neighbour distances the test runs at: a pose against the poses 1, 2 and 3 before and after
#: it, so that a run of up to five wild poses (whose inner poses agree with each other) has a
#: scale at which it disagrees with both sides.
SCALES = (1, 2, 3)
#: The floors are at least this many times the worst residual the values' rounding can make.
ROUNDING_MARGIN = 1.5

#: A position component beyond this (m) is no pose any stream can hold: 10 000 km, beyond
#: Earth-centred coordinates (6 400 km), which a GNSS-fused estimate may use.
ABSURD_POSITION_M = 1e7

#: Kinds of removed poses, as counted in :class:`Screening`.
KINDS = ('damaged', 'placeholder', 'outlier', 'short_segment')


@dataclass(frozen=True)
class Screening:
    """What screening removed from one stream.

    Attributes
    ----------
    stream : str
        'hand' or 'eye'.
    n_input : int
        Poses before screening.
    removed_ns : ndarray of int64, shape (R,)
        Stamps (as read) of the removed poses, sorted.
    removed_kind : tuple of str
        The kind (one of :data:`KINDS`) of each removed pose, in the order of ``removed_ns``.
    threshold_translation_m, threshold_rotation_rad : float
        Median over the stream of the Hampel thresholds used (for the report).
    breaks_ns : ndarray of int64
        Stamps of the first pose after each break found later (:func:`find_eye_breaks`).
    """

    stream: str
    n_input: int
    removed_ns: Stamps
    removed_kind: tuple[str, ...]
    threshold_translation_m: float = float('nan')
    threshold_rotation_rad: float = float('nan')
    breaks_ns: Stamps = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    @property
    def counts(self) -> dict[str, int]:
        """Removed poses per kind."""
        return {k: int(sum(1 for x in self.removed_kind if x == k)) for k in KINDS}

    @property
    def n_removed(self) -> int:
        return int(self.removed_ns.size)

    @property
    def n_short(self) -> int:
        """Poses in segments between breaks too short to use: not wrong, only unusable."""
        return self.counts['short_segment']

    @property
    def n_placeholders(self) -> int:
        """Poses that say "no pose here" (the identity of a toolbox, zeros or the last pose held
        for a lost body): missing, not wrong."""
        return self.counts['placeholder']

    @property
    def n_outliers(self) -> int:
        """Poses removed as wrong (damaged rows, outliers)."""
        return self.n_removed - self.n_short - self.n_placeholders

    @property
    def fraction(self) -> float:
        """Poses removed as wrong over input poses (what ``max_outlier_fraction`` bounds);
        poses in short segments between breaks and placeholders are missing, not wrong, and
        are not counted."""
        return self.n_outliers / max(self.n_input, 1)

    @property
    def short_fraction(self) -> float:
        """Poses in segments too short to use over input poses."""
        return self.n_short / max(self.n_input, 1)

    def merged(self, removed_ns: Stamps, kind: str, breaks_ns: Stamps | None = None) -> Screening:
        """This report with more removed poses (all of one kind) and breaks."""
        ns = np.concatenate((self.removed_ns, np.asarray(removed_ns, dtype=np.int64)))
        kinds = self.removed_kind + (kind,) * int(np.size(removed_ns))
        order = np.argsort(ns, kind='stable')
        br = self.breaks_ns if breaks_ns is None else np.union1d(self.breaks_ns, breaks_ns)
        return Screening(
            self.stream,
            self.n_input,
            ns[order],
            tuple(kinds[i] for i in order),
            self.threshold_translation_m,
            self.threshold_rotation_rad,
            br.astype(np.int64),
        )


def resolution(values: Floats) -> float:
    """The step the values were rounded to: 10^-k for the fewest decimals k (0..9) that
    represent them all (within 1e-3 of a step); 0 when they carry more than 9 decimals."""
    v = np.asarray(values, dtype=float).ravel()
    v = v[np.isfinite(v)][:20_000]
    for k in range(10):
        scaled = v * 10.0**k
        if np.all(np.abs(scaled - np.rint(scaled)) < 1e-3):
            return 10.0**-k
    return 0.0


def _predict(
    t: Floats, p: Floats, q: Floats, a: Indices, b: Indices, k: Indices
) -> tuple[Floats, Floats]:
    """Residuals (m, rad) of poses k against the line through poses a and b at t_k
    (interpolation when a < k < b, extrapolation otherwise; q: x y z w quaternions)."""
    return chunked(lambda s: _predict_rows(t, p, q, a[s], b[s], k[s]), k.size)


def _predict_rows(
    t: Floats,
    p: Floats,
    q: Floats,
    a: Indices | slice,
    b: Indices | slice,
    k: Indices | slice,
) -> tuple[Floats, Floats]:
    """:func:`_predict` on the rows a, b, k (index arrays, or slices: views of a long stream)
    of the stamps (s), positions (m) and x y z w quaternions."""
    ta, tb, tk = t[a], t[b], t[k]
    f = (tk - ta) / np.where(tb != ta, tb - ta, 1.0)
    p_pred = p[a] + f[:, None] * (p[b] - p[a])
    return row_norms(p[k] - p_pred), quat_angle(quat_slerp(q[a], q[b], f), q[k])


def interpolation_residuals(t: Floats, p: Floats, q: Floats, d: int = 1) -> tuple[Floats, Floats]:
    """(N,) position (m) and rotation (rad) residual of each pose against the interpolation of
    the poses ``d`` before and after it (near the ends: the extrapolation of the two on the
    side that exists)."""
    n = t.size
    if n <= 4 * d:
        return _end_residuals(t, p, q, np.arange(n), d)
    # the inner poses by slices of the arrays (views: a stream of millions of poses is not
    # gathered three times), a chunk at a time; the 2d poses at the ends by index
    e_p, e_r = np.empty(n), np.empty(n)

    def inner(s: slice) -> tuple[Floats, Floats]:
        a, k, b = (
            slice(s.start, s.stop),
            slice(s.start + d, s.stop + d),
            slice(s.start + 2 * d, s.stop + 2 * d),
        )
        return _predict_rows(t, p, q, a, b, k)

    e_p[d : n - d], e_r[d : n - d] = chunked(inner, n - 2 * d)
    ends = np.concatenate((np.arange(d), np.arange(n - d, n)))
    e_p[ends], e_r[ends] = _end_residuals(t, p, q, ends, d)
    return e_p, e_r


def _end_residuals(t: Floats, p: Floats, q: Floats, k: Indices, d: int) -> tuple[Floats, Floats]:
    """:func:`interpolation_residuals` of the poses k, each against its neighbours d away, or
    near an end the extrapolation of the two on the side that exists."""
    n = t.size
    a, b = k - d, k + d
    left_end, right_end = a < 0, b > n - 1
    a = np.where(left_end, k + d, np.where(right_end, k - 2 * d, a))
    b = np.where(left_end, k + 2 * d, np.where(right_end, k - d, b))
    a, b = np.clip(a, 0, n - 1), np.clip(b, 0, n - 1)
    return _predict(t, p, q, a, b, k)


def side_residuals(
    t: Floats, p: Floats, q: Floats, k: Indices, side: int, d: int = 1
) -> tuple[Floats, Floats, Mask]:
    """Residuals of poses k against the extrapolation from the poses d and 2d before (side -1)
    or after (side +1) them, and whether that side exists."""
    n = t.size
    a = k + side * d
    b = k + 2 * side * d
    ok = (b >= 0) & (b < n)
    a, b = np.clip(a, 0, n - 1), np.clip(b, 0, n - 1)
    e_p, e_r = _predict(t, p, q, a, b, k)
    return e_p, e_r, ok


def hampel_thresholds(res: Floats, scale_window: int, n_sigma: float, floor: float) -> Floats:
    """Per-pose threshold ``max(m + n_sigma * 1.4826 * s, floor)`` from the running median m
    and median absolute deviation s of the residuals. A window of more than MEDIAN_SAMPLES
    residuals (a stream faster than 200 Hz) takes them from every k-th residual, k =
    window // MEDIAN_SAMPLES, and each residual the value at its nearest one."""
    size = min(scale_window, 2 * (res.size // 2) - 1)
    k = max(1, size // MEDIAN_SAMPLES)
    if k == 1:
        return _hampel(res, size, n_sigma, floor)
    sub = _hampel(res[::k], (size // k) | 1, n_sigma, floor)
    # residual i takes sub[(i + k // 2) // k], the last one past the end
    near = np.repeat(sub, k)[k // 2 : k // 2 + res.size]
    return np.concatenate((near, np.full(res.size - near.size, sub[-1])))


#: The running median and MAD of the screening take at most about this many residuals: the
#: thresholds from 401 of 2001 (2 s of 1 kHz MoCap) are within 10 % of those from all (1st
#: and 99th percentiles, Gaussian residuals), which moves a 6-sigma threshold by less than a
#: sigma; at every residual, the rank filters over an hour of 1 kHz cost 2.1 s of its 25 s.
MEDIAN_SAMPLES = 401


def _hampel(res: Floats, size: int, n_sigma: float, floor: float) -> Floats:
    # mirror, not nearest: repeating an end value would let a wild end pose set its own scale
    size = min(size, 2 * (res.size // 2) - 1)
    m = running_median(res, size)
    s = running_median(np.abs(res - m), size)
    limit: Floats = np.maximum(m + n_sigma * 1.4826 * s, floor)
    return limit


def _outliers(
    t: Floats,
    p: Floats,
    q: Floats,
    n_sigma: float,
    floors: tuple[float, float],
    d: int,
) -> tuple[Mask, float, float]:
    """(N,) bool outliers of one round at scale d, and the median thresholds (m, rad)."""
    rate = 1.0 / max(float(np.median(np.diff(t))), 1e-9)
    scale_window = int(max(SCALE_WINDOW_MIN, min(2001, SCALE_WINDOW_S * rate))) | 1
    bad = np.zeros(t.size, dtype=bool)
    e_p, e_r = interpolation_residuals(t, p, q, d)
    tp = hampel_thresholds(e_p, scale_window, n_sigma, floors[0])
    tr = hampel_thresholds(e_r, scale_window, n_sigma, floors[1])
    cand = np.flatnonzero(np.maximum(e_p / tp, e_r / tr) > 1.0)
    if cand.size:
        inconsistent = np.ones(cand.size, dtype=bool)
        for side in (-1, 1):
            sp, sr, ok = side_residuals(t, p, q, cand, side, d)
            off = (sp > EXTRAPOLATION_FACTOR * tp[cand]) | (sr > EXTRAPOLATION_FACTOR * tr[cand])
            inconsistent &= off | ~ok
        bad[cand[inconsistent]] = True
    return bad, float(np.median(tp)), float(np.median(tr))


def placeholders(traj: Trajectory, floors: tuple[float, float]) -> Mask:
    """(N,) bool: rows written exactly as the identity pose (``0 0 0`` and ``0 0 0 1``: the
    placeholder of evaluation toolboxes, the dropout of MoCap drivers) while the nearest other
    rows are elsewhere (by more than the floors)."""
    p, q = traj.p_xyz, traj.q_xyzw
    exact = (p[:, 0] == 0.0) & (p[:, 1] == 0.0) & (p[:, 2] == 0.0)
    exact &= (q[:, 0] == 0.0) & (q[:, 1] == 0.0) & (q[:, 2] == 0.0)
    if not exact.any() or exact.all():
        return np.zeros(len(traj), dtype=bool)
    others = np.flatnonzero(~exact)
    k = np.flatnonzero(exact)
    j = np.clip(np.searchsorted(others, k), 0, others.size - 1)  # the next other row
    i = np.clip(j - 1, 0, others.size - 1)  # the previous one
    out = np.zeros(len(traj), dtype=bool)
    for nb in (others[i], others[j]):
        far = (np.linalg.norm(traj.p_xyz[nb], axis=1) > floors[0]) | (
            2.0 * np.arccos(np.clip(np.abs(traj.q_xyzw[nb, 3]), 0.0, 1.0)) > floors[1]
        )
        out[k[far]] = True
    return out


def held_poses(traj: Trajectory, floors: tuple[float, float]) -> Mask:
    """(N,) bool: the copies (all but the first) in each run of REPEATED_MIN or more
    consecutive poses repeated bit for bit whose step out, to the next pose, is a jump: beyond
    the floors (m, rad) and HELD_JUMP times the median of the AFTER_STEPS steps that follow,
    in position or in rotation. A run at rest leaves it by steps like the next ones."""
    p, q = traj.p_xyz, traj.q_xyzw
    same = np.all(p[1:] == p[:-1], axis=1) & np.all(q[1:] == q[:-1], axis=1)
    edges = np.diff(np.concatenate(([0], same.astype(np.int8), [0])))
    first, last = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    out = np.zeros(len(traj), dtype=bool)
    for f, k in zip(first, last, strict=True):
        if k - f + 1 < REPEATED_MIN or k + 2 >= len(traj):
            continue
        nxt = slice(k + 1, min(len(traj), k + 2 + AFTER_STEPS))
        step_p = row_norms(np.diff(p[nxt], axis=0))
        step_r = quat_angle(q[nxt][:-1], q[nxt][1:])
        jump_p = float(np.linalg.norm(p[k + 1] - p[k]))
        jump_r = float(quat_angle(q[k], q[k + 1]))
        if (jump_p > floors[0] and jump_p > HELD_JUMP * float(np.median(step_p))) or (
            jump_r > floors[1] and jump_r > HELD_JUMP * float(np.median(step_r))
        ):
            out[f + 1 : k + 1] = True
    return out


def damaged(traj: Trajectory) -> Mask:
    """(N,) bool: rows with a physically absurd position (:data:`ABSURD_POSITION_M`)."""
    a = np.abs(traj.p_xyz)  # column by column: a max over rows of three is slow in numpy
    wrecked: Mask = np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2]) > ABSURD_POSITION_M
    return wrecked


def describe_damage(traj: Trajectory, bad: Mask) -> str:
    """How many rows are damaged, in how many blocks, where and what (for a message)."""
    k = np.flatnonzero(bad)
    edges = np.diff(np.concatenate(([0], bad.astype(np.int8), [0])))
    blocks = int(np.sum(edges == 1))
    cols = ', '.join(
        c
        for c, far in zip(
            'xyz', np.abs(traj.p_xyz[k]).max(axis=0) > ABSURD_POSITION_M, strict=True
        )
        if far
    )
    t = traj.seconds(int(traj.t_ns[0]))
    return (
        f'{traj.name}: {k.size} of {len(traj)} rows ({k.size / len(traj):.0%}) are damaged, '
        f'in {blocks} block(s) from {t[k[0]]:.1f} s to {t[k[-1]]:.1f} s: their '
        f'{cols} positions reach {np.abs(traj.p_xyz[k]).max():.3g} m (no pose stream holds values '
        f'beyond {ABSURD_POSITION_M:.0e} m; first at pose {int(k[0])}: '
        f'{np.round(traj.p_xyz[k[0]], 4).tolist()}): a corrupted column, not a motion'
    )


def screen(traj: Trajectory, stream: str, n_sigma: float = 6.0) -> tuple[Trajectory, Screening]:
    """Remove isolated outliers from one stream (see module docstring).

    Returns the screened trajectory (breaks and notes kept) and what was removed.
    """
    n_input = len(traj)
    kinds = np.zeros(n_input, dtype=np.int8)  # 1 + the index in KINDS of a removed pose
    idx = np.arange(n_input)
    # a residual the file's rounding can make is no outlier: positions rounded to r move it
    # by up to sqrt(3) r; quaternion components rounded to r turn a pose by up to ~2 r
    floors = (
        max(FLOOR_TRANSLATION_M, ROUNDING_MARGIN * np.sqrt(3.0) * resolution(traj.p_xyz)),
        max(FLOOR_ROTATION_RAD, ROUNDING_MARGIN * 4.0 * resolution(traj.q_xyzw)),
    )
    thr_p = thr_r = float('nan')
    t = traj.seconds(int(traj.t_ns[0]))
    wrecked = damaged(traj)
    kinds[wrecked] = 1 + KINDS.index('damaged')
    missing = (placeholders(traj, floors) | held_poses(traj, floors)) & ~wrecked
    kinds[missing] = 1 + KINDS.index('placeholder')
    idx = idx[~(missing | wrecked)]
    # scale 1 until nothing more is found (isolated poses), then the larger scales (runs), so
    # that isolated wild poses no longer spoil the wider extrapolations of good ones; keyframes
    # seconds apart are no smooth motion to interpolate (find_eye_breaks judges them)
    for d in () if traj.keyframes else SCALES:
        for _ in range(HAMPEL_ROUNDS):
            if idx.size < 4 * d + 4:
                break
            sel = slice(None) if idx.size == n_input else idx  # a clean stream is not copied
            bad, tp, tr = _outliers(t[sel], traj.p_xyz[sel], traj.q_xyzw[sel], n_sigma, floors, d)
            if d == 1 and np.isnan(thr_p):
                thr_p, thr_r = tp, tr
            if not bad.any():
                break
            kinds[idx[bad]] = 1 + KINDS.index('outlier')
            idx = idx[~bad]
    removed = kinds != 0
    report = Screening(
        stream,
        n_input,
        traj.t_ns[removed].copy(),
        tuple(KINDS[k - 1] for k in kinds[removed]),
        thr_p,
        thr_r,
    )
    return (traj.select(~removed) if removed.any() else traj), report
