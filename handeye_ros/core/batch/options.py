"""How stage 3 solves (:class:`BatchOptions`): the options of :func:`.refine.refine` and of
its solve (:mod:`.solves`)."""

from __future__ import annotations

from dataclasses import dataclass

from ..config import KNOT_SPACING_S


@dataclass(frozen=True)
class BatchOptions:
    """How stage 3 solves (the defaults are :class:`~handeye_ros.core.config.CalibrationConfig`'s).

    knot_spacing (s) and order: the hand's spline. hand_noise / eye_noise: (rotation rad,
    translation m) per axis of each MoCap pose / of the eye's relative poses between
    consecutive frames; None estimates it from the data's own residuals. huber_delta, in
    sigmas; max_iterations of the solver. fix_time_offset: dt held at its start. decoupled: rotation then translation (:func:`.solves.solve_offset_extrinsic`).
    drift_stamp_ns: also estimate a clock drift, dt(t) = dt + drift (t - drift_stamp_ns) with t
    the eye's stamps (:mod:`.time.clock`); scale: also a factor on the eye's translations. Both
    are corrections to what the eye already has (0 and 1 to start). held_axis: a unit direction
    (hand frame) along which the translation of T_HE stays at its start: the only rotation axis
    of the motion, along which no eye motion depends on it; held_rotation: the rotation of T_HE
    about it held too (a rig turned in place, where any such rotation has its own translation
    across the axis).
    """

    knot_spacing: float = KNOT_SPACING_S
    order: int = 4
    hand_noise: tuple[float | None, float | None] = (None, None)
    eye_noise: tuple[float | None, float | None] = (None, None)
    huber_delta: float = 1.345
    max_iterations: int = 50
    fix_time_offset: bool = False
    decoupled: bool = True
    drift_stamp_ns: int | None = None
    scale: bool = False
    held_axis: tuple[float, ...] | None = None
    held_rotation: bool = False
