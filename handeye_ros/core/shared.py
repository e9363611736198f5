"""A rig's calibration from its recordings' own (:mod:`.rig`), and each recording's result
with the rig's T_HE.

:func:`solve_rig` is the recipe: each recording's own calibration (the pipeline, alone) gives a
:class:`.rig.Member`; :func:`.checks.consistency.split` groups those that agree; the largest
group's members are fused into the rig's T_HE; each recording's own parameters are conditioned
on it; :func:`.checks.verdict.assess_rig` gives the verdict.

:func:`at_shared`: the recording keeps its poses, screening, eye model (drift, scale) and verdict; its T_HE becomes
the rig's, its offset the one conditioned on it (:func:`.rig.conditioned`), and what follows
from both is computed again: the world alignment T_WG (eye segments each their own), the
metrics and the keyframe motions' agreement. The batch covariance becomes the joint problem's
(:func:`.rig.joint_covariance`), so the result's sigmas are the rig's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .association import associate
from .checks.consistency import Split, Test, split
from .checks.selfcheck import motion_consistency
from .checks.verdict import Quality, assess_rig
from .result import CalibrationResult
from .rig import Conditioned, Joint, Member, conditioned, fuse, joint_covariance
from .world import align_worlds, evaluate


@dataclass(frozen=True)
class Rig:
    """A rig's calibration.

    joint: the shared T_HE (of the members in ``split.groups[0]``); members: the recordings
    that gave a calibration, in the given order; split: their groups and tests; shared: each
    member's own parameters conditioned on the joint T_HE (None for one left out); why_not:
    the recordings left out by name, with the reason; quality: the rig's verdict.
    """

    joint: Joint | None
    members: tuple[Member, ...]
    split: Split | None
    shared: tuple[Conditioned | None, ...]
    why_not: dict[str, str]
    quality: Quality

    @property
    def used(self) -> tuple[str, ...]:
        return tuple(self.members[k].name for k in self.split.groups[0]) if self.split else ()

    def group_joints(self) -> list[Joint]:
        """Each group's own joint T_HE, largest group first."""
        if self.split is None:
            return []
        return [fuse([self.members[k] for k in g]) for g in self.split.groups]


def solve_rig(members: list[Member], failed: dict[str, str]) -> Rig:
    """The rig from its recordings' calibrations (``failed``: those that gave none, by name,
    with the reason): the module docstring's recipe."""
    why_not = dict(failed)
    if not members:
        return Rig(None, (), None, (), why_not, assess_rig([], (), why_not))
    s = split(members)
    main = s.groups[0]
    joint = fuse([members[k] for k in main])
    for k, (m, t) in enumerate(zip(members, s.tests, strict=True)):
        if k not in main:
            why_not[m.name] = _disagrees(t, s.threshold, len(main))
    names = [m.name for m in members]
    shared = tuple(conditioned(m, joint) if k in main else None for k, m in enumerate(members))
    return Rig(joint, tuple(members), s, shared, why_not, assess_rig(names, s.groups, why_not))


def _disagrees(test: Test | None, limit: float, n_main: int) -> str:
    if test is None:
        return 'no other recording to compare it with'
    return (
        f'its T_HE is {test.translation_mm:.1f} mm and {test.rotation_deg:.2f} deg from the '
        f'{n_main} that agree (chi-square {test.chi2:.1f} > {limit:.1f}, 6 dof, with both '
        'covariances)'
    )


def at_shared(result: CalibrationResult, member: Member, joint: Joint) -> CalibrationResult:
    """``result`` (the recording's own, of which ``member`` was made) at the rig's T_HE."""
    used = result.used
    if used is None:
        raise ValueError('this result does not hold the streams it was computed on')
    delta = conditioned(member, joint).values['time_offset'] - result.time_offset_s
    dt = used.time_offset_s + delta
    q, p = joint.q_HE, joint.p_HE
    pairs = associate(used.hand, used.eye, dt)
    world = align_worlds(pairs, q, p)
    m_rot, m_trans, m_len, n_mot = motion_consistency(
        used.hand, used.eye, dt, q, p, np.deg2rad(result.config.eta)
    )
    metrics = replace(
        evaluate(pairs, q, p, world),
        motion_rotation_deg=m_rot,
        motion_translation_m=m_trans,
        motion_length_m=m_len,
        n_motions=n_mot,
    )
    cov = joint_covariance(member, joint)
    batch = result.batch and replace(result.batch, covariance=cov, std=np.sqrt(np.diag(cov)))
    return replace(
        result,
        time_offset_s=result.time_offset_s + delta,
        time_offset_ns=result.time_offset_ns + round(delta * 1e9),
        q_HE=q,
        p_HE=p,
        world=world,
        metrics=metrics,
        n_pairs=int(pairs.t_eye_s.size),
        batch=batch,
        used=replace(used, time_offset_s=dt),
    )
