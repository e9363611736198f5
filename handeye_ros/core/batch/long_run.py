"""Uncertainty of the batch estimate when the residuals are correlated in time.

The textbook covariance of a least-squares estimate, ``s^2 (J^T J)^-1``, holds for white
residuals. A real VIO's errors are not white: its drift, scale error and filter smoothing make
consecutive relative poses err alike, so N residuals carry far less than N independent pieces
of information, and that covariance is too small (on 21 real VI-SLAM runs of one flight, 2-5x
too small for the offset). Here the covariance comes from the residuals themselves:

1. **Influence functions.** The estimate solves ``sum_e g_e(theta) = 0`` over the eye's
   consecutive pose pairs e (in time order), ``g_e = sum_rows J_row^T psi(r_row)`` with
   Huber's psi (the residual clipped at delta). To first order the estimate's error is
   ``sum_e psi_e`` with ``psi_e = -H^-1 g_e`` and ``H = sum_rows J_row^T psi'(r_row) J_row``
   (psi' = 1 inside delta, 0 beyond). For the two-step (decoupled) solve, the second step's
   influence also carries the first step's through its sensitivity to the rotation
   (:func:`influence_two_step`).
2. **Long-run covariance.** ``Cov = sum_{|l| <= L} w_l Gamma_l``, ``Gamma_l = sum_e psi_e
   psi_{e+l}^T``, with Bartlett weights ``w_l = 1 - |l| / (L + 1)`` (Newey & West 1987: always
   positive semi-definite). With ``L = 0`` this is the robust (sandwich) covariance of white
   residuals, which on white data equals ``s^2 (J^T J)^-1``.
3. **Bandwidth from the data** (Andrews 1991, AR(1) plug-in for the Bartlett kernel): each
   component of psi is fitted an AR(1) coefficient rho; ``alpha = sum 4 rho^2 s^4 / ((1 -
   rho)^6 (1 + rho)^2) / sum s^4 / (1 - rho)^4`` and ``L = 1.1447 (alpha T)^(1/3)``, at most
   T / 4. White residuals give rho ~ 0 and L ~ 0.

Cost: one more Jacobian-sized product and T x L inner products of 7-vectors (for T = 18 000
eye poses and L = 50, a few milliseconds).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import Floats, Indices
from .loss import huber_psi
from .rank import inverse

#: Largest AR(1) coefficient used in the bandwidth (a unit root has no long-run variance).
MAX_RHO = 0.97
#: The bandwidth is at most this fraction of the series.
MAX_BANDWIDTH_FRACTION = 0.25


@dataclass(frozen=True)
class LongRunCovariance:
    """A long-run covariance and how it was made.

    covariance: (p, p); white: the same with L = 0 (the sandwich for white residuals);
    bandwidth: L, in eye poses; samples: T.
    """

    covariance: Floats
    white: Floats
    bandwidth: int
    samples: int

    @property
    def inflation(self) -> Floats:
        """(p,) ratio of the long-run to the white standard deviations (>= 0)."""
        w = np.sqrt(np.clip(np.diag(self.white), 1e-300, None))
        out: Floats = np.sqrt(np.clip(np.diag(self.covariance), 0.0, None)) / w
        return out


def influence(r: Floats, J: Floats, delta: float, rows_per_sample: int) -> tuple[Floats, Floats]:
    """Per-sample influence ``psi_e = -H^-1 g_e`` of an M-estimate and ``H^-1``.

    Parameters
    ----------
    r : ndarray, shape (T * rows_per_sample,)
        Weighted residuals at the solution, grouped by sample in time order.
    J : ndarray, shape (T * rows_per_sample, p)
        Their Jacobian.
    """
    g, H = influence_sums(
        r.reshape(-1, rows_per_sample), J.reshape(-1, rows_per_sample, J.shape[1]), delta
    )
    return influence_from_sums(g, H)


def influence_sums(
    r: Floats, J: Floats, delta: float, other: Floats | None = None
) -> tuple[Floats, ...]:
    """What the influences need of some samples, to be summed over all of them: per sample
    ``g_e = sum_rows J_row^T psi(r_row)`` (T, p) and ``H = sum J^T psi' J`` (p, p); with
    ``other`` (T, rows, q) also ``sum J^T psi' other`` (p, q).

    r: (T, rows) weighted residuals; J: (T, rows, p) their Jacobian. Summing H over chunks of
    samples and stacking g is the same as one call on all of them (an hour of 200 Hz eye
    poses is taken in chunks).
    """
    psi, dpsi = huber_psi(r, delta)
    g = np.einsum('trp,tr->tp', J, psi)
    Jw = J * dpsi[..., None]
    flat = J.reshape(-1, J.shape[-1])
    H = Jw.reshape(-1, J.shape[-1]).T @ flat
    if other is None:
        return g, H
    return g, H, Jw.reshape(-1, J.shape[-1]).T @ other.reshape(-1, other.shape[-1])


def influence_from_sums(g: Floats, H: Floats) -> tuple[Floats, Floats]:
    """Influences ``psi_e = -H^-1 g_e`` (T, p) and ``H^-1`` from :func:`influence_sums`."""
    H_inv = inverse(H)
    return -g @ H_inv.T, H_inv


def influence_two_step(
    r_a: Floats,
    J_a: Floats,
    r_b: Floats,
    J_b: Floats,
    J_theta: Floats,
    delta: float,
    rows_a: int,
    rows_b: int,
    theta_in_a: Indices,
) -> tuple[Floats, Floats]:
    """Influences of a two-step estimate: theta from step A, then step B's parameters b with
    theta fixed (b moves by ``S dtheta``, ``S = -H_b^-1 J_b^T psi' J_theta``).

    Returns (psi_theta (T, 3), psi_b (T, p_b)).
    """
    g_a, H_a = influence_sums(
        r_a.reshape(-1, rows_a), J_a.reshape(-1, rows_a, J_a.shape[1]), delta
    )
    g_b, H_b, C = influence_sums(
        r_b.reshape(-1, rows_b),
        J_b.reshape(-1, rows_b, J_b.shape[1]),
        delta,
        J_theta.reshape(-1, rows_b, J_theta.shape[1]),
    )
    return two_step_from_sums(g_a, H_a, g_b, H_b, C, theta_in_a)


def two_step_from_sums(
    g_a: Floats,
    H_a: Floats,
    g_b: Floats,
    H_b: Floats,
    C: Floats,
    theta_in_a: Indices,
) -> tuple[Floats, Floats]:
    """:func:`influence_two_step` from the sums of :func:`influence_sums` of both steps (C:
    step B's ``J_b^T psi' J_theta``)."""
    psi_a, _ = influence_from_sums(g_a, H_a)
    psi_theta = psi_a[:, theta_in_a]
    psi_b, H_b_inv = influence_from_sums(g_b, H_b)
    S = -H_b_inv @ C
    return psi_theta, psi_b + psi_theta @ S.T


def andrews_bandwidth(psi: Floats) -> int:
    """Bartlett bandwidth by Andrews' (1991) AR(1) plug-in rule over the columns of psi (T, p)."""
    T = psi.shape[0]
    if T < 8:
        return 0
    x = psi - psi.mean(axis=0)
    num = den = 0.0
    for c in x.T:
        d = float(c[:-1] @ c[:-1])
        if not d > 0.0:
            continue
        rho = float(np.clip((c[1:] @ c[:-1]) / d, -MAX_RHO, MAX_RHO))
        s2 = float(np.mean((c[1:] - rho * c[:-1]) ** 2))
        num += 4.0 * rho**2 * s2**2 / ((1.0 - rho) ** 6 * (1.0 + rho) ** 2)
        den += s2**2 / (1.0 - rho) ** 4
    if not den > 0.0:
        return 0
    L = 1.1447 * (num / den * T) ** (1.0 / 3.0)
    return int(min(np.floor(L), MAX_BANDWIDTH_FRACTION * T))


def long_run_covariance(psi: Floats, bandwidth: int | None = None) -> LongRunCovariance:
    """Newey-West covariance of ``sum_e psi_e`` (see module docstring); ``bandwidth`` None
    chooses it by :func:`andrews_bandwidth`."""
    T = psi.shape[0]
    L = andrews_bandwidth(psi) if bandwidth is None else int(bandwidth)
    white = psi.T @ psi
    cov = white.copy()
    for lag in range(1, L + 1):
        g = psi[lag:].T @ psi[:-lag]
        cov += (1.0 - lag / (L + 1.0)) * (g + g.T)
    return LongRunCovariance(0.5 * (cov + cov.T), white, L, T)
