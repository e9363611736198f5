"""The self-check: when two stages propose different offsets, which one do the data support?

Stage 1 can be misled (a periodic motion gives several correlation peaks; a noisy VIO biases
the magnitude peak), and the batch stage is a local refinement. Instead of trusting one stage
or capping how far another may move (a distance guard throws away a refinement that was
right), every proposed offset is checked the same way: the linear stage (Section III-B) is run
again at that offset, and its extrinsic and the offset are scored on *one* set of motions with
*one* noise model, so that the scores compare:

- the motions are keyframe motions chosen on the eye's own rotations (eq. 6 with eta), which
  do not depend on the offset, at most a bounded sample of them spread over the recording
  (:mod:`.excerpt`), restricted to those the hand covers at every candidate offset;
- each motion's error is that of AX = XB, the rotation angle and the translation of
  ``(T_HE^-1 A T_HE)^-1 B`` (:func:`~handeye_ros.core.association.eye_motion_errors`);
- each error is divided by the smallest median of that error over the candidates, and the
  score is the mean Huber loss (threshold 3) of the two: a wrong offset leaves every fast
  motion with a large error and cannot win by a few good ones.

The candidate with the lowest score wins; the result says which were tried, their scores, and
which won.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..arrays import Floats, Indices
from ..association import eye_motion_errors, interpolate
from ..batch.loss import huber_rho
from ..geometry import matrix_from_quat, rotation_angle, row_norms
from ..linear.keyframes import segment_motion_indices
from ..trajectory import Trajectory
from .excerpt import spread_sample

#: Huber threshold of the score, in units of the best median error.
SCORE_HUBER = 3.0
#: Fewest common motions a comparison needs.
MIN_COMMON_MOTIONS = 10
#: A candidate offset at which the eye's keyframe motions and the hand's turn by angles this
#: many times further apart than at the offset in hand (eq. 9: a rigid T_HE keeps each motion's
#: angle, whatever it is) is rejected before stage 2 runs there; SCREW_FLOOR_DEG floors the
#: offset in hand's own disagreement (noise-free data agree to round-off).
SCREW_REJECT = 3.0
SCREW_FLOOR_DEG = 0.05


@dataclass(frozen=True)
class Candidate:
    """One offset the self-check scored.

    time_offset_s: dt of the candidate (s, on the clocks as the pipeline sees them); source:
    where it came from ('correlation peak', 'correlation runner-up', 'batch stage', ...);
    score: lower is better (NaN: could not be scored); residuals: median rotation (deg) and
    translation (m) error of the scored motions; q_HE, p_HE: the extrinsic it was scored with;
    chosen: whether it won.
    """

    time_offset_s: float
    source: str
    score: float
    rotation_residual_deg: float
    translation_residual_m: float
    q_HE: Floats
    p_HE: Floats
    chosen: bool = False


@dataclass(frozen=True)
class Hypothesis:
    """A (dt, T_HE) to score: time_offset_s (s, on the clocks as the pipeline sees them),
    source (where it came from), q_HE and p_HE."""

    time_offset_s: float
    source: str
    q_HE: Floats
    p_HE: Floats


def eye_keyframes(eye: Trajectory, eta_rad: float) -> tuple[Indices, Indices]:
    """Keyframe motions (eq. 6) chosen on the eye's own rotations, within its segments: they
    do not depend on the offset, so every candidate is scored on the same ones."""
    return segment_motion_indices(
        matrix_from_quat(eye.q_xyzw), eye.segment_ids(), 'rotation', eta_rad
    )


def scored_motions(eye: Trajectory, eta_rad: float) -> tuple[Indices, Indices]:
    """The keyframe motions (i -> j) candidates are judged on: the eye's
    (:func:`eye_keyframes`), at most :data:`~.excerpt.SAMPLE_MOTIONS` of them evenly spread."""
    return spread_sample(*eye_keyframes(eye, eta_rad))


def screw_disagreement(
    hand: Trajectory, eye: Trajectory, time_offset_s: float, i: Indices, j: Indices
) -> float:
    """Median difference (deg) between the rotation angles of the eye's motions (i -> j) and
    of the hand's over the same instants at ``time_offset_s`` (eq. 9's screw congruence, which
    needs no T_HE); NaN when the hand covers fewer than MIN_COMMON_MOTIONS of them. A wrong
    offset pairs motions that turn by unrelated angles: tens of degrees apart."""
    shift = np.int64(round(time_offset_s * 1e9))
    R_a, _, ok_a = interpolate(hand, eye.t_ns[i] - shift)
    R_b, _, ok_b = interpolate(hand, eye.t_ns[j] - shift)
    ok = ok_a & ok_b
    if ok.sum() < MIN_COMMON_MOTIONS:
        return float('nan')
    R_e = matrix_from_quat(eye.q_xyzw[np.concatenate((i[ok], j[ok]))])
    n = int(ok.sum())
    hand_angle = rotation_angle(np.swapaxes(R_a[ok], -1, -2) @ R_b[ok])
    eye_angle = rotation_angle(np.swapaxes(R_e[:n], -1, -2) @ R_e[n:])
    return float(np.degrees(np.median(np.abs(hand_angle - eye_angle))))


def screw_rejects(disagreement: float, in_hand: float) -> bool:
    """Whether a candidate's screw disagreement rules it out against the offset in hand's."""
    return bool(
        np.isfinite(disagreement)
        and np.isfinite(in_hand)
        and disagreement > SCREW_REJECT * max(in_hand, SCREW_FLOOR_DEG)
    )


def motion_consistency(
    hand: Trajectory,
    eye: Trajectory,
    time_offset_s: float,
    q_HE: Floats,
    p_HE: Floats,
    eta_rad: float,
) -> tuple[float, float, float, int]:
    """Median AX = XB rotation (deg) and translation (m) error over the eye's keyframe
    motions at (dt, T_HE), the motions' median translation (m), and how many there are."""
    i, j = eye_keyframes(eye, eta_rad)
    e_r, e_t, covered = eye_motion_errors(
        hand, eye, i, j, time_offset_s, (matrix_from_quat(q_HE), p_HE)
    )
    if not covered.any():
        return float('nan'), float('nan'), float('nan'), 0
    length = row_norms(eye.p_xyz[j] - eye.p_xyz[i])
    return (
        float(np.degrees(np.median(e_r[covered]))),
        float(np.median(e_t[covered])),
        float(np.median(length[covered])),
        int(covered.sum()),
    )


