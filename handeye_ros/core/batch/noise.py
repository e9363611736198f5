"""The noise of a stream, from its own residuals (robust: median absolute deviation).

Stage 3 weights each stream by 1/sigma per axis; unless the user gives a sigma, it is measured
on the residuals at the current estimate (:mod:`.batch.refine` does so twice: at the linear
result and at the first solution).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import Floats

#: Noise estimates never go below these (rad, m): a noise-free stream would get infinite weight.
MIN_SIGMA_ROT = 1e-6
MIN_SIGMA_TRANS = 1e-6


@dataclass(frozen=True)
class Noise:
    """Standard deviations per axis (rad, m) of one stream's residuals: of each pose for the
    hand, of the relative pose between consecutive poses for the eye."""

    rotation: float
    translation: float
    estimated: bool


def robust_sigma(r: Floats) -> float:
    """Per-axis standard deviation from the median absolute deviation (robust to outliers)."""
    return float(1.4826 * np.median(np.abs(r - np.median(r, axis=0))))


def sigmas(
    r: Floats, given: tuple[float | None, float | None], fitted: int = 0, n: int | None = None
) -> tuple[float, float, bool]:
    """Per-axis (rotation, translation) noise of residuals r (N, 6), unless given.

    ``fitted``: parameters per axis fitted to these same residuals (the spline's M control
    poses for the hand), which shrink them by sqrt((N - fitted) / N): undone here, up to a
    factor sqrt(2). A spline with about as many control poses as MoCap poses (a sparse MoCap)
    nearly interpolates it and its residuals say little about the noise; blowing them up
    then would only turn interpolation round-off into noise. ``n``: how many residuals the fit
    had, when r is a sample of them.
    """
    n = r.shape[0] if n is None else n
    inflate = float(np.sqrt(n / max(n - fitted, n / 2.0)))
    rot = (
        given[0] if given[0] is not None else max(inflate * robust_sigma(r[:, :3]), MIN_SIGMA_ROT)
    )
    trans = (
        given[1]
        if given[1] is not None
        else max(inflate * robust_sigma(r[:, 3:]), MIN_SIGMA_TRANS)
    )
    return rot, trans, given[0] is None or given[1] is None
