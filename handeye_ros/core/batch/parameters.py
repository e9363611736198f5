"""Stage 3's parameters and how the solvers walk the eye residuals: y = (dt, dtheta_X (3),
dp_X (3), [drift], [scale]) and which entries each step of the decoupled solve frees
(:class:`ParameterLayout`), the eye residuals weighted a chunk at a time
(:func:`weighted_eye_chunks`)."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..arrays import Floats, Indices
from .residuals import EYE_CHUNK_PAIRS, FD_STEP, FD_STEP_DRIFT, FD_STEP_S, Weights

if TYPE_CHECKING:
    from .residuals import BatchProblem


@dataclass(frozen=True)
class ParameterLayout:
    """Which entries of y = (dt, dtheta_X (3), dp_X (3), [drift], [scale]) each step frees.

    time: dt (unless fixed) and the drift, free in both steps of the decoupled solve;
    rotation, translation: the entries of dtheta_X and dp_X that are free (y[3] and y[6] are
    held with a held rotation and axis, :class:`.residuals.BatchProblem`); scale: with the translation (step B). Every covariance
    is in the order of :attr:`all`.
    """

    time: tuple[int, ...]
    scale: tuple[int, ...]
    size: int
    translation: tuple[int, ...] = (4, 5, 6)
    rotation: tuple[int, ...] = (1, 2, 3)

    @classmethod
    def of(
        cls, prob: BatchProblem, fix_time_offset: bool, held_axis: bool, held_rotation: bool
    ) -> ParameterLayout:
        time_idx = (() if fix_time_offset else (0,)) + (
            () if prob.i_drift is None else (prob.i_drift,)
        )
        scale = () if prob.i_scale is None else (prob.i_scale,)
        return cls(
            time_idx,
            scale,
            prob.n_y,
            (4, 5) if held_axis else (4, 5, 6),
            (1, 2) if held_rotation else (1, 2, 3),
        )

    @property
    def a(self) -> Indices:
        return np.array((*self.time, *self.rotation))

    @property
    def b(self) -> Indices:
        return np.array((*self.time, *self.translation, *self.scale))

    @property
    def all(self) -> Indices:
        return np.array((*self.time, *self.rotation, *self.translation, *self.scale))

    @property
    def steps(self) -> Floats:
        """Central-difference steps for the entries of y."""
        h = np.full(self.size, FD_STEP)
        h[0] = FD_STEP_S
        if self.size > 7 and len(self.time) and self.time[-1] >= 7:
            h[self.time[-1]] = FD_STEP_DRIFT
        return h


def weighted_eye_chunks(
    prob: BatchProblem,
    w: Weights,
    y: Floats,
    rotation_only: bool = False,
    raw: list[Floats] | None = None,
    every: int = 1,
) -> Iterator[tuple[Floats, Floats]]:
    """(r (n, rows), J (n, rows, n_y)) of each chunk of eye pairs (of every ``every``-th
    chunk), weighted by 1/sigma; the unweighted residuals of each chunk are appended to
    ``raw`` when given."""
    rows = 3 if rotation_only else 6
    w_rows = w.eye[:rows]
    for k in prob.chunks()[::every]:
        r, J = prob.eye_chunk(y, k, min(k + EYE_CHUNK_PAIRS, prob.ei.size), True, rotation_only)
        assert J is not None  # asked for (True above)
        if raw is not None:
            raw.append(r)
        yield r * w_rows, J * w_rows[None, :, None]
