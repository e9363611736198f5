"""The part of each APE/RPE figure's uncertainty that comes from the calibration.

The calibrated ground truth ``T_WG T_GH(t - dt) T_HE`` (:mod:`.aligned`) depends on dt and T_HE,
and on the drift and the eye's scale when they were estimated: the batch stage reports their
covariance (eq. 14-16 at the solution, with the terms of :mod:`..core.batch.correlated`). Each
figure is computed again at DRAWS draws of those parameters from a normal distribution about
the estimate with that covariance, each eye segment's world T_WG fitted again at every draw as
the calibration fits it; the figure's calibration 1-sigma is the root-mean-square of the draws'
differences from it. (Not their standard deviation: near the estimate the figures are near a
minimum in the parameters, so they move one way.) The draws come in opposite pairs whose
second moment is exactly the covariance (:func:`_normal_draws`), so that the part of a
figure's change that is linear in the calibration, most of it, has its exact mean square:
independent draws would give each 1-sigma a Monte-Carlo error of about 1 / sqrt(2 DRAWS)
(12.5 %), and the largest of a result's figures' shares, which the verdict reads, a bias
upward. The draws run on the eye poses thinned to no
fewer than THINNED_PER_STEP per RPE time step (so that every RPE pair still finds its pose
within RPE_TOLERANCE of its step), and on a long recording on WINDOWS runs of consecutive
poses spread over it, MAX_POSES in all: the sigma of a root-mean-square over an hour at 200 Hz
needs no 720 000 poses. The figure's own value is taken on the same poses. The same draws
name the group of parameters that moves each figure most (:func:`moved_most_by`), which the
verdict's ``imprecise`` says with what narrows it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..core.arrays import Floats, Indices, Stamps
from ..core.association import MIN_PAIRS, pairs_at_eye
from ..core.document import ErrorKey
from ..core.geometry import compose, matrix_from_quat
from ..core.result import CalibrationResult
from ..core.time.clock import retime
from ..core.trajectory import Trajectory
from ..core.world import align_worlds, worlds_per_pair
from .aligned import AlignedTrajectories
from .metrics import POSE_ERRORS, STATS, CalibrationSigmas, PoseErrors

#: Draws of the calibration's parameters, in DRAWS / 2 opposite pairs (at least twice the
#: parameters' number, so that their second moment can be made the identity).
DRAWS = 32
#: The draws' eye poses: at least this many per RPE time step (RPE_TOLERANCE is 0.1 of it), and
#: at most MAX_POSES in WINDOWS runs of consecutive poses.
THINNED_PER_STEP = 20
MAX_POSES = 5_000
WINDOWS = 10
#: The draws' generator's seed: the same result gives the same error bars.
SEED = 0
#: A figure's change is put down to a group of parameters (:func:`moved_most_by`) when its part
#: linear in the calibration holds at least this share of its mean square.
LINEAR_SHARE = 0.5
#: Eigenvalues of a group's covariance below this fraction of its largest are a held direction
#: (its variance zero but for round-off), left out of the pseudo-inverse.
RCOND = 1e-9


def calibration_sigmas(
    result: CalibrationResult, delta_s: float, delta_m: float, draws: int = DRAWS
) -> tuple[CalibrationSigmas | None, str]:
    """The APE/RPE figures' calibration 1-sigmas (module docstring), or None and why not (no
    batch covariance: the linear result was kept, or it is not finite)."""
    batch, used = result.batch, result.used
    if used is None:
        return None, 'the result holds no poses'
    if batch is None or not np.all(np.isfinite(batch.covariance)):
        return None, 'the calibration has no covariance (its batch stage was not used)'
    cov = batch.covariance
    sample = _sample(result, delta_s, delta_m)
    drift_at, scale_at, _ = sample.model
    names = ['dt', 'T_HE']
    if drift_at is not None:
        names.append('clock drift')
    if scale_at is not None:
        names.append('eye scale')

    def figures(d: Floats) -> dict[str, dict[str, float]] | None:
        return _figures(result, sample, d)

    zero = figures(np.zeros(cov.shape[0]))
    if zero is None:
        return None, 'too few eye poses fall inside the hand recording'
    L = _factor(cov)
    z = _normal_draws(cov.shape[0], draws)
    tried = [figures(L @ zk) for zk in z]
    moved = [m for m in tried if m is not None]
    if len(moved) < draws // 2:
        return None, 'most draws of the calibration leave the hand recording'
    sigmas = {
        name: {
            stat: _rms_change(zero[name][stat], [m[name][stat] for m in moved]) for stat in STATS
        }
        for name in POSE_ERRORS
    }
    through: dict[ErrorKey, str] = {}
    if len(moved) == len(tried):  # the draws' second moment is the identity only all together
        changes = np.array([[m[k]['rmse'] - zero[k]['rmse'] for k in POSE_ERRORS] for m in moved])
        valued = np.isfinite(changes).all(axis=0)  # a figure with no value names nothing
        keys = [k for k, ok in zip(POSE_ERRORS, valued, strict=True) if ok]
        picked = moved_most_by(cov, L, z, changes[:, valued], _groups(sample.model))
        through = dict(zip(keys, picked, strict=True))
    return (
        CalibrationSigmas(sigmas, len(moved), len(sample.stamps), tuple(names), through),
        '',
    )


def _groups(model: tuple[int | None, int | None, int]) -> dict[str, Indices]:
    """The parameters' groups by their places in the covariance (reported order), named as
    the verdict's words name them (``verdict.THROUGH``)."""
    drift_at, scale_at, _ = model
    groups = {'time_offset': np.r_[0], 'translation': np.r_[1:4], 'rotation': np.r_[4:7]}
    if drift_at is not None:
        groups['clock_drift'] = np.r_[drift_at]
    if scale_at is not None:
        groups['scale'] = np.r_[scale_at]
    return groups


