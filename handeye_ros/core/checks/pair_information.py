"""What consecutive eye pairs say about (dt, T_HE), gathered in chunks that can be added up.

The readiness predicts the batch stage's white covariance (eq. 15-16) from the relative-pose
residuals of consecutive eye pairs (i, i + 1) against the hand interpolated at their stamps less
dt. One :class:`Chunk` holds, for the pairs of one span of the recording, linearised at one
estimate (dt, R_HE, p_HE): the normal equations J^T J and J^T r of the rotation rows and of the
translation rows apart (so that the noise weights can change after they are summed), and the
histogram of the residuals' magnitudes (so that the robust noise level can be taken from chunks
already summed). Chunks add up; so the information of a recording that keeps growing costs the
new pairs only, and the chunks of poses a buffer has dropped can be taken out again.

Parameters, as the Jacobian is ordered: dt [s], p_HE in H [m], the rotation R_HE Exp(d) with d
in E [rad].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import Floats, Indices, Mask
from ..association import interpolate, residual_motions
from ..chunked import CHUNK_ROWS
from ..geometry import Pose, exp_so3, log_so3, matrix_from_quat, relative
from ..trajectory import Trajectory

#: The histogram of residual magnitudes: log10 edges from LOG_LO to LOG_HI in LOG_STEP. A
#: twentieth of a decade is a 12 % bin; the median is interpolated inside its bin.
LOG_LO, LOG_HI, LOG_STEP = -12.0, 2.0, 0.05
NBINS = round((LOG_HI - LOG_LO) / LOG_STEP)
#: Residuals beyond this many robust sigmas are left out, as Huber's loss nearly does.
OUTLIER_SIGMAS = 5.0


@dataclass(frozen=True)
class Estimate:
    """The point the chunks are linearised at: dt [s], R_HE (3, 3), p_HE [m] in H."""

    time_offset_s: float
    R_HE: Floats
    p_HE: Floats


@dataclass(frozen=True)
class Chunk:
    """The pairs of one span: eye stamps [t0_ns, t1_ns] (their first start and last end),
    how many, the time they span [s], and their normal equations (rotation rows, translation
    rows): ``info`` (2, 7, 7) J^T J and ``grad`` (2, 7) J^T r, unweighted, of the pairs within
    OUTLIER_SIGMAS; ``hist`` (2, NBINS) the residual components' magnitudes (rad, m). Pairs
    used one in k count k times (``scale``)."""

    t0_ns: int
    t1_ns: int
    pairs: int
    span_s: float
    info: Floats
    grad: Floats
    hist: Indices

    def __add__(self, other: Chunk) -> Chunk:
        return Chunk(
            min(self.t0_ns, other.t0_ns),
            max(self.t1_ns, other.t1_ns),
            self.pairs + other.pairs,
            self.span_s + other.span_s,
            self.info + other.info,
            self.grad + other.grad,
            self.hist + other.hist,
        )


def histogram(r: Floats) -> Indices:
    """(NBINS,) counts of |r| (every component) on the log10 bins."""
    with np.errstate(divide='ignore'):
        k = np.floor((np.log10(np.abs(r).ravel()) - LOG_LO) / LOG_STEP)
    return np.bincount(
        np.clip(np.nan_to_num(k, neginf=0), 0, NBINS - 1).astype(int), minlength=NBINS
    )


def robust_sigma(hist: Indices) -> float:
    """A robust standard deviation (1.4826 times the median magnitude, about 0) from a
    histogram of magnitudes, the median interpolated in log inside its bin; floored."""
    n = float(hist.sum())
    if n == 0:
        return float('nan')
    cum = np.cumsum(hist)
    k = int(np.searchsorted(cum, n / 2.0))
    below = cum[k - 1] if k else 0.0
    frac = (n / 2.0 - below) / max(float(hist[k]), 1.0)
    median = 10.0 ** (LOG_LO + (k + frac) * LOG_STEP)
    return float(max(1.4826 * median, 1e-9))


def pairs_of(eye: Trajectory, start_ns: int, stop_ns: int) -> Indices:
    """The eye's usable pairs (index of their first pose) that start at or after ``start_ns``
    and end at or before ``stop_ns``."""
    i = np.flatnonzero(eye.interval_ok())
    inside: Indices = i[(eye.t_ns[i] >= start_ns) & (eye.t_ns[i + 1] <= stop_ns)]
    return inside


def residuals(hand: Trajectory, eye: Trajectory, i: Indices, est: Estimate) -> tuple[Floats, Mask]:
    """(n, 6) residuals (Log of the rotation [rad], translation [m]) of the eye pairs ``i``
    at ``est`` (eq. 16, in the eye frame), and which pairs the hand covers."""
    A, ok = _hand_motions(hand, eye, i, est.time_offset_s)
    out = np.full((i.size, 6), np.nan)
    out[ok] = _residuals(_select(A, ok), _eye_motions(eye, i[ok]), (est.R_HE, est.p_HE))
    return out, ok


def chunks(
    hand: Trajectory,
    eye: Trajectory,
    i: Indices,
    est: Estimate,
    h: float,
    sigma: tuple[float, float],
    scale: float = 1.0,
    piece_s: float | None = None,
) -> list[Chunk]:
    """The chunks of the eye pairs ``i`` (those the hand covers at dt and dt +- h), at ``est``,
    one for each ``piece_s`` of eye time (one for all when None); ``h`` [s] the step of dt's
    central difference (half a knot spacing: as smooth as the batch stage's spline, so that the
    MoCap's own noise does not pass for motion); ``sigma`` the robust noise (rad, m) that sets
    which pairs are outliers; ``scale`` how many pairs each one stands for."""
    dt = est.time_offset_s
    hands = [_hand_motions(hand, eye, i, dt + s) for s in (0.0, -h, h)]
    ok = hands[0][1] & hands[1][1] & hands[2][1]
    k = i[ok]
    if k.size == 0:
        return []
    A = [_select(motions, ok) for motions, _ in hands]
    B = _eye_motions(eye, k)
    X = (np.asarray(est.R_HE, float), np.asarray(est.p_HE, float))
    r = _residuals(A[0], B, X)
    w = np.array([1 / sigma[0]] * 3 + [1 / sigma[1]] * 3)
    keep = np.all(np.abs(r * w) < OUTLIER_SIGMAS, axis=1)
    J = np.concatenate(
        [
            _jacobian([_rows(a, rows) for a in A], _rows(B, rows), X, h)
            for rows in (slice(s, s + CHUNK_ROWS) for s in range(0, k.size, CHUNK_ROWS))
        ]
    )
    t = eye.t_ns
    piece = (
        np.zeros(k.size, int)
        if piece_s is None
        else np.floor((t[k] - t[k[0]]) * 1e-9 / piece_s).astype(int)
    )
    out = []
    for p in np.unique(piece):
        rows = piece == p
        used = rows & keep
        info, grad = np.zeros((2, 7, 7)), np.zeros((2, 7))
        for g, c in enumerate((slice(0, 3), slice(3, 6))):
            Jg = J[used][:, c, :].reshape(-1, 7)
            info[g] = Jg.T @ Jg
            grad[g] = Jg.T @ r[used][:, c].ravel()
        kk = k[rows]
        span = float(np.sum(t[kk + 1] - t[kk])) * 1e-9 * scale
        hist = np.stack([histogram(r[rows][:, :3]), histogram(r[rows][:, 3:])])
        out.append(
            Chunk(
                int(t[kk[0]]), int(t[kk[-1] + 1]), kk.size, span, info * scale, grad * scale, hist
            )
        )
    return out


def weights(hist: Indices) -> tuple[float, float]:
    """The robust noise of the rotation [rad] and translation [m] rows from a (2, NBINS)
    histogram."""
    return robust_sigma(hist[0]), robust_sigma(hist[1])


def normal_equations(total: Chunk) -> tuple[Floats, Floats]:
    """The weighted (7, 7) information and (7,) gradient of summed chunks."""
    s_rot, s_t = weights(total.hist)
    w = np.array([1 / s_rot**2, 1 / s_t**2])
    return np.tensordot(w, total.info, 1), np.tensordot(w, total.grad, 1)


def covariance(info: Floats) -> Floats:
    """The information's inverse; inf where no motion observes a direction."""
    with np.errstate(all='ignore'):
        try:
            cov = np.linalg.inv(info)
        except np.linalg.LinAlgError:
            return np.full((7, 7), np.inf)
    return cov if np.all(np.isfinite(cov)) else np.full((7, 7), np.inf)


def sigmas(cov: Floats) -> tuple[float, float, float]:
    """1-sigma of dt [s], the translation [m] (norm of three) and the rotation [deg] (norm)."""
    d = np.diag(cov)
    return (
        float(np.sqrt(max(d[0], 0.0))),
        float(np.sqrt(max(d[1:4].sum(), 0.0))),
        float(np.degrees(np.sqrt(max(d[4:7].sum(), 0.0)))),
    )


def step(info: Floats, grad: Floats) -> Floats:
    """The Gauss-Newton step the chunks call for (7,), NaN where unobservable."""
    with np.errstate(all='ignore'):
        try:
            return -np.linalg.solve(info, grad)
        except np.linalg.LinAlgError:
            return np.full(7, np.nan)


def step_sizes(d: Floats) -> tuple[float, float, float]:
    """A step's size in the units of :func:`sigmas`."""
    return (
        abs(float(d[0])),
        float(np.linalg.norm(d[1:4])),
        float(np.degrees(np.linalg.norm(d[4:7]))),
    )


def _hand_motions(hand: Trajectory, eye: Trajectory, i: Indices, dt: float) -> tuple[Pose, Mask]:
    """The hand's motions between the stamps of eye poses i and i + 1 less dt, and where the
    hand covers both ends."""
    shift = np.int64(round(dt * 1e9))
    R, p, ok = interpolate(hand, eye.t_ns[np.concatenate([i, i + 1])] - shift)
    n = i.size
    return relative((R, p), np.arange(n), np.arange(n, 2 * n)), ok[:n] & ok[n:]


def _eye_motions(eye: Trajectory, i: Indices) -> Pose:
    ends = np.concatenate([i, i + 1])
    pose = (matrix_from_quat(eye.q_xyzw[ends]), eye.p_xyz[ends])
    n = i.size
    return relative(pose, np.arange(n), np.arange(n, 2 * n))


def _select(m: tuple[Floats, Floats], ok: Mask) -> tuple[Floats, Floats]:
    return m[0][ok], m[1][ok]


def _rows(m: tuple[Floats, Floats], rows: slice) -> tuple[Floats, Floats]:
    return m[0][rows], m[1][rows]


def _jacobian(A: list[Pose], B: Pose, X: Pose, h: float) -> Floats:
    """(n, 6, 7) central differences of the residuals in (dt, p_HE in H, the rotation
    R_HE Exp(d) with d in E): dt over +-h (A: the hand's motions at dt, dt - h, dt + h), the
    extrinsic over +-1e-6."""
    J = np.zeros((B[1].shape[0], 6, 7))
    J[:, :, 0] = (_residuals(A[2], B, X) - _residuals(A[1], B, X)) / (2 * h)
    eps = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = eps
        up: Pose = (X[0], X[1] + d)
        down: Pose = (X[0], X[1] - d)
        J[:, :, 1 + k] = (_residuals(A[0], B, up) - _residuals(A[0], B, down)) / (2 * eps)
        up, down = (X[0] @ exp_so3(d[None])[0], X[1]), (X[0] @ exp_so3(-d[None])[0], X[1])
        J[:, :, 4 + k] = (_residuals(A[0], B, up) - _residuals(A[0], B, down)) / (2 * eps)
    return J


def _residuals(A: Pose, B: Pose, X: Pose) -> Floats:
    """(n, 6) residual motions as (Log of the rotation, translation): the relative-pose
    residuals of eq. 16 in the eye frame."""
    err_R, err_p = residual_motions(A, B, X)
    return np.concatenate((log_so3(err_R), err_p), axis=1)
