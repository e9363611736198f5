"""The loss function of the batch stage (eq. 15): Huber's rho on each whitened residual.

Kept apart from the residual blocks and the solver as Ceres keeps its LossFunction apart from
its CostFunction and Solver; the self-check scores candidates with the same loss."""

from __future__ import annotations

import numpy as np

from ..arrays import Floats


def huber_rho(r: Floats, delta: float) -> Floats:
    """Huber's loss per residual: r^2 / 2 within +-delta, linear beyond (continuous slope)."""
    a = np.abs(r)
    return np.where(a <= delta, 0.5 * a * a, delta * (a - 0.5 * delta))


def huber_psi(r: Floats, delta: float) -> tuple[Floats, Floats]:
    """Huber's psi (the residual clipped at +-delta) and psi' (1 inside, 0 beyond)."""
    return np.clip(r, -delta, delta), (np.abs(r) <= delta).astype(float)


def huber_cost(r: Floats, delta: float) -> float:
    """The Huber cost of residuals r (any shape) at threshold delta."""
    return float(np.sum(huber_rho(r, delta)))
