"""A rig's calibration from its recordings' own (:mod:`.rig`), and each recording's result
with the rig's T_HE.

:func:`solve_rig` is the recipe: each recording's own calibration (the pipeline, alone) gives a
:class:`.rig.Member`; :func:`.checks.consistency.split` groups those that agree; the largest
group's members are fused into the rig's T_HE; each recording's own parameters are conditioned
on it; :func:`.checks.verdict.assess_rig` gives the verdict.

:func:`at_shared`: the recording keeps its poses, screening, eye model (drift, scale) and
verdict; its T_HE becomes the rig's, its offset the one conditioned on it
(:func:`.rig.conditioned`), and what follows from both is computed again: the world alignment
T_WG (eye segments each their own), the metrics and the keyframe motions' agreement. The batch
covariance becomes the joint problem's (:attr:`.rig.Conditioned.covariance`), so the result's
sigmas are the rig's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from .association import associate
from .checks.consistency import Split, Test, split, threshold
from .checks.verdict import Purpose, Quality, assess_rig, motion_inconsistency
from .pipeline import metrics_at
from .result import CalibrationResult
from .rig import HELD_PART, Conditioned, Joint, Member, conditioned, fuse
from .world import align_worlds


@dataclass(frozen=True)
class Rig:
    """A rig's calibration.

    joint: the shared T_HE (of the members in ``split.groups[0]``); members: the recordings
    that gave a calibration with a covariance, in the given order; split: their groups and
    tests; shared: each member's own parameters conditioned on the joint T_HE (None for one
    left out); followers: recordings that gave an offset but no T_HE with a covariance (a
    motion that leaves part of it unobservable): they take the rig's T_HE and add nothing to
    it; why_not: the recordings left out by name, with the reason; quality: the rig's verdict.
    """

    joint: Joint | None
    members: tuple[Member, ...]
    split: Split | None
    shared: tuple[Conditioned | None, ...]
    followers: tuple[str, ...]
    why_not: dict[str, str]
    quality: Quality

    def leaving_out(self, why_not: dict[str, str]) -> Rig:
        """The same rig with more recordings left out (followers whose motions the rig's T_HE
        does not explain, found once their poses were at hand)."""
        out = {**self.why_not, **why_not}
        groups = self.split.groups if self.split else ()
        return replace(
            self,
            followers=tuple(f for f in self.followers if f not in why_not),
            why_not=out,
            quality=_assess(self.joint, self.members, groups, out, self.quality.purpose),
        )

    @property
    def used(self) -> tuple[str, ...]:
        return tuple(self.members[k].name for k in self.split.groups[0]) if self.split else ()

    def group_joints(self) -> list[Joint]:
        """Each group's own joint T_HE, largest group first."""
        if self.split is None or self.joint is None:
            return []
        rest = [fuse([self.members[k] for k in g]) for g in self.split.groups[1:]]
        return [self.joint, *rest]


def solve_rig(
    members: list[Member],
    failed: dict[str, str],
    followers: tuple[str, ...] = (),
    purpose: Purpose = Purpose.EVALUATION,
) -> Rig:
    """The rig from its recordings' calibrations (``failed``: those that gave none, by name,
    with the reason; ``followers``: see :class:`Rig`), its verdict judged for ``purpose``:
    the module docstring's recipe."""
    why_not = dict(failed)
    if not members:
        why_not |= {f: 'no recording gave the T_HE it could take' for f in followers}
        quality = assess_rig([], (), why_not, purpose=purpose)
        return Rig(None, (), None, (), (), why_not, quality)
    s = split(members)
    main = s.groups[0]
    joint = fuse([members[k] for k in main])
    for k, (m, t) in enumerate(zip(members, s.tests, strict=True)):
        if k not in main:
            why_not[m.name] = _disagrees(t, len(members), len(main))
    shared = tuple(conditioned(m, joint) if k in main else None for k, m in enumerate(members))
    quality = _assess(joint, members, s.groups, why_not, purpose)
    return Rig(joint, tuple(members), s, shared, tuple(followers), why_not, quality)


