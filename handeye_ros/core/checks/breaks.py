"""Breaks of the eye stream: resets of the VIO's world, found against the hand's motion.

A reset moves the eye's world frame by decimetres and degrees and the jump persists, so it is no
isolated outlier (:mod:`.screening` leaves it); once stage 2 has an extrinsic, the motion the eye
should have made over each interval is known, and an interval that disagrees with it beyond the
stream's own spread is a break. The eye is then split into segments at the breaks, and no
relative pose is built across one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..arrays import Floats, Stamps
from ..association import eye_motion_errors
from ..trajectory import Trajectory, segment_spans

#: Eye intervals whose error against the hand's motion exceeds median + this many robust
#: standard deviations (and the floors) are inconsistent: 8, stricter than for poses, because
#: a false break only costs the motions across it while the test runs on every interval.
BREAK_SIGMAS = 8.0
#: Interval errors below these never make a break (m, rad): a reset of the VIO's world moves it
#: by decimetres and degrees, while consecutive VIO poses differ from the hand's motion by mm.
BREAK_FLOOR_TRANSLATION_M = 0.02
BREAK_FLOOR_ROTATION_RAD = np.deg2rad(1.0)
#: A part of the eye stream between breaks shorter than this (s, poses) is dropped.
MIN_SEGMENT_S = 1.0
MIN_SEGMENT_POSES = 10


@dataclass(frozen=True)
class EyeBreaks:
    """Result of :func:`find_eye_breaks`: the eye with its breaks, and the stamps of the poses
    dropped (isolated outliers, parts too short to use) and of the first pose after each
    break."""

    eye: Trajectory
    outliers_ns: Stamps
    short_ns: Stamps
    breaks_ns: Stamps


def find_eye_breaks(
    hand: Trajectory, eye: Trajectory, time_offset_s: float, R_HE: Floats, p_HE: Floats
) -> EyeBreaks:
    """Breaks (resets of the VIO world) and leftover wild poses of the eye, found against the
    hand's motion once stage 2 has an extrinsic.

    Every consecutive eye interval, gaps included, is compared with the hand's motion over the
    same instants (:func:`~handeye_ros.core.association.eye_motion_errors`). Its error is
    inconsistent above median + BREAK_SIGMAS robust deviations of the errors of ordinary
    intervals (for a gap, scaled by the square root of its length: a VIO's error grows like a
    random walk) and above the floors. Two inconsistent intervals around one pose make that
    pose an outlier (dropped); one inconsistent interval is a break. Parts between breaks
    shorter than MIN_SEGMENT_S or MIN_SEGMENT_POSES are dropped.
    """
    k = np.arange(len(eye) - 1)
    e_r, e_t, covered = eye_motion_errors(hand, eye, k, k + 1, time_offset_s, (R_HE, p_HE))
    step = np.diff(eye.t_ns).astype(float)
    usual = eye.interval_ok() & covered
    if usual.sum() < 20:
        return EyeBreaks(eye, *(np.zeros(0, dtype=np.int64),) * 3)
    scale = np.sqrt(np.maximum(step / np.median(step[usual]), 1.0))

    def limit(e: Floats, floor: float) -> Floats:
        m = np.median(e[usual])
        s = 1.4826 * np.median(np.abs(e[usual] - m))
        out: Floats = np.maximum(m + BREAK_SIGMAS * s, floor) * scale
        return out

    bad = covered & (
        (e_r > limit(e_r, BREAK_FLOOR_ROTATION_RAD))
        | (e_t > limit(e_t, BREAK_FLOOR_TRANSLATION_M))
    )
    bad[eye.breaks] = False  # known already
    # a pose between two inconsistent intervals is a wild pose, not two breaks
    wild = np.zeros(len(eye), dtype=bool)
    wild[1:-1] = bad[:-1] & bad[1:]
    k = np.flatnonzero(wild)
    bad[k - 1] = False
    bad[k] = False
    new_breaks = np.flatnonzero(bad)
    marked = eye.with_breaks(new_breaks)
    # parts too short to use
    short = np.zeros(len(eye), dtype=bool)
    for a, b in segment_spans(marked.segment_ids()):
        if b - a < MIN_SEGMENT_POSES or (eye.t_ns[b - 1] - eye.t_ns[a]) * 1e-9 < MIN_SEGMENT_S:
            short[a:b] = True
    if short.all():  # nothing would be left: keep the stream whole, the verdict will tell
        return EyeBreaks(eye, *(np.zeros(0, dtype=np.int64),) * 3)
    drop = wild | short
    out = marked.select(~drop) if drop.any() else marked
    breaks_ns = out.t_ns[out.breaks + 1] if out.breaks.size else np.zeros(0, dtype=np.int64)
    new = np.setdiff1d(breaks_ns, eye.t_ns[eye.breaks + 1] if eye.breaks.size else [])
    return EyeBreaks(out, eye.t_ns[wild & ~short], eye.t_ns[short], new.astype(np.int64))
