"""Rank decisions of stage 3's normal matrices, by one stated tolerance.

A direction the data do not determine (a scale the eye's translations cannot tell from the
lever arm, a lever arm along the only rotation axis) makes a normal matrix ``J^T J`` singular
to rounding. Whether LAPACK's LU then raises or returns a huge finite answer depends on the
rounding of the BLAS kernel, so it is never asked: the matrix is scaled to a unit diagonal
(parameters of different units become comparable) and its eigenvalues below RANK_RTOL times the
largest are the directions it does not determine. A diagonal within rounding of zero (below
ROUNDING_RTOL times the largest) is a parameter it does not determine before any scaling: a
covariance that holds a direction along one of its axes has a variance of 1e-24 there, and
scaling that row to 1 would blow its rounding up into a determined direction.
"""

from __future__ import annotations

import numpy as np

from ..arrays import Floats

#: An eigenvalue of a normal matrix scaled to a unit diagonal below this fraction of the
#: largest is a direction the data do not determine: its sigma would be 1e5 times the
#: best-determined one's (in the scaled units), and ``J^T J`` squares the Jacobian's
#: condition, so 1e-10 keeps the decision 1e6 above float64's rounding (2.2e-16).
RANK_RTOL = 1e-10
#: A matrix formed of products (``J^T J``, ``T C T^T``) carries rounding of about float64's
#: epsilon times its largest entries; a diagonal within a thousand such roundings of zero is
#: zero. The parameters' units spread the diagonals of this package's matrices by less than
#: 1e8 (a clock drift against a translation), far above it.
ROUNDING_RTOL = 1e3 * float(np.finfo(float).eps)


def determined(A: Floats) -> tuple[Floats, Floats, Floats]:
    """The scaled eigen-decomposition of a symmetric positive semi-definite A (p, p):
    (the scale d (p,) with ``A = diag(d) C diag(d)``, C's eigenvalues (k,) and eigenvectors
    (p, k) of the k directions it determines). A parameter whose diagonal is zero to rounding
    is not determined."""
    diag = np.diag(A)
    zero = diag <= ROUNDING_RTOL * max(float(np.max(diag, initial=0.0)), 0.0)
    d = np.sqrt(np.where(zero, 1.0, diag))
    C = A / np.outer(d, d)
    C = 0.5 * (C + C.T)
    C[zero, :] = 0.0
    C[:, zero] = 0.0
    lam, V = np.linalg.eigh(C)
    keep = lam > RANK_RTOL * max(float(lam[-1]), 0.0)
    return d, lam[keep], V[:, keep]


def full_rank(A: Floats) -> bool:
    """A (p, p) determines every direction (:func:`determined`)."""
    return bool(determined(A)[1].size == A.shape[0])


def solve_determined(A: Floats, b: Floats) -> Floats:
    """The least-norm (in A's scaled units) solution of ``A x = b`` on the directions A
    determines: no step along the others (they stay where they are)."""
    d, lam, V = determined(A)
    x: Floats = (V @ ((V.T @ (b / d)) / lam)) / d
    return x


def pseudo_inverse(A: Floats) -> Floats:
    """A's inverse on the directions it determines, zero along the others."""
    d, lam, V = determined(A)
    out: Floats = ((V / lam) @ V.T) / np.outer(d, d)
    return out


def undetermined(A: Floats) -> Floats:
    """An orthonormal basis (p, k) of the k directions A does not determine, in A's own
    coordinates (the null space of a covariance that holds them, or of a normal matrix)."""
    d, _, V = determined(A)
    if V.shape[1] == A.shape[0]:
        return np.zeros((A.shape[0], 0))
    # the determined directions of A are diag(d)^-1 V's span's complement in A's coordinates:
    # A v = 0 <=> C (d v) = 0, and C's null space is V's orthogonal complement
    free = np.linalg.svd(np.eye(A.shape[0]) - V @ V.T)[0][:, : A.shape[0] - V.shape[1]]
    basis, _ = np.linalg.qr(free / d[:, None])
    out: Floats = basis
    return out


def inverse(A: Floats) -> Floats:
    """A's inverse when it determines every direction, else NaN throughout: a covariance
    with an undetermined direction is none, which the stage says (never a finite number
    whose size the BLAS kernel's rounding chose)."""
    if not full_rank(A):
        return np.full(A.shape, np.nan)
    out: Floats = np.linalg.inv(A)
    return out
