"""The covariance of stage 3's estimate (Section III-C), at the solution of :mod:`.batch.refine`.

White residuals give ``s^2 (J^T J)^-1``; for the decoupled two-step solve the covariance of the
two-step estimate (:func:`two_step_from_normals`); for the joint solve the 7x7 block by a Schur
complement over the spline (:func:`marginal_covariance`). The reported covariance is the
long-run one of :mod:`.batch.long_run`, from each eye pose pair's influence on the estimate,
which holds for residuals correlated in time (a VIO's drift).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.sparse import csc_matrix, diags
from scipy.sparse.linalg import splu

from ..arrays import Floats, Mask
from .joint_jacobian import central_jacobian, joint_jacobian
from .long_run import (
    LongRunCovariance,
    influence,
    influence_from_sums,
    influence_sums,
    influence_two_step,
    long_run_covariance,
    two_step_from_sums,
)
from .loss import huber_cost
from .parameters import ParameterLayout, weighted_eye_chunks
from .rank import inverse
from .residuals import BatchProblem, Weights


def eye_covariance(
    prob: BatchProblem,
    weights: Weights,
    y: Floats,
    layout: ParameterLayout,
    delta: float,
    decoupled: bool,
) -> tuple[Floats, LongRunCovariance, float, int]:
    """(white covariance, long-run covariance (:mod:`.batch.long_run`), Huber cost, number of
    residuals) of the default solve at y, in the order of y (zero rows for a fixed dt), from
    one pass over the eye pairs with their analytic Jacobian (:class:`CovarianceSums`)."""
    sums = CovarianceSums(layout, delta, decoupled)
    for r, J in weighted_eye_chunks(prob, weights, y):
        sums.add(r, J)
    return sums.result()


class CovarianceSums:
    """What :func:`eye_covariance` needs of the eye pairs at one y, summed a chunk at a time,
    so that a solver's pass at the solution can gather it on the way (no pass of its own).

    The white covariance is ``s^2 (J^T J)^-1`` (for the two-step solve that of the two-step
    estimate, :func:`two_step_from_normals`); the long-run one comes from the per-pair
    influences (:func:`.long_run.influence_sums`)."""

    def __init__(self, layout: ParameterLayout, delta: float, decoupled: bool) -> None:
        self.layout, self.delta, self.decoupled = layout, delta, decoupled
        self.cost, self.n_res = 0.0, 0
        self.g_parts: dict[str, list[Floats]] = {'a': [], 'b': [], 'all': []}
        self.sums: dict[str, Floats] = {}

    def _add_sum(self, name: str, value: Floats) -> None:
        self.sums[name] = self.sums[name] + value if name in self.sums else value

    def add(self, r: Floats, J: Floats) -> None:
        """One chunk: weighted residuals r (n, 6) and their Jacobian J (n, 6, n_y)."""
        layout, delta = self.layout, self.delta
        self.cost += huber_cost(r, delta)
        self.n_res += r.size
        if self.decoupled:
            J_a, J_b, J_t = J[:, :3][:, :, layout.a], J[:, :, layout.b], J[:, :, 1:4]
            g_a, H_a = influence_sums(r[:, :3], J_a, delta)
            g_b, H_b, C = influence_sums(r, J_b, delta, J_t)
            self.g_parts['a'].append(g_a)
            self.g_parts['b'].append(g_b)
            fa, fb, ft = (x.reshape(-1, x.shape[-1]) for x in (J_a, J_b, J_t))
            for name, value in (
                ('H_a', H_a),
                ('H_b', H_b),
                ('C', C),
                ('N_a', fa.T @ fa),
                ('N_b', fb.T @ fb),
                ('N_bt', fb.T @ ft),
            ):
                self._add_sum(name, value)
        else:
            J_f = J[:, :, layout.all]
            g, H = influence_sums(r, J_f, delta)
            self.g_parts['all'].append(g)
            f = J_f.reshape(-1, J_f.shape[-1])
            self._add_sum('H', H)
            self._add_sum('N', f.T @ f)

    def result(self) -> tuple[Floats, LongRunCovariance, float, int]:
        """(white covariance, long-run covariance, Huber cost, number of residuals), as
        :func:`eye_covariance` returns them."""
        layout, sums, k = self.layout, self.sums, len(self.layout.time)
        free_all = layout.all
        s2 = max(2.0 * self.cost / max(self.n_res - free_all.size, 1), 1e-12)
        cov = np.zeros((layout.size, layout.size))
        if self.decoupled:
            cov[np.ix_(free_all, free_all)] = two_step_from_normals(
                sums['N_a'], sums['N_b'], sums['N_bt'], s2, k
            )
            psi = _two_step_influences(
                *two_step_from_sums(
                    np.concatenate(self.g_parts['a']),
                    sums['H_a'],
                    np.concatenate(self.g_parts['b']),
                    sums['H_b'],
                    sums['C'],
                    np.arange(k, k + 3),
                ),
                k,
            )
        else:
            cov[np.ix_(free_all, free_all)] = s2 * inverse(sums['N'])
            psi, _ = influence_from_sums(np.concatenate(self.g_parts['all']), sums['H'])
        return cov, _long_run_in_y(psi, layout), self.cost, self.n_res


def _two_step_influences(psi_theta: Floats, psi_b: Floats, k: int) -> Floats:
    """The two-step estimate's influences (T, free) in the order of :attr:`ParameterLayout.all`:
    step B's k time parameters, step A's dtheta, then step B's others."""
    return np.concatenate((psi_b[:, :k], psi_theta, psi_b[:, k:]), axis=1)


