"""The rig's verdict (the second table of the package docstring): from the groups of
:mod:`..consistency`."""

from __future__ import annotations

from .codes import Code, Quality, Reason


def assess_rig(
    names: list[str],
    groups: tuple[tuple[int, ...], ...],
    why_not: dict[str, str],
    precision: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> Quality:
    """The rig's verdict (the second table of the module docstring): ``names`` of the
    recordings that gave a calibration, their ``groups`` (largest first), and ``why_not`` the
    others' reasons; the messages of the left-out ones come with :mod:`.consistency`'s tests.
    ``precision``: the joint T_HE's 1-sigmas (translation's norm [m], rotation's [deg]) and the
    targets its recordings required (the strictest), when known."""
    reasons = [
        Reason(Code.RECORDING_LEFT_OUT, f'{name}: left out, {why}')
        for name, why in why_not.items()
    ]
    if precision is not None:
        (t, r), (need_t, need_r) = precision
        over = [
            f'{label} {v:.3g} {unit} (required {n:.3g})'
            for label, v, n, unit in (
                ('translation', t * 1e3, need_t * 1e3, 'mm'),
                ('rotation', r, need_r, 'deg'),
            )
            if v > n
        ]
        if over:
            reasons.append(
                Reason(
                    Code.IMPRECISE,
                    "the rig's 1-sigma exceeds the precision its recordings required: "
                    + '; '.join(over)
                    + ' (each recording that agrees narrows it about as the square root of '
                    'their number)',
                )
            )
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
    return Quality.from_reasons(reasons, [])
