"""The hand trajectory mapped onto the eye, with and without the calibration.

With the calibration (what ``groundtruth.tum`` holds): at every eye stamp t on the eye's own
clock, ``T_WG T_GH(t - dt(t)) T_HE``, the eye pose the MoCap predicts, in the eye's world W
(each eye segment between VIO resets in its own W) and on the eye's clock; the hand is
interpolated (positions linearly, rotations by slerp) and never across one of its gaps.

Without it (what a user does today with evo's ``-a``): hand and eye paired on their stamps as
if both clocks were one, the hand's *marker* poses T_GH aligned onto the eye's body poses by an
SE(3) Umeyama fit of the positions (no T_HE, no offset).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.arrays import Floats, Indices, Stamps
from ..core.association import MIN_PAIRS, interpolate, pairs_at_eye
from ..core.geometry import compose, matrix_from_quat
from ..core.result import CalibrationResult
from ..core.world import rigid_fit, worlds_per_pair


@dataclass(frozen=True)
class AlignedTrajectories:
    """A reference and an estimate at the same eye stamps, in the eye's world.

    t_ns: (N,) int64 eye stamps on the eye's own clock. R_ref, p_ref: the reference poses
    (N, 3, 3), (N, 3) m; R_est, p_est: the eye's (metric when a scale was estimated).
    segment: (N,) the eye segment of each pose (no relative pose joins two).
    what: a short label for tables and plots.
    """

    t_ns: Stamps
    R_ref: Floats
    p_ref: Floats
    R_est: Floats
    p_est: Floats
    segment: Indices
    what: str

    def __len__(self) -> int:
        return int(self.t_ns.size)

    def seconds(self) -> Floats:
        """Stamps in seconds from the first one."""
        return (self.t_ns - self.t_ns[0]).astype(float) * 1e-9


def calibrated(result: CalibrationResult) -> AlignedTrajectories:
    """The calibrated ground truth ``T_WG T_GH(t - dt) T_HE`` at the eye's stamps (module
    docstring); eye stamps the hand does not cover are left out.

    Raises ValueError for a result without the streams it was computed on (``result.used``).
    """
    used = result.streams()
    pairs, ok = pairs_at_eye(used.hand, used.eye, used.time_offset_s)
    X = (matrix_from_quat(result.q_HE), np.asarray(result.p_HE, dtype=float))
    world = worlds_per_pair(pairs, result.q_HE, result.p_HE, result.world)
    R_ref, p_ref = compose(world, compose((pairs.R_GH, pairs.p_GH), X))
    return AlignedTrajectories(
        used.eye_stamps_ns[ok], R_ref, p_ref, pairs.R_WE, pairs.p_WE, pairs.segment, 'calibrated'
    )


def uncalibrated(result: CalibrationResult) -> tuple[AlignedTrajectories | None, str]:
    """The baseline without our calibration (module docstring), or None and why not."""
    used = result.streams()
    hand, eye = used.hand, used.eye
    R_GH, p_GH, ok = interpolate(hand, used.eye_stamps_ns)
    if ok.sum() < MIN_PAIRS:
        return None, (
            f'without the time offset only {int(ok.sum())} eye stamps fall inside '
            'the hand recording: the two clocks do not overlap, so no APE can be '
            'computed without it'
        )
    p_est, R_est = eye.p_xyz[ok], matrix_from_quat(eye.q_xyzw[ok])
    p_h = p_GH[ok]
    d = p_h - p_h.mean(axis=0)
    if np.linalg.svd(d, compute_uv=False)[1] < 1e-6 * max(1.0, np.abs(d).max()):
        return None, 'the hand positions span no plane: an SE(3) fit of positions is undefined'
    R_ref, p_ref = compose(rigid_fit(p_h, p_est), (R_GH[ok], p_h))
    return AlignedTrajectories(
        used.eye_stamps_ns[ok],
        R_ref,
        p_ref,
        R_est,
        p_est,
        np.zeros(int(ok.sum()), dtype=int),
        'uncalibrated (dt = 0, no T_HE, SE(3) Umeyama)',
    ), ''