def _long_run_in_y(psi: Floats, layout: ParameterLayout) -> LongRunCovariance:
    """Long-run covariance (:mod:`.batch.long_run`) of influences psi (T, free), as matrices in
    the order of y (zero rows and columns for the entries held fixed)."""
    lr = long_run_covariance(psi)
    full, white = np.zeros((layout.size,) * 2), np.zeros((layout.size,) * 2)
    idx = np.ix_(layout.all, layout.all)
    full[idx], white[idx] = lr.covariance, lr.white
    return LongRunCovariance(full, white, lr.bandwidth, lr.samples)


#: The small solve ends when a step moves no parameter by more than this fraction of its
#: standard deviation (from the Gauss-Newton normal matrix), or lowers the cost by less than


def eye_jacobians(
    residuals: Callable[..., Floats], y: Floats, layout: ParameterLayout, decoupled: bool
) -> dict[str, Floats]:
    """Central-difference Jacobians of the eye residuals at y (the joint solve's, where the
    spline moves): for the two-step solve 'a' (rotation rows; dt if free, dtheta), 'b' (all
    rows; dt if free, dp) and 'theta' (all rows; dtheta); otherwise 'all' (all rows; every
    free parameter)."""
    h = layout.steps
    if not decoupled:
        return {'all': central_jacobian(residuals, y, layout.all, h)}
    return {
        'a': central_jacobian(lambda yy: residuals(yy, rotation_only=True), y, layout.a, h),
        'b': central_jacobian(residuals, y, layout.b, h),
        'theta': central_jacobian(residuals, y, np.array([1, 2, 3]), h),
    }


def eye_long_run(
    r: Floats,
    jac: dict[str, Floats],
    layout: ParameterLayout,
    delta: float,
    decoupled: bool,
) -> LongRunCovariance:
    """Long-run covariance (:mod:`.batch.long_run`) of (dt, dtheta_X, dp_X, ...) from the eye
    residuals at the solution, as matrices in the order of y (zero rows for a fixed dt).

    ``r``: the weighted eye residuals, 6 rows per eye pose pair in time order; ``jac``: their
    Jacobians as :func:`eye_jacobians` names them.
    """
    k = len(layout.time)
    if decoupled:
        psi = _two_step_influences(
            *influence_two_step(
                r.reshape(-1, 6)[:, :3].ravel(),
                jac['a'],
                r,
                jac['b'],
                jac['theta'],
                delta,
                3,
                6,
                np.arange(k, k + 3),
            ),
            k,
        )
    else:
        psi, _ = influence(r, jac['all'], delta, 6)
    return _long_run_in_y(psi, layout)


def two_step_from_normals(N_A: Floats, N_B: Floats, N_Bt: Floats, s2: float, k: int) -> Floats:
    """Covariance of the decoupled estimate under white residuals, in the order (dt if free,
    dtheta, dp); k is 1 when dt is free.

    Step A gives dtheta (with dt) from the rotation residuals: Sigma_A = s2 (J_A^T J_A)^-1.
    Step B gives (dt, dp) from all residuals with dtheta fixed; its own noise gives
    Sigma_B = s2 (J_B^T J_B)^-1, and dtheta's error moves it by S = -(J_B^T J_B)^-1 J_B^T J_t
    (J_t: all residuals wrt dtheta). The final dt is step B's. N_A, N_B, N_Bt: J_A^T J_A,
    J_B^T J_B and J_B^T J_t, summed over the eye pairs.
    """
    cov_a = s2 * inverse(N_A)
    cov_tt = cov_a[k:, k:]
    N_B_inv = inverse(N_B)
    S = -N_B_inv @ N_Bt
    return assemble_two_step(cov_tt, s2 * N_B_inv, S, k)