def moved_most_by(
    cov: Floats, L: Floats, z: Floats, changes: Floats, groups: dict[str, Indices]
) -> list[str]:
    """Per figure, the group of parameters that moves it most: the one whose exact knowledge
    would remove the most of the variance of the figure's change that is linear in the
    calibration (parameters ``L z`` drawn with covariance ``cov = L L^T``, ``z`` the draws of
    :func:`_normal_draws`, ``changes`` (draws, figures) the figures' changes at them). With
    ``f = a . d`` the draws give ``g = L^T a`` exactly as the mean of ``changes * z``, so
    ``cov a = L g`` and a group G's share of ``a^T cov a`` is ``(L g)_G^T cov_GG^+ (L g)_G``,
    correlations between the groups included. '' for a figure whose linear part is less than
    LINEAR_SHARE of its changes' mean square (a figure at a minimum in the calibration moves
    one way, by its curvature)."""
    g = z.T @ changes / len(z)
    linear = np.sum(g * g, axis=0) >= LINEAR_SHARE * np.mean(changes**2, axis=0)
    b = L @ g
    removed = np.array(
        [
            np.sum(
                b[i] * (np.linalg.pinv(cov[np.ix_(i, i)], rcond=RCOND, hermitian=True) @ b[i]), 0
            )
            for i in groups.values()
        ]
    )
    names = list(groups)
    return [names[k] if ok else '' for k, ok in zip(removed.argmax(axis=0), linear, strict=True)]


def _sample(result: CalibrationResult, delta_s: float, delta_m: float) -> _Sample:
    """What each draw of ``result`` evaluates (:class:`_Sample`), for RPE steps ``delta_s`` [s]
    and ``delta_m`` [m]: the drift's and the scale's places follow dt and T_HE's 7 in the
    covariance, when the batch stage estimated them."""
    used, batch = result.used, result.batch
    assert used is not None, 'a result with its poses'
    k = 7
    drift_at = scale_at = None
    if batch is not None and batch.clock_drift is not None:
        drift_at, k = k, k + 1
    if batch is not None and batch.scale is not None:
        scale_at = k
    keep, window = _windows(used.eye_stamps_ns, delta_s)
    stamp_ns = result.eye_model.stamp_ns if result.eye_model is not None else 0
    return _Sample(
        used.eye.select(keep),
        used.eye_stamps_ns[keep],
        window,
        (drift_at, scale_at, stamp_ns),
        (delta_s, delta_m),
    )


def figures_at(
    result: CalibrationResult,
    time_offset_s: float,
    q_HE: Floats,
    p_HE: Floats,
    delta_s: float = 1.0,
    delta_m: float = 1.0,
) -> dict[str, dict[str, float]] | None:
    """The APE/RPE figures (m, deg) at another calibration (dt [s], T_HE as x y z w and m), on
    the same poses as the error bars' draws, less those at the reported one: how far the
    figures the user reads would move were that calibration the true one. None when they cannot
    be computed."""
    d = np.zeros(7)
    d[0] = time_offset_s - result.time_offset_s
    d[1:4] = np.asarray(p_HE, float) - result.p_HE
    d[4:7] = (Rotation.from_quat(result.q_HE).inv() * Rotation.from_quat(q_HE)).as_rotvec()
    n = 7 if result.batch is None else result.batch.covariance.shape[0]
    d = np.r_[d, np.zeros(n - 7)]
    sample = _sample(result, delta_s, delta_m)
    at, here = _figures(result, sample, d), _figures(result, sample, np.zeros_like(d))
    if at is None or here is None:
        return None
    return {k: {s: at[k][s] - here[k][s] for s in at[k]} for k in at}


def _rms_change(at: float, moved: list[float]) -> float | None:
    """The root-mean-square of the draws' changes from ``at``; None for a figure that has no
    value (an RPE step longer than the recording)."""
    changes = np.array(moved) - at
    changes = changes[np.isfinite(changes)]
    return float(np.sqrt(np.mean(changes**2))) if np.isfinite(at) and changes.size else None


