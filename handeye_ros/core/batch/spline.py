"""Uniform cumulative B-splines of poses: R^3 for the position, SO(3) for the rotation.

For order k (cubic: k = 4), knot spacing ``dt`` and control poses ``(R_m, p_m)``, m = 0..M-1,
time t in segment i (``u = (t - t0) / dt``, ``i = floor(u)``, ``s = u - i``) is (paper eq. 14,
Kim et al. 1995, Sommer et al. 2020)::

    R(t) = R_i  prod_{j=1}^{k-1} Exp( Bc_j(s) Log(R_{i+j-1}^T R_{i+j}) )
    p(t) = p_i + sum_{j=1}^{k-1} Bc_j(s) (p_{i+j} - p_{i+j-1})

with ``Bc_j`` the cumulative uniform B-spline basis. Everything is vectorised over times.

A spline of *pieces* (:func:`fit_pieces`) is several such splines with one knot spacing, one
per gap-free part of a stream, their control poses stacked: a time maps to the piece that
starts last before it, and to that piece's control poses only, so nothing is interpolated
across a gap (a MoCap dropout). The evaluation and its Jacobians are the same code.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
from scipy.linalg import LinAlgError, solveh_banded
from scipy.sparse import csr_matrix
from scipy.sparse.linalg import lsqr
from scipy.spatial.transform import Rotation, Slerp

from ..arrays import Floats, Indices
from ..geometry import Pose, exp_so3, log_so3, quat_multiply

if TYPE_CHECKING:  # imported where used (see _cardinal)
    from scipy.interpolate import BSpline

#: Passes of the rotation control-point correction in :func:`fit_spline`.
ROTATION_FIT_ITERATIONS = 12
#: ... which end early once no control rotation moves by more than this (rad, 2 arcsec: far
#: below a MoCap's orientation noise of 0.01-0.1 deg; each pass costs a second on an hour).
ROTATION_FIT_TOL = 1e-5
#: MoCap rotations a segment the rotations' least squares reads at most, on average (a 1 kHz
#: MoCap has 53 a segment of the default 0.0527 s; ten average its noise down by three).
ROTATION_LSQ_PER_SEGMENT = 10


@lru_cache(maxsize=8)
def _cardinal(order: int) -> BSpline:
    """The cardinal B-spline of an order (scipy's BSpline): the cubic has a closed form
    below, and scipy.interpolate's import (0.6 s, with scipy.optimize) is left to other
    orders."""
    from scipy.interpolate import BSpline

    return BSpline.basis_element(np.arange(order + 1, dtype=float), extrapolate=False)


def cumulative_basis(s: Floats, order: int) -> Floats:
    """``Bc_j(s)``, j = 0..k-1, for s in [0, 1): shape (N, k); column 0 is 1."""
    s = np.asarray(s, dtype=float)
    if order == 4:  # the cubic's closed form (Sommer et al. 2020), as scipy's below
        s2, s3 = s * s, s * s * s
        return np.stack(
            (
                np.ones_like(s),
                (5.0 + 3.0 * s - 3.0 * s2 + s3) / 6.0,
                (1.0 + 3.0 * s + 3.0 * s2 - 2.0 * s3) / 6.0,
                s3 / 6.0,
            ),
            axis=-1,
        )
    N = _cardinal(order)
    # the basis function of control point i + j on segment i is the cardinal B-spline at
    # s + k - 1 - j
    b = np.stack([np.nan_to_num(N(s + order - 1 - j)) for j in range(order)], axis=-1)
    out: Floats = np.cumsum(b[:, ::-1], axis=1)[:, ::-1]
    return out


def cumulative_basis_derivative(s: Floats, order: int) -> Floats:
    """``dBc_j / ds``, j = 0..k-1, for s in [0, 1): shape (N, k); column 0 is 0."""
    s = np.asarray(s, dtype=float)
    if order == 4:
        s2 = s * s
        return np.stack(
            (
                np.zeros_like(s),
                (3.0 - 6.0 * s + 3.0 * s2) / 6.0,
                (3.0 + 6.0 * s - 6.0 * s2) / 6.0,
                s2 / 2.0,
            ),
            axis=-1,
        )
    dN = _cardinal(order).derivative()
    b = np.stack([np.nan_to_num(dN(s + order - 1 - j)) for j in range(order)], axis=-1)
    out: Floats = np.cumsum(b[:, ::-1], axis=1)[:, ::-1]
    return out


def plain_basis(Bc: Floats) -> Floats:
    """The B-spline basis (N, k) of control points i..i+k-1 from the cumulative one:
    ``b_j = Bc_j - Bc_j+1``, the last one as it is."""
    b = np.empty(Bc.shape)
    np.subtract(Bc[:, :-1], Bc[:, 1:], out=b[:, :-1])
    b[:, -1] = Bc[:, -1]
    return b


def exp_quat(v: Floats) -> Floats:
    """Unit quaternions (N, 4), x y z w, of rotation vectors (N, 3)."""
    theta = np.sqrt(np.einsum('ij,ij->i', v, v))
    small = theta < 1e-4
    # sin(t/2)/t with its Taylor series near 0
    k = np.where(
        small, 0.5 - theta * theta / 48.0, np.sin(0.5 * theta) / np.where(small, 1.0, theta)
    )
    return np.concatenate((v * k[:, None], np.cos(0.5 * theta)[:, None]), axis=1)


def _rotate_back(q: Floats, v: Floats) -> Floats:
    """``R(q)^T v`` for unit quaternions q (N, 4) and vectors v (N, 3)."""
    u, w = -q[:, :3], q[:, 3:]
    t = 2.0 * _cross(u, v)
    return v + w * t + _cross(u, t)


def _cross(a: Floats, b: Floats) -> Floats:
    """a x b row-wise for (N, 3) arrays (np.cross's generality costs it twice the time)."""
    out = np.empty_like(b)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


@dataclass(frozen=True)
class PoseSpline:
    """A uniform cumulative B-spline of poses (see the module docstring).

    t0 : float, start of the first segment (s, relative to the caller's origin)
    dt : float, knot spacing (s)
    order : int, k (4: cubic)
    R, p : control rotations (M, 3, 3) and positions (M, 3)
    pieces : None for one spline; else (starts (P,) s, first control pose (P,), segments (P,))
        of the stacked pieces of :func:`fit_pieces`
    """

    t0: float
    dt: float
    order: int
    R: Floats
    p: Floats
    pieces: tuple[Floats, Indices, Indices] | None = None

    @property
    def t_end(self) -> float:
        """End of the last segment (exclusive), s."""
        if self.pieces is not None:
            starts, _, n_seg = self.pieces
            return float(starts[-1] + n_seg[-1] * self.dt)
        return float(self.t0 + (self.R.shape[0] - self.order + 1) * self.dt)

    def spans(self) -> list[tuple[float, float]]:
        """(start, end) of each piece, s (one for a plain spline)."""
        if self.pieces is None:
            return [(self.t0, self.t_end)]
        starts, _, n_seg = self.pieces
        return [(float(a), float(a + n * self.dt)) for a, n in zip(starts, n_seg, strict=True)]

    def segments(self, t: Floats) -> tuple[Indices, Floats]:
        """(segment index i, fraction s) of times t; times outside are clamped to the ends (of
        the piece that starts last before them)."""
        t = np.asarray(t, dtype=float)
        t0: float | Floats
        first: int | Indices
        n_seg: int | Indices
        if self.pieces is None:
            t0, first, n_seg = self.t0, 0, self.R.shape[0] - self.order + 1
        else:
            starts, firsts, counts = self.pieces
            k = np.clip(np.searchsorted(starts, t, side='right') - 1, 0, starts.size - 1)
            t0, first, n_seg = starts[k], firsts[k], counts[k]
        u = (t - t0) / self.dt
        i = np.clip(np.floor(u).astype(int), 0, n_seg - 1)
        return first + i, np.clip(u - i, 0.0, 1.0)

    def _increments(self) -> tuple[Floats, Floats]:
        """Log of consecutive control rotations and position differences, computed once."""
        cached = self.__dict__.get('_inc')
        if cached is None:
            cached = (
                log_so3(np.matmul(np.swapaxes(self.R[:-1], -1, -2), self.R[1:])),
                np.diff(self.p, axis=0),
            )
            object.__setattr__(self, '_inc', cached)  # frozen: the cache is not state
        return cached

    def _control_quats(self) -> Floats:
        """The control rotations as quaternions (M, 4), computed once."""
        cached = self.__dict__.get('_quat')
        if cached is None:
            cached = Rotation.from_matrix(self.R).as_quat()
            object.__setattr__(self, '_quat', cached)  # frozen: the cache is not state
        out: Floats = cached
        return out

    def basis(self, t: Floats) -> tuple[Indices, Floats]:
        """(segment index, cumulative basis (N, k)) of times t: all that :meth:`poses_at` needs
        of the times, to reuse across splines with the same knots."""
        i, s = self.segments(t)
        return i, cumulative_basis(s, self.order)

    def basis_derivative(self, t: Floats) -> Floats:
        """``dBc_j / dt`` (N, k) at times t (1/s), for :meth:`poses_and_rates_at`."""
        _, s = self.segments(t)
        return cumulative_basis_derivative(s, self.order) / self.dt

    def poses_at(self, t: Floats, basis: tuple[Indices, Floats] | None = None) -> Pose:
        """Poses at times t (s): rotations (N, 3, 3), positions (N, 3); ``basis``: the
        :meth:`basis` of t, if already at hand."""
        R, p, _, _ = self._product(self.basis(t) if basis is None else basis)
        return R, p

    def poses_and_rates_at(
        self, basis: tuple[Indices, Floats], dbasis: Floats
    ) -> tuple[Floats, Floats, Floats, Floats]:
        """Poses at the times of ``basis`` and their rates: R (N, 3, 3), p (N, 3), the body
        angular velocity w (N, 3) with ``dR/dt = R [w]x`` [rad/s], and dp/dt (N, 3) [m/s].
        ``dbasis``: :meth:`basis_derivative` at the same times."""
        R, p, w, v = self._product(basis, dbasis)
        assert w is not None and v is not None, 'rates come with dbasis'
        return R, p, w, v

    def _product(
        self, basis: tuple[Indices, Floats], dbasis: Floats | None = None
    ) -> tuple[Floats, Floats, Floats | None, Floats | None]:
        """Eq. 14's product factor by factor: (R, p) and, with ``dbasis``, the rates (w, v).

        In quaternions (a product is 16 multiplications where numpy's stacked 3x3 matmul is
        several times slower), one conversion to matrices at the end. With ``A_j = Exp(Bc_j
        w_j)`` the body rate after factor j is ``A_j^T (rate before) + dBc_j w_j`` (Sommer et
        al., CVPR 2020).
        """
        i, Bc = basis
        omega, dp = self._increments()
        q = self._control_quats()[i]
        p = self.p[i].copy()
        w: Floats | None = None
        v: Floats | None = None
        if dbasis is not None:
            w, v = np.zeros((i.size, 3)), np.zeros((i.size, 3))
        for j in range(1, self.order):
            a = exp_quat(Bc[:, j, None] * omega[i + j - 1])
            q = quat_multiply(q, a)
            p += Bc[:, j, None] * dp[i + j - 1]
            if dbasis is not None and w is not None and v is not None:
                w = _rotate_back(a, w) + dbasis[:, j, None] * omega[i + j - 1]
                v += dbasis[:, j, None] * dp[i + j - 1]
        return Rotation.from_quat(q).as_matrix(), p, w, v


def fit_spline(t: Floats, R: Floats, p: Floats, knot_spacing: float, order: int = 4) -> PoseSpline:
    """A spline through stamped poses (the hand's spline of the batch stage).

    Control poses start as the poses interpolated where each control point weighs most (the
    centre of its support); rotations are then corrected until the spline passes through the
    data at those centres, and from there fitted by least squares to the samples
    (:func:`_rotations_least_squares`); positions are solved by linear least squares on the
    samples.
    ``R``: rotation matrices (N, 3, 3) or x y z w quaternions (N, 4) of the poses at times t
    (s); ``p``: positions (N, 3).
    """
    t = np.asarray(t, dtype=float)
    n_seg = int(np.ceil((t[-1] - t[0]) / knot_spacing - 1e-9))
    n_seg = max(n_seg, 1)
    M = n_seg + order - 1
    t0 = float(t[0])
    # control point m has its support centred at t0 + (m - (k - 2) / 2) * dt
    tc = np.clip(t0 + (np.arange(M) - (order - 2) / 2.0) * knot_spacing, t[0], t[-1])
    # the rotations at the centres, by slerp between the samples around each (only those: an
    # hour of 1 kHz MoCap is 3.6 million samples for some 72 000 centres)
    right = np.clip(np.searchsorted(t, tc), 1, t.size - 1)
    near = np.unique(np.concatenate((right - 1, right)))
    rotations = Rotation.from_quat(R[near]) if R.shape[-1] == 4 else Rotation.from_matrix(R[near])
    R_at_c = Slerp(t[near], rotations)(tc).as_matrix()
    Rc = R_at_c.copy()
    pc = np.stack([np.interp(tc, t, p[:, a]) for a in range(3)], axis=1)
    spline = PoseSpline(t0, knot_spacing, order, Rc, pc)
    # Rotations: make the spline pass through the data at the control centres by the classic
    # iterative correction (control += data - spline there); the basis at the centres is
    # diagonally dominant (1/6, 2/3, 1/6 for cubic), so it converges geometrically.
    for _ in range(ROTATION_FIT_ITERATIONS):
        R_s, _ = spline.poses_at(tc)
        err = log_so3(np.matmul(np.swapaxes(R_s, -1, -2), R_at_c))
        Rc = np.matmul(Rc, exp_so3(err))
        spline = PoseSpline(t0, knot_spacing, order, Rc, pc)
        if np.abs(err).max() < ROTATION_FIT_TOL:
            break
    spline = _rotations_least_squares(spline, t, R)
    Rc = spline.R
    # positions are linear in the control points, p(t) = A c: least squares by the normal
    # equations, which are banded (k - 1 off-diagonals) and well conditioned for a B-spline
    # basis; an hour of 1 kHz MoCap is 3.6 million rows, where an iterative solver takes 22 s
    i, s = spline.segments(t)
    b = plain_basis(cumulative_basis(s, order))
    pc = _banded_least_squares(i, b, p, M, pc)
    return PoseSpline(t0, knot_spacing, order, Rc, pc)


def _rotations_least_squares(spline: PoseSpline, t: Floats, R: Floats) -> PoseSpline:
    """The spline's control rotations refined to the least-squares fit of the MoCap's
    rotations at times t (s) at up to ROTATION_LSQ_PER_SEGMENT samples a segment on average
    (every k-th). The fit through the centres carries a sample's whole noise into each control
    rotation, and more into the spline's angular acceleration, from which the eye's relative
    poses read dt (eq. 16; bench/results/accuracy.md, "The MoCap's own noise"). Gauss-Newton
    on the body-frame residuals, each control rotation's correction spread over its support by
    the plain basis (the frames of one support differ little): the banded normal equations of
    the positions."""
    per = ROTATION_LSQ_PER_SEGMENT * (spline.R.shape[0] - spline.order + 1)
    pick = np.arange(0, t.size, max(1, -(-t.size // per)))
    obs = Rotation.from_quat(R[pick]).as_matrix() if R.shape[-1] == 4 else R[pick]
    i, s = spline.segments(t[pick])
    b = plain_basis(cumulative_basis(s, spline.order))
    M = spline.R.shape[0]
    for _ in range(ROTATION_FIT_ITERATIONS):
        R_s, _ = spline.poses_at(t[pick])
        err = log_so3(np.matmul(np.swapaxes(R_s, -1, -2), obs))
        step = _banded_least_squares(i, b, err, M, np.zeros((M, 3)))
        spline = PoseSpline(spline.t0, spline.dt, spline.order, spline.R @ exp_so3(step), spline.p)
        if np.abs(step).max() < ROTATION_FIT_TOL:
            break
    return spline


def fit_pieces(
    t: Floats,
    R: Floats,
    p: Floats,
    knot_spacing: float,
    order: int,
    spans: list[tuple[int, int]],
) -> PoseSpline:
    """One spline (:func:`fit_spline`) per index range ``spans`` of the stamped poses, stacked
    into a spline of pieces (see the module docstring); a single span gives the plain spline."""
    if len(spans) == 1:
        a, b = spans[0]
        return fit_spline(t[a:b], R[a:b], p[a:b], knot_spacing, order)
    parts = [fit_spline(t[a:b], R[a:b], p[a:b], knot_spacing, order) for a, b in spans]
    sizes = np.array([s.R.shape[0] for s in parts])
    pieces = (
        np.array([s.t0 for s in parts]),
        np.concatenate(([0], np.cumsum(sizes)[:-1])),
        sizes - order + 1,
    )
    return PoseSpline(
        parts[0].t0,
        knot_spacing,
        order,
        np.concatenate([s.R for s in parts]),
        np.concatenate([s.p for s in parts]),
        pieces,
    )


def _banded_least_squares(i: Indices, b: Floats, y: Floats, M: int, start: Floats) -> Floats:
    """Control values c (M, d) minimising sum_n |sum_c b[n, c] c[i_n + c] - y_n|^2.

    Normal equations in LAPACK's lower banded storage, by Cholesky; when a control value has
    no sample in its support (a singular system), sparse LSQR from ``start`` instead.
    """
    k = b.shape[1]
    ab = np.zeros((k, M))
    for off in range(k):
        for c in range(k - off):
            ab[off] += np.bincount(i + c, weights=b[:, c] * b[:, c + off], minlength=M)[:M]
    rhs = np.stack(
        [
            sum(np.bincount(i + c, weights=b[:, c] * y[:, a], minlength=M)[:M] for c in range(k))
            for a in range(y.shape[1])
        ],
        axis=1,
    )
    try:
        out: Floats = solveh_banded(ab, rhs, lower=True)
        return out
    except LinAlgError:
        rows = np.repeat(np.arange(i.size), k)
        cols = (i[:, None] + np.arange(k)).ravel()
        A = csr_matrix((b.ravel(), (rows, cols)), shape=(i.size, M))
        return np.stack(
            [
                lsqr(A, y[:, a], x0=start[:, a], atol=1e-12, btol=1e-12)[0]
                for a in range(y.shape[1])
            ],
            axis=1,
        )