def assemble_two_step(cov_tt: Floats, cov_b: Floats, S: Floats, k: int) -> Floats:
    """The two-step estimate's covariance in the order (time parameters, dtheta, dp, scale?).

    cov_tt: dtheta from step A; cov_b: step B's (time, dp, scale?) from its own noise; S: how
    dtheta's error moves step B's parameters; k: how many time parameters (dt, drift) are free.
    """
    cov_b = cov_b + S @ cov_tt @ S.T
    n = cov_tt.shape[0] + cov_b.shape[0]
    out = np.zeros((n, n))
    pos_t = np.arange(k, k + 3)
    idx_b = np.array(list(range(k)) + list(range(k + 3, n)))  # where B's parameters go
    out[np.ix_(pos_t, pos_t)] = cov_tt
    out[np.ix_(idx_b, idx_b)] = cov_b
    cross = S @ cov_tt  # Cov(B's parameters, dtheta)
    out[np.ix_(idx_b, pos_t)] = cross
    out[np.ix_(pos_t, idx_b)] = cross.T
    return out


def marginal_covariance(J: csc_matrix | Floats, n_nuisance: int) -> Floats:
    """(J^T J)^-1 block of the parameters after the first ``n_nuisance`` (the control poses,
    and dt where it is marginalised too), by the Schur complement over those."""
    J = csc_matrix(J)
    Js, Jc = J[:, :n_nuisance], J[:, n_nuisance:].toarray()
    A = csc_matrix(Js.T @ Js)
    B = np.asarray(Js.T @ Jc)
    C = Jc.T @ Jc
    lu = splu(A)
    S = C - B.T @ lu.solve(B)
    return inverse(S)


def joint_covariance(
    prob: BatchProblem,
    weights: Weights,
    x: Floats,
    f: Floats,
    free: Mask,
    rot_rows: Mask,
    theta: Mask,
    trans: Mask,
    delta: float,
    decoupled: bool,
) -> Floats:
    """White 7x7 covariance of (dt, dtheta_X, dp_X) of the joint solve at x, the control
    poses marginalised; ``f``: the weighted residuals at x; ``free``, ``theta``, ``trans``:
    masks over x (free parameters, rotation of T_HE, translation of T_HE); ``rot_rows``: the
    rows of step A (MoCap rows and the eye's rotation rows).

    The Gauss-Newton Jacobian of the Huber cost (scipy's convention), each stream's rows
    scaled by its own reduced chi^2: its noise is estimated apart; the hand rows also pay for
    the control poses, the eye rows for dt and T_HE."""
    ns, nh = prob.n_spline, 6 * prob.th.size
    s2_h = 2.0 * huber_cost(f[:nh], delta) / max(nh - ns, 1)
    s2_e = 2.0 * huber_cost(f[nh:], delta) / max(f.size - nh - 7, 1)
    scale = np.where(
        np.arange(f.size) < nh, 1.0 / np.sqrt(max(s2_h, 1e-12)), 1.0 / np.sqrt(max(s2_e, 1e-12))
    )
    scale *= np.sqrt(np.minimum(1.0, delta / np.maximum(np.abs(f), 1e-300)))
    J = diags(scale) @ joint_jacobian(prob, x, weights)
    cov = np.zeros((7, 7))
    glob = np.flatnonzero(free[ns:])  # y's free entries
    if not decoupled:
        cov[np.ix_(glob, glob)] = marginal_covariance(J[:, free], ns)
        return cov
    # as two_step_from_normals, with the control poses marginalised in each step
    J_A = J[rot_rows][:, free & ~trans]
    cov_tt = marginal_covariance(J_A, J_A.shape[1] - 3)
    J_B = csc_matrix(J[:, free & ~theta])
    rhs = np.asarray((J_B.T @ J[:, theta]).todense())
    S = -splu(csc_matrix(J_B.T @ J_B)).solve(rhs)[ns:]
    k_dt = int(free[ns])
    cov[np.ix_(glob, glob)] = assemble_two_step(cov_tt, marginal_covariance(J_B, ns), S, k_dt)
    return cov


def joint_long_run(
    prob: BatchProblem,
    weights: Weights,
    x: Floats,
    cov: Floats,
    layout: ParameterLayout,
    delta: float,
    decoupled: bool,
) -> LongRunCovariance:
    """The joint solve's covariance with the eye's long-run correlation added to the Schur
    covariance ``cov`` (which has the spline's share): the eye rows' long-run minus their white
    sandwich, at the joint solution x (the spline moved with it)."""
    spline, y = prob.unpack(x)
    w_eye = weights.eye

    def eye_rows(yy: Floats, rotation_only: bool = False) -> Floats:
        r = prob.eye_raw_at(spline, yy) * w_eye
        return (r[:, :3] if rotation_only else r).ravel()

    lr = eye_long_run(
        eye_rows(y), eye_jacobians(eye_rows, y, layout, decoupled), layout, delta, decoupled
    )
    extra = lr.covariance - lr.white
    lam, V = np.linalg.eigh(0.5 * (cov + extra + (cov + extra).T))
    cov_lr = (V * np.clip(lam, 0.0, None)) @ V.T
    return LongRunCovariance(cov_lr, cov, lr.bandwidth, lr.samples)