def score_candidates(
    hand: Trajectory,
    eye: Trajectory,
    hypotheses: list[Hypothesis],
    motions: tuple[Indices, Indices],
) -> list[Candidate]:
    """Score hypotheses on one set of the eye's motions (i -> j,
    :func:`scored_motions`; see the module docstring).

    Returns the candidates in the given order, the best one marked ``chosen``; when fewer than
    MIN_COMMON_MOTIONS motions are covered at every offset, every score is NaN and the first
    hypothesis is marked chosen.
    """
    i, j = motions
    errors = []
    common = np.ones(i.size, dtype=bool)
    for h in hypotheses:
        e_r, e_t, covered = eye_motion_errors(
            hand, eye, i, j, h.time_offset_s, (matrix_from_quat(h.q_HE), h.p_HE)
        )
        errors.append((e_r, e_t))
        common &= covered
    if common.sum() < MIN_COMMON_MOTIONS:
        nan = float('nan')
        return [
            Candidate(h.time_offset_s, h.source, nan, nan, nan, h.q_HE, h.p_HE, k == 0)
            for k, h in enumerate(hypotheses)
        ]
    s_r = max(min(float(np.median(e_r[common])) for e_r, _ in errors), 1e-9)
    s_t = max(min(float(np.median(e_t[common])) for _, e_t in errors), 1e-9)
    out = []
    for h, (e_r, e_t) in zip(hypotheses, errors, strict=True):
        score = float(
            np.mean(
                huber_rho(e_r[common] / s_r, SCORE_HUBER)
                + huber_rho(e_t[common] / s_t, SCORE_HUBER)
            )
        )
        out.append(
            Candidate(
                h.time_offset_s,
                h.source,
                score,
                float(np.degrees(np.median(e_r[common]))),
                float(np.median(e_t[common])),
                h.q_HE,
                h.p_HE,
            )
        )
    best = int(np.argmin([c.score for c in out]))
    return [replace(c, chosen=k == best) for k, c in enumerate(out)]