def _windows(t_ns: Stamps, delta_s: float) -> tuple[Indices, Indices]:
    """The eye poses (stamps ``t_ns``) the draws run on, as indices, and the run of consecutive
    poses each is in: every one of them, thinned to THINNED_PER_STEP per ``delta_s``, and when
    more than MAX_POSES are left, WINDOWS runs of them spread evenly."""
    n = t_ns.size
    period = float(t_ns[-1] - t_ns[0]) * 1e-9 / max(n - 1, 1)
    # thinned no further than the cost asks: an RPE step of minutes needs no fewer poses
    most = max(1, n // MAX_POSES)
    every = max(1, min(int(delta_s / THINNED_PER_STEP / period), most)) if period > 0.0 else 1
    thinned = np.arange(0, n, every)
    if thinned.size <= MAX_POSES:
        return thinned, np.zeros(thinned.size, dtype=int)
    length = MAX_POSES // WINDOWS
    starts = np.linspace(0, thinned.size - length, WINDOWS).astype(int)
    keep = thinned[(starts[:, None] + np.arange(length)).ravel()]
    return keep, np.repeat(np.arange(WINDOWS), length)


def _normal_draws(n: int, draws: int) -> Floats:
    """(draws, n) standard normal vectors from SEED, in opposite pairs (z, -z), transformed
    so that their mean of z z^T is exactly the identity: for a figure f(z) = g.z + z.A.z / 2
    the draws' mean of the squared change then holds g.g exactly, and the cross term g.z z.A.z
    cancels pair by pair; only the quadratic term's own spread is left to chance."""
    half = np.random.default_rng(SEED).standard_normal((max(draws, 2 * n) // 2, n))
    z = np.concatenate([half, -half])
    w, V = np.linalg.eigh(z.T @ z / len(z))
    out: Floats = z @ (V / np.sqrt(w)) @ V.T
    return out


def _factor(cov: Floats) -> Floats:
    """L with L L^T = cov, for a covariance that may be only semi-definite (a held direction):
    ``L = D R^(1/2)``, D the standard deviations and ``R^(1/2)`` the principal square root of
    the correlations ``R = D^-1 cov D^-1``. It is continuous in cov and the same in any units of
    the parameters and whatever signs and order the eigen-solver gives its vectors (an
    eigenvector factor is none of these), so that the same standard normal numbers (SEED) draw
    nearly the same calibrations, and give nearly the same error bars, for nearly the same
    covariance: two calibrations of a growing recording a second apart."""
    c = 0.5 * (cov + cov.T)
    d = np.sqrt(np.clip(np.diag(c), 0.0, None))
    free = np.flatnonzero(d > 0.0)  # a held parameter's row and column are zero: it is not drawn
    w, V = np.linalg.eigh(c[np.ix_(free, free)] / np.outer(d[free], d[free]))
    root = np.zeros_like(c)
    root[np.ix_(free, free)] = (V * np.sqrt(np.clip(w, 0.0, None))) @ V.T
    out: Floats = d[:, None] * root
    return out


@dataclass(frozen=True)
class _Sample:
    """What each draw evaluates: the eye poses (on the hand's clock) and their own stamps
    [ns], the run each is in (``window``: no RPE pair joins two); ``model``: the drift's and the
    scale's places in the reported order (None when not estimated) and the drift's reference
    stamp [ns]; ``deltas``: the RPE steps (s, m)."""

    eye: Trajectory
    stamps: Stamps
    window: Indices
    model: tuple[int | None, int | None, int]
    deltas: tuple[float, float]


def _figures(
    result: CalibrationResult, sample: _Sample, d: Floats
) -> dict[str, dict[str, float]] | None:
    """The figures with the calibration moved by ``d`` (reported order: dt, translation,
    rotation in the tangent on the right, [drift], [scale]), or None when too few eye poses
    of ``sample`` fall inside the hand recording."""
    eye, stamps, window = sample.eye, sample.stamps, sample.window
    used, (drift_at, scale_at, stamp_ns) = result.streams(), sample.model
    if drift_at is not None and d[drift_at]:
        eye = retime(eye, float(d[drift_at]), stamp_ns)
    scale = None if result.batch is None else result.batch.scale
    if scale_at is not None and scale is not None and d[scale_at]:
        eye = eye.scaled(1.0 + d[scale_at] / scale)
    q = (Rotation.from_quat(result.q_HE) * Rotation.from_rotvec(d[4:7])).as_quat()
    p = np.asarray(result.p_HE, dtype=float) + d[1:4]
    pairs, ok = pairs_at_eye(used.hand, eye, used.time_offset_s + float(d[0]))
    if pairs.segment.size < MIN_PAIRS:
        return None
    # the positions weighed against the orientations as at the reported calibration in every
    # draw (core/world.py): the draws move T_WG with the calibration, not with the weighing
    reported = (result.q_HE, result.p_HE)
    world = align_worlds(pairs, q, p, reported)
    X = (matrix_from_quat(q), p)
    R_ref, p_ref = compose(
        worlds_per_pair(pairs, q, p, world, reported), compose((pairs.R_GH, pairs.p_GH), X)
    )
    runs = pairs.segment * (int(window.max()) + 1) + window[ok]
    al = AlignedTrajectories(stamps[ok], R_ref, p_ref, pairs.R_WE, pairs.p_WE, runs, '')
    errors = PoseErrors.of(al, *sample.deltas)
    return {name: vars(getattr(errors, name)) for name in POSE_ERRORS}
