"""The covariance of stage 3's estimate (Section III-C), at the solution of :mod:`.batch.refine`.

White residuals give ``s^2 (J^T J)^-1``; for the decoupled two-step solve the covariance of the
two-step estimate (:func:`two_step_from_normals`). The reported covariance is the
long-run one of :mod:`.batch.long_run`, from each eye pose pair's influence on the estimate,
which holds for residuals correlated in time (a VIO's drift).
"""

from __future__ import annotations

import numpy as np

from ..arrays import Floats
from .long_run import (
    LongRunCovariance,
    influence_from_sums,
    influence_sums,
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