def _assess(
    joint: Joint | None,
    members: Sequence[Member],
    groups: tuple[tuple[int, ...], ...],
    why_not: dict[str, str],
    purpose: Purpose,
) -> Quality:
    names = [m.name for m in members]
    precision = _precision(joint, members, groups)
    held = '' if joint is None else _held_words(joint)
    return assess_rig(names, groups, why_not, precision, held, purpose)


def _held_words(joint: Joint) -> str:
    """The joint T_HE's held directions in words ('' when it determines all six)."""
    said = []
    for v in joint.held.T:
        t, r = v[:3], v[3:]
        axis = t if np.linalg.norm(t) >= np.linalg.norm(r) else r
        axis = axis / np.linalg.norm(axis)
        words = ' '.join(f'{c:+.3f}' for c in axis)
        if np.linalg.norm(r) < HELD_PART:
            said.append(f'the translation along [{words}] (hand frame)')
        elif np.linalg.norm(t) < HELD_PART:
            said.append(f'the rotation about [{words}] (eye frame)')
        else:
            said.append(f'a direction mixing translation and rotation, mostly [{words}]')
    return ' and '.join(said)


def _precision(
    joint: Joint | None, members: Sequence[Member], groups: tuple[tuple[int, ...], ...]
) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """The joint T_HE's 1-sigmas (translation's norm [m], rotation's [deg]) and the strictest
    targets of the recordings it rests on, for :func:`.checks.verdict.assess_rig`; None
    without a joint T_HE or any recording's targets."""
    needs = [m.precision for k, m in enumerate(members) if groups and k in groups[0]]
    known = [n for n in needs if n is not None]
    if joint is None or not known:
        return None
    sd = joint.std
    sigmas = (float(np.linalg.norm(sd[:3])), float(np.degrees(np.linalg.norm(sd[3:]))))
    return sigmas, (min(n[0] for n in known), min(n[1] for n in known))


def _disagrees(test: Test | None, n: int, n_main: int) -> str:
    if test is None:
        return 'no other recording to compare it with'
    limit = threshold(n, test.dof)
    return (
        f'its T_HE is {test.translation_mm:.1f} mm and {test.rotation_deg:.2f} deg from the '
        f'{n_main} that agree (chi-square {test.chi2:.1f} '
        f'{">" if test.chi2 > limit else "<="} {limit:.1f}, {test.dof} dof, with both '
        'covariances)'
    )


def at_shared(result: CalibrationResult, joint: Joint, member: Member | None) -> CalibrationResult:
    """``result`` (a recording's own) at the rig's T_HE ``joint``: its offset conditioned on it
    when ``member`` (made of ``result``) is given, else (a follower) its own offset. Its verdict
    fails when AX = XB does not hold at the rig's T_HE over its keyframe motions."""
    used = result.used
    if used is None:
        raise ValueError('this result does not hold the streams it was computed on')
    given = None if member is None else conditioned(member, joint)
    delta = 0.0 if given is None else given.values['time_offset'] - result.time_offset_s
    dt = used.time_offset_s + delta
    q, p = joint.q_HE, joint.p_HE
    pairs = associate(used.hand, used.eye, dt)
    world = align_worlds(pairs, q, p)
    metrics = metrics_at(used.hand, used.eye, pairs, world, (dt, q, p), result.config.eta)
    batch = result.batch
    if given is not None and batch is not None:
        cov = given.covariance
        batch = replace(batch, covariance=cov, std=np.sqrt(np.diag(cov)))
    quality = result.quality
    unfit = motion_inconsistency(metrics, "the rig's T_HE")
    if unfit is not None:
        quality = Quality.from_reasons([*quality.reasons, unfit], list(quality.notes))
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
        quality=quality,
        used=replace(used, time_offset_s=dt),
    )
