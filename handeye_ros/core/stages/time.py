"""Stage 1 as the pipeline runs it (:class:`Offset`): the correlation of eq. 1 over every lag
or a window (:mod:`..time.align`), the keyframe search of a keyframe-only eye
(:mod:`..time.keyframe_only`), or the offset the user fixed (checked against the data); then the orientation conventions, which
need an offset to be checked (AX = XB holds under one reading only)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..association import MIN_PAIRS
from ..checks.orientations import check_orientations
from ..checks.verdict import WEAK_CORRELATION, Findings, FixedOffsetDisagrees
from ..config import CalibrationConfig
from ..errors import NoOverlapError, TimeAlignmentError
from ..time.align import TimeAlignment, align_time
from ..time.keyframe_only import align_time_keyframes
from ..trajectory import Trajectory
from .prepare import Inputs

#: A search window given by its guess alone is this wide on each side (s).
DEFAULT_HALF_WINDOW_S = 0.5
#: A fixed offset further than this from the correlation peak is reported (s): a few grid
#: steps, well above the peak's own error (< 2 ms on the paper's protocol).
FIXED_OFFSET_DISAGREEMENT_S = 0.01


@dataclass(frozen=True)
class Offset:
    """alignment: stage 1's result (or the offset fixed by the user); hand, eye: the streams
    after the orientation conventions; fixed: the user gave the offset; found: a fixed offset
    the data disagree with, the orientation readings corrected."""

    alignment: TimeAlignment
    hand: Trajectory
    eye: Trajectory
    fixed: bool
    found: Findings

    @property
    def shift_ns(self) -> int:
        """Stage 1's offset in integer ns, by which the later stages move the eye's stamps."""
        return self.alignment.time_offset_ns


def align_stage(inputs: Inputs, cfg: CalibrationConfig) -> Offset:
    """Stage 1 (see the module docstring)."""
    hand, eye = inputs.hand, inputs.eye
    fixed = cfg.time_offset is not None
    guess, half = search_window(cfg)
    found = Findings()
    if cfg.time_offset is not None:
        _check_fixed_overlap(hand, eye, cfg.time_offset)
        ta = TimeAlignment(
            time_offset_s=cfg.time_offset,
            method='fixed',
            time_offset_ns=round(cfg.time_offset * 1e9),
        )
        found = check_fixed_offset(hand, eye, cfg.time_offset, cfg)
    elif eye.keyframes:
        ta = align_time_keyframes(hand, eye, max_time_offset=half, time_offset_guess=guess)
    else:
        ta = align_time(
            hand,
            eye,
            max_time_offset=half,
            time_offset_guess=guess,
            resample_rate_hz=cfg.resample_rate_hz,
            peak_fit=cfg.peak_fit,
        )
    if cfg.check_conventions:
        hand, eye, corrections = check_orientations(
            hand, eye, ta.time_offset_s, np.deg2rad(cfg.eta)
        )
        found = found + Findings.corrected(corrections)
    return Offset(ta, hand, eye, fixed, found)


def search_window(cfg: CalibrationConfig) -> tuple[float | None, float | None]:
    """(guess, half-width) of stage 1's search; (None, None) searches every lag."""
    if cfg.max_time_offset is None and cfg.time_offset_guess is None:
        return None, None
    return (
        cfg.time_offset_guess or 0.0,
        cfg.max_time_offset if cfg.max_time_offset is not None else DEFAULT_HALF_WINDOW_S,
    )


def _check_fixed_overlap(hand: Trajectory, eye: Trajectory, fixed_s: float) -> None:
    """NoOverlapError, naming the offset the user fixed, when fewer than MIN_PAIRS eye poses
    fall inside the hand's span at it (later stages see the eye already moved by it)."""
    at_hand = eye.t_ns - round(fixed_s * 1e9)
    inside = int(np.count_nonzero((at_hand >= hand.t_ns[0]) & (at_hand <= hand.t_ns[-1])))
    if inside < MIN_PAIRS:
        gap = (eye.t_ns[0] - hand.t_ns[0]) * 1e-9
        raise NoOverlapError(
            f'with the time offset fixed at {fixed_s:+.4f} s, {inside} poses of {eye.name} fall '
            f'inside {hand.name} (need {MIN_PAIRS}; the eye starts {gap:+.3f} s after the hand '
            'on their own clocks, and an offset dt moves it by -dt): check time_offset, or '
            'leave it unset to find it'
        )


def check_fixed_offset(
    hand: Trajectory, eye: Trajectory, fixed_s: float, cfg: CalibrationConfig
) -> Findings:
    """Warn, and lower the verdict (``offset_disagrees``), when a user-fixed offset
    ``fixed_s`` (s) disagrees with the angular-speed correlation.

    Why: the linear stage cannot tell a wrong offset from a noisy eye (a 50 ms error still gives
    most motions as inliers at moderate speed), so a wrong fixed value would pass silently.
    """
    half = cfg.max_time_offset or DEFAULT_HALF_WINDOW_S
    try:
        est = align_time(
            hand,
            eye,
            max_time_offset=half,
            time_offset_guess=fixed_s,
            resample_rate_hz=cfg.resample_rate_hz,
        )
    except TimeAlignmentError as err:
        return Findings.warned(f'could not check the fixed time offset against the data: {err}')
    if (
        est.peak_correlation >= WEAK_CORRELATION
        and abs(est.time_offset_s - fixed_s) > FIXED_OFFSET_DISAGREEMENT_S
    ):
        text = (
            f'the fixed time offset {fixed_s * 1e3:+.1f} ms disagrees with the '
            f'angular-speed correlation, which peaks at {est.time_offset_s * 1e3:+.1f} ms '
            f'(correlation {est.peak_correlation:.2f}); check the fixed value'
        )
        fact = FixedOffsetDisagrees(fixed_s, est.time_offset_s, est.peak_correlation)
        return Findings(warnings=(text,), log=(fact,))
    return Findings()
