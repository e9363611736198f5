"""How the pipeline brings the eye onto the hand's clock and into metres.

Every stage after stage 1 solves the paper's problem: one small constant offset and a metric
eye. The pipeline gets there by moving the eye's stamps by stage 1's offset (integer ns),
taking out a clock drift (:func:`.time.clock.retime`) and scaling its positions; this record keeps
what was applied so that the result can be stated on the eye's own clock and scale::

    hand time of eye stamp t  =  t - time_offset - clock_drift (t - time_offset_stamp)
    metric eye positions      =  scale * eye positions
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .arrays import Stamps
from .linear.scale import observable
from .time.clock import retime
from .trajectory import Trajectory


@dataclass(frozen=True)
class EyeModel:
    """What was applied to the eye (see the module docstring).

    shift_ns: stage 1's offset taken out of the stamps (eye clock minus hand clock, ns).
    stamp_ns: the drift's reference stamp on the shifted clock (ns; add shift_ns for the eye's
    own clock). drift, drift_std: [s/s]; scale, scale_std: the factor on the positions.
    drift_estimated / scale_estimated: whether they were estimated (rather than left at 0 / 1).
    """

    shift_ns: int
    stamp_ns: int = 0
    drift: float = 0.0
    drift_std: float = float('nan')
    drift_estimated: bool = False
    scale: float = 1.0
    scale_std: float = float('nan')
    scale_estimated: bool = False

    def add_drift(self, eye: Trajectory, drift: float, std: float) -> tuple[Trajectory, EyeModel]:
        """Take a further drift out of an eye this model was applied to (about the same
        stamp: the drifts compose as ``d1 + d2 (1 - d1)``); ``std`` is that of the total."""
        total = self.drift + drift * (1.0 - self.drift)
        return (
            retime(eye, drift, self.stamp_ns),
            replace(self, drift=total, drift_std=std, drift_estimated=True),
        )

    def add_scale(self, eye: Trajectory, factor: float, std: float) -> tuple[Trajectory, EyeModel]:
        """Scale the positions of an eye this model was applied to by a further factor; ``std``
        is that of the total scale."""
        return (
            eye.scaled(factor),
            replace(self, scale=self.scale * factor, scale_std=std, scale_estimated=True),
        )

    @property
    def scale_observable(self) -> bool:
        """Whether the estimated scale says anything (see :func:`.linear.scale.observable`)."""
        return self.scale_estimated and observable(self.scale, self.scale_std)

    @property
    def time_offset_stamp_ns(self) -> int:
        """The reference stamp on the eye's own clock, ns."""
        return int(self.shift_ns + self.stamp_ns)

    def own_clock_ns(self, t_ns: Stamps, eye_stamps_ns: Stamps | None = None) -> Stamps:
        """Stamps [int64 ns] of an eye this model was applied to, back on the eye's own clock.

        Inverts the shift and the drift (``u = v - drift (v - stamp)`` with ``v = t - shift``);
        the integer rounding of each retiming leaves a few ns, so when the eye's own stamps
        ``eye_stamps_ns`` are given each result is snapped to the nearest of them within 1 us.
        """
        u = np.asarray(t_ns, dtype=np.int64)
        v = u.copy()
        if self.drift != 0.0:
            rel = (u - np.int64(self.stamp_ns)).astype(float)
            v = u + np.rint(self.drift * rel / (1.0 - self.drift)).astype(np.int64)
        out = v + np.int64(self.shift_ns)
        if eye_stamps_ns is None or out.size == 0 or np.size(eye_stamps_ns) == 0:
            return out
        own = np.asarray(eye_stamps_ns, dtype=np.int64)
        k = (
            np.clip(np.searchsorted(own, out), 1, own.size - 1)
            if own.size > 1
            else np.zeros(out.shape, dtype=int)
        )
        near = (
            own[k]
            if own.size == 1
            else np.where(np.abs(own[k - 1] - out) <= np.abs(own[k] - out), own[k - 1], own[k])
        )
        return np.where(np.abs(near - out) <= 1000, near, out)
