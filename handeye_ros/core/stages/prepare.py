"""The streams as the stages use them (:class:`Inputs`): explicit inversions, stamp units read
against the rates, clock epochs named, a keyframe-only eye recognised, each stream screened (a
stream that would lose too much is refused, its damage named first)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..checks.conventions import check_stamp_units, epoch_note
from ..checks.orientations import reread
from ..checks.screening import Screening, damaged, describe_damage, screen
from ..config import CalibrationConfig
from ..errors import InputError
from ..trajectory import Trajectory, TrajectoryInfo, is_keyframe_only
from .findings import Findings


@dataclass(frozen=True)
class Inputs:
    """hand (T_GH), eye (T_WE): the streams after the conventions and screening, each on its
    own clock; screening: what was removed from each (hand, eye); given: the streams as handed
    over, described (names, counts, rates, spans)."""

    hand: Trajectory
    eye: Trajectory
    screening: tuple[Screening, Screening]
    given: tuple[TrajectoryInfo, TrajectoryInfo]


def prepare(hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig, run: Findings) -> Inputs:
    """The inputs of the stages (see the module docstring)."""
    given = (hand.info(), eye.info())
    run.warnings += [*hand.notes, *eye.notes]
    hand, eye = prepare_streams(hand, eye, cfg, run)
    hand, eye, screening = screen_streams(hand, eye, cfg, run)
    return Inputs(hand, eye, screening, given)


def prepare_streams(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig, run: Findings
) -> tuple[Trajectory, Trajectory]:
    """Explicit inversions, stamp units, epochs."""
    if cfg.invert_hand:
        hand = reread(hand, 'inverse')
    if cfg.invert_eye:
        eye = reread(eye, 'inverse')
    if cfg.check_conventions:
        hand, eye, found = check_stamp_units(hand, eye)
        run.corrected(found)
    note = epoch_note(hand, eye)
    if note:
        run.warnings.append(note)
        run.note(note)
    if is_keyframe_only(eye):
        eye = replace(eye, keyframes=True)
        step = np.diff(eye.t_ns) * 1e-9
        note = (
            f'{eye.name} holds keyframes only ({len(eye)} poses, {np.median(step):.2f} s apart '
            f'at the median, up to {step.max():.2f} s): the time offset comes from the '
            'rotation angles over keyframe pairs (screw congruence), not from the angular-speed '
            'correlation; no vector refinement and no drift windows'
        )
        run.warnings.append(note)
        run.note(note)
    return hand, eye


def screen_streams(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig, run: Findings
) -> tuple[Trajectory, Trajectory, tuple[Screening, Screening]]:
    """Both streams screened (see :mod:`.checks.screening`); refuse a stream that would lose too much."""
    if not cfg.screening:
        return (
            hand,
            eye,
            (
                Screening('hand', len(hand), np.zeros(0, np.int64), ()),
                Screening('eye', len(eye), np.zeros(0, np.int64), ()),
            ),
        )
    out, reports = [], []
    for traj, stream in ((hand, 'hand'), (eye, 'eye')):
        kept, rep = screen(traj, stream, cfg.outlier_threshold)
        wrecked = damaged(traj)
        damage = describe_damage(traj, wrecked) if wrecked.any() else ''
        check_fraction(rep, traj, cfg, damage)
        if damage:
            run.warnings.append(f'{damage}; those rows were left out')
        out.append(kept)
        reports.append(rep)
    return out[0], out[1], (reports[0], reports[1])


def check_fraction(
    rep: Screening, traj: Trajectory, cfg: CalibrationConfig, damage: str = ''
) -> None:
    """Refuse a stream screening would take too much of; damaged rows are named first."""
    if rep.fraction > cfg.max_outlier_fraction:
        counts = ', '.join(f'{v} {k.replace("_", " ")}' for k, v in rep.counts.items() if v)
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
