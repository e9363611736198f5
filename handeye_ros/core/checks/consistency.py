"""Do a rig's recordings agree on T_HE? Groups of recordings that do, and who is left out.

A recording's T_HE is tested against the joint T_HE of the *others* (leave one out, so that the
two errors are independent): ``chi2 = d^T (C_i + C_others)^-1 d`` with d the difference
(:func:`..rig.chi2_against`), 6 degrees of freedom (fewer by a direction either holds: a
ground robot's lever arm along its only rotation axis is no test of agreement). The threshold
keeps the chance of naming any recording of a consistent rig at FAMILY_FALSE_ALARM, whatever
the count (Bonferroni).

:func:`split` finds the groups: the recording that disagrees most leaves the set while any
disagrees, then each one left out rejoins if it agrees with what remains; what is left out is
searched for a group of its own in the same way. A marker moved between two sessions gives two
groups, which are reported as such (the verdict's rig rules), never averaged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from ..rig import Joint, Member, chi2_against, fuse

#: The chance that a rig whose recordings all agree has one of them named (Gaussian errors).
FAMILY_FALSE_ALARM = 0.01
DOF = 6


def threshold(n: int, dof: int = DOF) -> float:
    """The chi-square (``dof`` degrees of freedom) above which one of ``n`` recordings is
    said to disagree."""
    return float(chi2.isf(FAMILY_FALSE_ALARM / max(n, 1), dof))


@dataclass(frozen=True)
class Test:
    """One recording against a joint T_HE without it: chi2 with its degrees of freedom (6,
    fewer by the directions either holds) and the difference [mm], [deg]."""

    chi2: float
    translation_mm: float
    rotation_deg: float
    dof: int = DOF

    @classmethod
    def of(cls, member: Member, others: Joint) -> Test:
        c, dof, d = chi2_against(member, others)
        return cls(
            c,
            float(np.linalg.norm(d[:3]) * 1e3),
            float(np.degrees(np.linalg.norm(d[3:]))),
            dof,
        )

    def excess(self, n: int) -> float:
        """chi2 over the threshold of its degrees of freedom among ``n`` recordings (above 1:
        it disagrees)."""
        return self.chi2 / threshold(n, self.dof)


@dataclass(frozen=True)
class Split:
    """The groups of agreeing recordings (indices into the members), largest first, and each
    recording's test against the first group's joint T_HE (without it; None for the only
    member of a group of one)."""

    groups: tuple[tuple[int, ...], ...]
    tests: tuple[Test | None, ...]
    threshold: float


def _test(members: Sequence[Member], i: int, group: Sequence[int]) -> Test | None:
    """Member i against the others of ``group`` fused (None: no others)."""
    others = [members[k] for k in group if k != i]
    return Test.of(members[i], fuse(others)) if others else None


def _excess(members: Sequence[Member], i: int, group: Sequence[int]) -> float:
    """:func:`_test`'s :meth:`Test.excess`, for a group with others than i."""
    test = _test(members, i, group)
    assert test is not None, 'the group has others'
    return test.excess(len(members))


def _agreeing(members: Sequence[Member], candidates: list[int]) -> list[int]:
    """The largest set of ``candidates`` that agree: the worst leaves while any disagrees,
    then those left out rejoin when they agree with the rest."""
    kept = list(candidates)
    out: list[int] = []
    while len(kept) > 1:
        scores = [_excess(members, i, kept) for i in kept]
        worst = int(np.argmax(scores))
        if scores[worst] <= 1.0:
            break
        out.append(kept.pop(worst))
    changed = True
    while changed and out:
        changed = False
        joint = fuse([members[k] for k in kept])
        for i in list(out):
            if Test.of(members[i], joint).excess(len(members)) <= 1.0:
                out.remove(i)
                kept.append(i)
                changed = True
                break
    return sorted(kept)


def split(members: Sequence[Member]) -> Split:
    """Groups of agreeing recordings (module docstring)."""
    limit = threshold(len(members))
    left = list(range(len(members)))
    groups = []
    while left:
        group = _agreeing(members, left)
        groups.append(tuple(group))
        left = [k for k in left if k not in group]
    groups.sort(key=lambda g: (-len(g), g))
    tests = tuple(_test(members, i, groups[0]) for i in range(len(members)))
    return Split(tuple(groups), tests, limit)
