"""The Huber loss and the Levenberg-Marquardt solvers of stage 3 (Section III-C: "Huber loss,
Levenberg-Marquardt"), apart from the residuals they minimise (:mod:`.batch.residuals`).

A Newton model of the Huber cost: rows within delta as in least squares, rows beyond it with
their gradient clipped to +-delta and no curvature; the damping follows the gain ratio
(Nielsen). :func:`levenberg_marquardt_dense` works on normal equations summed over chunks of
rows (a few parameters, millions of rows); it is not scipy's ``least_squares``, and says why.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..arrays import Floats, Indices
from .loss import huber_cost, huber_psi
from .rank import pseudo_inverse, solve_determined

#: Levenberg-Marquardt: start, floor and ceiling of the damping (relative to the normal matrix's
#: diagonal) and the relative cost change that ends it.
LM_LAMBDA0 = 1e-4
LM_LAMBDA_MIN = 1e-9
LM_LAMBDA_MAX = 1e8
LM_FTOL = 1e-10


@dataclass(frozen=True)
class SolverReport:
    """How a solve ended: success, why (message), its iterations (each one Newton model, the
    count ``batch_max_iterations`` bounds in both solvers), residual passes (nfev) and
    Jacobian evaluations (njev)."""

    success: bool
    message: str
    nfev: int
    njev: int
    iterations: int


@dataclass(frozen=True)
class NormalSums:
    """One evaluation of weighted residuals over the free parameters, summed over the rows:
    the Huber cost, ``A = J^T psi' J``, ``g = J^T psi`` and the column sums of J^2 (the
    damping's scale); ``raw``: the unweighted residuals when the caller keeps them; ``extra``:
    whatever else the caller gathered on the same pass (the solver hands it back untouched)."""

    cost: float
    A: Floats
    g: Floats
    D: Floats
    raw: Floats | None = None
    extra: object = None


#: The dense solve ends when a step moves no parameter by more than this fraction of its
#: standard deviation (from the Gauss-Newton normal matrix), or lowers the cost by less than
#: LM_FTOL relative. A hundredth of a sigma is far below anything the result's precision can
#: show (for dt at 0.4 ms, 4 us), and each tighter step is a pass over every row.
STEP_TOL_SIGMA = 1e-2


def levenberg_marquardt_dense(
    sums_at: Callable[[Floats], NormalSums],
    y: Floats,
    free: Indices,
    max_iterations: int,
    start: NormalSums | None = None,
) -> tuple[Floats, SolverReport, NormalSums]:
    """Huber-robust Levenberg-Marquardt on a few parameters (``free`` entries of y) with an
    analytic Jacobian: the Newton model of the module docstring solved densely.
    ``sums_at(y)``: the normal sums at y (:class:`SumsOfChunks`); ``start``: those at the
    starting y when the caller already has them (one pass fewer).

    Why not scipy's least_squares: with a finite-difference Jacobian each of its iterations
    re-evaluated the spline at every eye pose once per parameter (on an hour of 200 Hz VIO,
    10 minutes of the stage), and it needs the whole Jacobian in memory. Here an iteration is
    one pass over the eye pairs with their Jacobian, summed as it goes, and the step from the
    linear result converges in 2-4 of them. Returns (y, report, the sums at y).
    """
    y = y.copy()
    cur = sums_at(y) if start is None else start
    lam, nu, nfev = LM_LAMBDA0, 2.0, 1  # the start counts, wherever it was summed
    message, success = 'maximum number of iterations reached', False
    iterations = 0
    for _ in range(max_iterations):
        iterations += 1
        # on the directions the data determine (:mod:`.rank`); along the others y stays
        sigma = np.sqrt(np.clip(np.diag(pseudo_inverse(cur.A)), 1e-300, None))
        D = np.diag(np.maximum(cur.D, 1e-12))
        if np.all(np.abs(solve_determined(cur.A, -cur.g)) <= STEP_TOL_SIGMA * sigma):
            # the Gauss-Newton step from here is below tolerance: y is the solution, and
            # the step is not worth a pass over the eye (it would change y by < 1e-2 sigma)
            message, success = "Gauss-Newton step below 1e-2 of every parameter's sigma", True
            break
        while True:
            step = solve_determined(cur.A + lam * D, -cur.g)
            y_new = y.copy()
            y_new[free] += step
            new = sums_at(y_new)
            nfev += 1
            predicted = -(cur.g @ step + 0.5 * step @ (cur.A @ step))
            if new.cost <= cur.cost or lam > LM_LAMBDA_MAX:
                break
            lam *= nu
            nu *= 2.0
        if new.cost > cur.cost:
            message, success = 'no step lowers the cost any further', True
            break
        decrease = cur.cost - new.cost
        rho = decrease / predicted if predicted > 0 else 0.0
        lam = float(max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), LM_LAMBDA_MIN))
        nu = 2.0
        y, cur = y_new, new
        if np.all(np.abs(step) <= STEP_TOL_SIGMA * sigma):
            message, success = "step below 1e-2 of every parameter's sigma", True
            break
        if decrease <= LM_FTOL * cur.cost:
            message, success = 'relative cost change below tolerance', True
            break
    report = SolverReport(success, message, nfev=nfev, njev=nfev, iterations=iterations)
    return y, report, cur


class SumsOfChunks:
    """:class:`NormalSums` over the free columns of chunks of weighted residuals r (n, rows)
    with their Jacobians J (n, rows, n_y), summed as they come (no chunk is kept)."""

    def __init__(self, free: Indices, delta: float) -> None:
        p = free.size
        self.free, self.delta = free, delta
        self.cost, self.A, self.g, self.D = 0.0, np.zeros((p, p)), np.zeros(p), np.zeros(p)

    def add(self, r: Floats, J: Floats) -> None:
        r = r.ravel()
        Jf = J[:, :, self.free].reshape(r.size, self.free.size)
        psi, dpsi = huber_psi(r, self.delta)
        self.cost += huber_cost(r, self.delta)
        self.A += Jf.T @ (Jf * dpsi[:, None])
        self.g += Jf.T @ psi
        self.D += np.einsum('ij,ij->j', Jf, Jf)

    def sums(self, raw: Floats | None = None, extra: object = None) -> NormalSums:
        return NormalSums(self.cost, self.A, self.g, self.D, raw, extra)
