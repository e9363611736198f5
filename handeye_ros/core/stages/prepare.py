"""The streams as the stages use them (:class:`Inputs`): explicit inversions, stamp units read
against the rates, clock epochs named, a keyframe-only eye recognised, each stream screened (a
stream that would lose too much is refused, its damage named first)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..checks.conventions import check_stamp_units, epoch_note
from ..checks.orientations import reread
from ..checks.screening import Screening, damaged, describe_damage, screen
from ..checks.verdict import Findings
from ..config import CalibrationConfig
from ..errors import InputError
from ..trajectory import Trajectory, TrajectoryInfo, is_keyframe_only


@dataclass(frozen=True)
class Inputs:
    """hand (T_GH), eye (T_WE): the streams after the conventions and screening, each on its
    own clock; screening: what was removed from each (hand, eye); given: the streams as handed
    over, described (names, counts, rates, spans); found: the readers' notes, the readings
    corrected, the epochs and a keyframe-only eye named, the damaged rows left out."""

    hand: Trajectory
    eye: Trajectory
    screening: tuple[Screening, Screening]
    given: tuple[TrajectoryInfo, TrajectoryInfo]
    found: Findings


def prepare(hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig) -> Inputs:
    """The inputs of the stages (see the module docstring)."""
    given = (hand.info(), eye.info())
    read = Findings.warned(*hand.notes, *eye.notes)
    hand, eye, conventions = prepare_streams(hand, eye, cfg)
    hand, eye, screening = screen_streams(hand, eye, cfg)
    damage = [rep.damage for rep in screening if rep.damage]
    return Inputs(
        hand,
        eye,
        (screening[0].report, screening[1].report),
        given,
        read + conventions + Findings.warned(*(f'{d}; those rows were left out' for d in damage)),
    )


def prepare_streams(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig
) -> tuple[Trajectory, Trajectory, Findings]:
    """Explicit inversions, stamp units, epochs, and what was found on the way. The same
    poses handed over as both streams (one file given twice) are refused: there is nothing to
    calibrate, and every figure would be zero."""
    if len(hand) == len(eye) and all(
        np.array_equal(a, b)
        for a, b in ((hand.t_ns, eye.t_ns), (hand.p_xyz, eye.p_xyz), (hand.q_xyzw, eye.q_xyzw))
    ):
        msg = (
            f'{hand.name} and {eye.name} hold the same {len(hand)} poses: the hand is the MoCap '
            "stream and the eye the device's own VO/VIO estimate of the same recording"
        )
        raise InputError(msg)
    if cfg.invert_hand:
        hand = reread(hand, 'inverse')
    if cfg.invert_eye:
        eye = reread(eye, 'inverse')
    found = Findings()
    if cfg.check_conventions:
        hand, eye, corrections = check_stamp_units(hand, eye)
        found = Findings.corrected(corrections)
    note = epoch_note(hand, eye)
    if note:
        found = found + Findings.warned(note, noted=True)
    if is_keyframe_only(eye):
        eye = replace(eye, keyframes=True)
        step = np.diff(eye.t_ns) * 1e-9
        note = (
            f'{eye.name} holds keyframes only ({len(eye)} poses, {np.median(step):.2f} s apart '
            f'at the median, up to {step.max():.2f} s): the time offset comes from the '
            'rotation angles over keyframe pairs (screw congruence), not from the angular-speed '
            'correlation; no drift windows'
        )
        found = found + Findings.warned(note, noted=True)
    return hand, eye, found


@dataclass(frozen=True)
class Screened:
    """What screening removed from a stream (``report``), and the damaged rows among them
    described (``damage``; empty when none)."""

    report: Screening
    damage: str


def screen_streams(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig
) -> tuple[Trajectory, Trajectory, tuple[Screened, Screened]]:
    """Both streams screened (see :mod:`.checks.screening`); refuse a stream that would lose too much."""
    if not cfg.screening:
        return (
            hand,
            eye,
            (
                Screened(Screening('hand', len(hand), np.zeros(0, np.int64), ()), ''),
                Screened(Screening('eye', len(eye), np.zeros(0, np.int64), ()), ''),
            ),
        )
    out, screened = [], []
    for traj, stream in ((hand, 'hand'), (eye, 'eye')):
        kept, rep = screen(traj, stream, cfg.outlier_threshold)
        wrecked = damaged(traj)
        damage = describe_damage(traj, wrecked) if wrecked.any() else ''
        check_fraction(rep, traj, cfg, damage)
        out.append(kept)
        screened.append(Screened(rep, damage))
    return out[0], out[1], (screened[0], screened[1])


def check_fraction(
    rep: Screening, traj: Trajectory, cfg: CalibrationConfig, damage: str = ''
) -> None:
    """Refuse a stream screening finds too much of wrong; damaged rows are named first. Poses
    in segments too short to use between breaks (a VI-SLAM's loop closures) and placeholders
    (no pose written) are missing, not wrong, and do not count."""
    if rep.fraction > cfg.max_outlier_fraction:
        wrong = {k: v for k, v in rep.counts.items() if v and k in ('damaged', 'outlier')}
        counts = ', '.join(f'{v} {k.replace("_", " ")}' for k, v in wrong.items())
        msg = (
            (
                f'{damage}. Without them too little of the stream is left: screening would remove '
                f'{rep.fraction:.1%} of it ({counts}), more than max_outlier_fraction '
                f'{cfg.max_outlier_fraction:.0%}. Repair or re-export the file'
            )
            if damage
            else (
                f'{traj.name}: screening would remove {rep.fraction:.1%} of the {rep.stream} '
                f'stream ({counts}), more than max_outlier_fraction '
                f'{cfg.max_outlier_fraction:.0%}: the stream is not what the tool expects '
                f'(check that it holds the {"MoCap" if rep.stream == "hand" else "VIO"} poses '
                'of this recording), or raise max_outlier_fraction / outlier_threshold'
            )
        )
        raise InputError(msg)
