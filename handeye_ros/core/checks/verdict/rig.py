"""The rig's verdict (the second table of the package docstring): from the groups of
:mod:`..consistency`, the joint T_HE's precision and held directions, and, for purpose
evaluation, the figures of the recordings evaluated at the rig's T_HE."""

from __future__ import annotations

from .codes import EVALUATION_SHARE, Code, Purpose, Quality, Reason

EXTRINSIC_ONLY = frozenset({Purpose.EXTRINSIC})


def assess_rig(
    names: list[str],
    groups: tuple[tuple[int, ...], ...],
    why_not: dict[str, str],
    precision: tuple[tuple[float, float], tuple[float, float]] | None = None,
    held: str = '',
    purpose: Purpose = Purpose.EVALUATION,
) -> Quality:
    """The rig's verdict for ``purpose`` (the second table of the module docstring):
    ``names`` of the recordings that gave a calibration, their ``groups`` (largest first), and
    ``why_not`` the others' reasons; the messages of the left-out ones come with
    :mod:`.consistency`'s tests. ``precision``: the joint T_HE's 1-sigmas (translation's norm
    [m], rotation's [deg]) and the targets its recordings required (the strictest), when
    known; ``held``: the directions of T_HE no recording determines, in words. Until
    :func:`judge_rig_figures` reads the recordings' figures, the extrinsic's rules stand in
    for the evaluation's (as for one recording, :class:`.codes.Quality`)."""
    reasons = [
        Reason(Code.RECORDING_LEFT_OUT, f'{name}: left out, {why}')
        for name, why in why_not.items()
    ]
    notes = []
    if held:
        said = (
            f"the rig's T_HE does not determine {held}: every recording it rests on turned "
            "about that one axis; it keeps the first recording's value there, on which no "
            'APE/RPE figure depends (the world alignment absorbs it)'
        )
        reasons.append(Reason(Code.UNOBSERVABLE, said, EXTRINSIC_ONLY))
        notes.append(
            f"held: {held}, at the first recording's value (held_lever_arm; no APE/RPE figure "
            'depends on it)'
        )
    if precision is not None:
        reasons += _imprecise(*precision)
    reasons += _agreement(names, groups, why_not)
    return Quality.from_reasons(reasons, notes, purpose)


def _imprecise(sigmas: tuple[float, float], need: tuple[float, float]) -> list[Reason]:
    """Purpose extrinsic's rule: the joint T_HE's 1-sigmas (translation [m], rotation [deg])
    against the strictest targets of its recordings."""
    over = [
        f'{label} {v:.3g} {unit} (required {n:.3g})'
        for label, v, n, unit in (
            ('translation', sigmas[0] * 1e3, need[0] * 1e3, 'mm'),
            ('rotation', sigmas[1], need[1], 'deg'),
        )
        if v > n
    ]
    if not over:
        return []
    text = (
        "the rig's 1-sigma exceeds the precision its recordings required: "
        + '; '.join(over)
        + ' (each recording that agrees narrows it about as the square root of their number)'
    )
    return [Reason(Code.IMPRECISE, text, EXTRINSIC_ONLY)]


def _agreement(
    names: list[str], groups: tuple[tuple[int, ...], ...], why_not: dict[str, str]
) -> list[Reason]:
    """No group the largest to agree, or several groups (a moved marker)."""
    reasons = []
    main = groups[0] if groups else ()
    # one recording alone is a rig of one (the node's first session): nothing to disagree with
    alone = len(names) == 1 and not why_not
    if not alone and (len(main) < 2 or sum(len(g) == len(main) for g in groups) > 1):
        said = ' and '.join(
            '{' + ', '.join(names[k] for k in g) + '}' for g in groups if len(g) == len(main)
        )
        reasons.append(
            Reason(
                Code.NO_AGREEMENT,
                'no group of recordings is the largest to agree on T_HE'
                + (f': {said}' if said else ''),
            )
        )
    if sum(len(g) > 1 for g in groups) > 1:
        said = '; '.join(', '.join(names[k] for k in g) for g in groups if len(g) > 1)
        reasons.append(
            Reason(
                Code.GROUPS,
                f'the recordings form {sum(len(g) > 1 for g in groups)} groups that agree '
                f'within themselves, not with each other (a moved marker?): {said}; the '
                "rig's T_HE is the first group's, each group's is reported",
            )
        )
    return reasons


def judge_rig_figures(
    quality: Quality, unsettled: dict[str, str], judged: int, taking: int
) -> Quality:
    """The rig's ``quality`` with purpose evaluation's rule: the rig's T_HE is precise enough
    when the calibration's 1-sigma on every figure of the recordings that take it is at most
    EVALUATION_SHARE of the figure. ``judged`` of the ``taking`` recordings had their figures
    judged at the rig's T_HE (the others' poses are not at hand: the node's earlier
    sessions); ``unsettled``: those whose figures it leaves unsettled, by name, with what their
    results say."""
    reasons = [
        Reason(
            Code.IMPRECISE,
            f"at the rig's T_HE the calibration's 1-sigma exceeds {EVALUATION_SHARE:.0%} of "
            f'a figure of {name}: {said}',
            frozenset({Purpose.EVALUATION}),
        )
        for name, said in unsettled.items()
    ]
    notes = []
    if judged < taking:
        notes.append(
            f"the evaluation's figures at the rig's T_HE are judged for {judged} of the "
            f'{taking} recordings that take it (the others are not at hand)'
        )
    return quality.with_evaluation(reasons, notes)
