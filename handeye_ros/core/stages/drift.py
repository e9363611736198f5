"""The clock along the recording, as the pipeline uses it: with ``clock_drift`` the drift from
stage 1 in windows before stage 2, and the offset measured in windows with stage 2's rotation
after it (the vector form of stage 1); without it, a drift the windows show is named in the
verdict (:mod:`..time.clock` measures, :class:`~handeye_ros.core.eye_model.EyeModel` applies)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..arrays import Floats, Stamps
from ..checks.verdict import DriftMeasured, DriftUnobservable, Findings
from ..config import CalibrationConfig
from ..eye_model import EyeModel
from ..geometry import matrix_from_quat
from ..linear.robust import LinearSolution
from ..time.clock import DriftFit, measure_drift
from ..trajectory import Trajectory


def drift_from_windows(
    hand: Trajectory, eye: Trajectory, model: EyeModel, cfg: CalibrationConfig
) -> tuple[Trajectory, EyeModel]:
    """With clock_drift, before stage 2: the drift from stage 1 in windows (magnitudes: no
    rotation of T_HE yet), taken out of the eye's stamps so that stage 2 sees one offset.
    When it cannot be measured here, :func:`clock_along` says so."""
    fit = measure_drift(hand, eye, None, cfg.resample_rate_hz)
    if not fit.estimated:
        return eye, model
    return model.add_drift(eye, fit.drift, fit.drift_std)


@dataclass(frozen=True)
class Along:
    """The clock along the recording: eye and model (with clock_drift, the drift taken out of
    the eye's stamps); clock: the windows' fit on the eye's own clock (None: not measured);
    moved: the offset at the reference stamp [s] when the stamps moved, else None; found: the
    drift measured (a fact), or why it could not be."""

    eye: Trajectory
    model: EyeModel
    clock: DriftFit | None
    moved: float | None
    found: Findings


def clock_along(
    hand: Trajectory,
    eye: Trajectory,
    model: EyeModel,
    dt: float,
    lin: LinearSolution,
    cfg: CalibrationConfig,
) -> Along:
    """The offset measured in windows along the recording with stage 2's rotation (the vector
    form of stage 1): named when it drifts (default run), taken out of the eye's stamps with
    clock_drift."""
    if eye.keyframes:  # the windows correlate angular velocities, which keyframes do not give
        found = Findings.of(DriftUnobservable(None)) if cfg.clock_drift else Findings()
        return Along(eye, model, None, None, found)
    R_HE = None if lin.unobservable else matrix_from_quat(lin.q_HE)
    fit = measure_drift(hand, eye, R_HE, cfg.resample_rate_hz, around_s=dt)
    clock = _absolute_clock(fit, model)
    if not cfg.clock_drift:
        return Along(eye, model, clock, None, Findings.of(DriftMeasured(fit)))
    if not fit.estimated:
        found = (
            Findings.warned(
                'the clock drift comes from the angular-speed magnitudes only: ' + fit.why
            )
            if model.drift_estimated
            else Findings.of(DriftUnobservable(fit.why))
        )
        return Along(eye, model, clock, None, found)
    eye, model = model.add_drift(eye, fit.drift, fit.drift_std * (1.0 - model.drift))
    return Along(eye, model, clock, float(fit.offset_at(model.stamp_ns)), Findings())


def _absolute_clock(fit: DriftFit, model: EyeModel) -> DriftFit:
    """A window fit measured on an eye the model was applied to, on the eye's own clock:
    the model's drift added back to the offsets and the rate."""

    def back(t_ns: Stamps | int) -> Floats:
        return model.drift * (np.asarray(t_ns) - np.int64(model.stamp_ns)) * 1e-9

    out = fit.shifted(model.shift_ns)
    return replace(
        out,
        offsets_s=out.offsets_s + back(fit.centres_ns),
        offset_s=out.offset_s + float(back(fit.stamp_ns)),
        drift=fit.drift + model.drift * (1.0 - fit.drift),
    )
