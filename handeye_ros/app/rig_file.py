"""A rig's file (``offline_calibrate --rig -o``, ``evaluate --shared-extrinsic``'s rig.yaml,
the node's ``rig_file``): the rig's T_HE with its covariance and verdict, its groups, and every
recording's own estimate with its full covariance, so that a file read back is a rig again
(:func:`read_members`)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np

from ..core.errors import ConfigError
from ..core.geometry import matrix_from_quat
from ..core.result_sections import transform_dict
from ..core.rig import Joint, Member
from ..core.rig_document import (
    RigDoc,
    RigExtrinsicDoc,
    RigRecordingDoc,
    RigSectionDoc,
)

if TYPE_CHECKING:  # the rig's solution module imports the rig's math only when solved
    from ..core.rig_pipeline import Rig

#: The rig's result file, beside the per-recording folders.
RIG_FILE = 'rig.yaml'


def rig_document(rig: Rig, frames: tuple[str, str] = ('hand', 'eye')) -> RigDoc:
    """The rig's result file (:data:`RIG_FILE`): its T_HE with covariance, its verdict, its
    groups and every recording's own and conditioned values."""
    names = [m.name for m in rig.members]
    recordings: list[RigRecordingDoc] = [_member(rig, k) for k in range(len(rig.members))]
    recordings += [
        {
            'name': n,
            'used': False,
            'follows': True,
            'reason': "no covariance of its own T_HE: it takes the rig's T_HE and keeps its own "
            'offset',
        }
        for n in rig.followers
    ]
    recordings += [
        {'name': n, 'used': False, 'reason': why}
        for n, why in rig.why_not.items()
        if n not in names
    ]
    joint = rig.joint
    groups = zip(rig.split.groups, rig.group_joints(), strict=True) if rig.split else ()
    return {
        'rig': {
            'quality': rig.quality.to_dict(),
            'extrinsic': None if joint is None else _extrinsic(joint, frames),
            'covariance': None
            if joint is None
            else {
                'order': ['tx', 'ty', 'tz', 'rx', 'ry', 'rz'],
                'matrix': [[float(v) for v in row] for row in joint.covariance],
            },
            'used': list(rig.used),
            'followers': list(rig.followers),
            'left_out': dict(rig.why_not),
            'groups': [
                {'recordings': [names[k] for k in g], 'extrinsic': _extrinsic(j, frames)}
                for g, j in groups
            ],
            'chi2_threshold': None if rig.split is None else rig.split.threshold,
            'method': 'each recording calibrated alone; its T_HE marginal (Schur complement '
            'over its own dt, drift, scale) fused by information; a recording whose T_HE '
            'disagrees with the others beyond the chi-square threshold (6 dof, 1 % for the '
            "whole rig) is left out; each recording's own parameters conditioned on the "
            "rig's T_HE",
            'units': {'translation': 'm', 'rotation': 'x y z w; std: rad, tangent on the right'},
        },
        'recordings': recordings,
    }


def _extrinsic(joint: Joint, frames: tuple[str, str]) -> RigExtrinsicDoc:
    return {
        **transform_dict(matrix_from_quat(joint.q_HE), joint.p_HE, *frames),
        'std': {
            'translation': [float(v) for v in joint.std[:3]],
            'rotation': [float(v) for v in joint.std[3:]],
        },
    }


def _member(rig: Rig, k: int) -> RigRecordingDoc:
    """A member's entry: its own estimate (with the full covariance, read back by
    :func:`read_members`), its test and its values conditioned on the rig's T_HE."""
    m, test, shared = rig.members[k], rig.split.tests[k] if rig.split else None, rig.shared[k]
    return {
        'name': m.name,
        'used': m.name in rig.used,
        'reason': rig.why_not.get(m.name, ''),
        'own': {
            'time_offset': m.values['time_offset'],
            'time_offset_std': float(np.sqrt(m.covariance[0, 0])),
            **m.to_dict(),
        },
        'test': None
        if test is None
        else {
            'chi2': test.chi2,
            'translation_mm': test.translation_mm,
            'rotation_deg': test.rotation_deg,
        },
        'shared': None if shared is None else {'values': shared.values, 'std': shared.std},
    }


def rig_summary(doc: RigDoc) -> str:
    """A few lines for the terminal: the verdict with its reasons, T_HE, the recordings."""
    from ..evaluation.terminal import other_purpose, purpose_words

    r = doc['rig']
    q = r['quality']
    lines = [f'rig: {q["verdict"]} ({len(r["used"])} of {len(doc["recordings"])} recordings)']
    if r['extrinsic']:
        e = r['extrinsic']
        t = ', '.join(f'{v:.4f}' for v in e['translation'])
        rot = ', '.join(f'{v:.4f}' for v in e['rotation'])
        st = e['std']
        lines.append(
            f'  T_HE translation [{t}] m (1-sigma {np.linalg.norm(st["translation"]) * 1e3:.2f} '
            f'mm), rotation [{rot}] x y z w (1-sigma '
            f'{np.degrees(np.linalg.norm(st["rotation"])):.3f} deg)'
        )
    lines.append(f'  judged for {purpose_words(q)}; {other_purpose(q)}')
    lines += [f'  {reason["code"]}: {reason["message"]}' for reason in q['reasons']]
    lines += [f'  note: {note}' for note in q['notes']]
    for rec in doc['recordings']:
        shared = rec.get('shared')
        if shared:
            v, s = shared['values'], shared['std']
            sigma = s.get('time_offset')
            lines.append(
                f'  {rec["name"]}: dt {v["time_offset"] * 1e3:+.3f} ms '
                + (
                    '(follows the rig: no sigma)'
                    if sigma is None
                    else f'(1-sigma {sigma * 1e3:.3f} ms)'
                )
            )
    return '\n'.join(lines)


def part_of(rig: RigSectionDoc, name: str) -> str:
    """A recording's part in a rig (the ``rig`` section of :func:`rig_document`): 'used',
    'follows' or 'left out'."""
    if name in rig['used']:
        return 'used'
    return 'follows' if name in rig['followers'] else 'left out'


def read_members(file: Path, said: str) -> list[Member]:
    """The recordings of a rig file that have an estimate of their own (none when the file
    does not exist); ConfigError naming ``said`` when it is no rig file."""
    if not file.is_file():
        return []
    import yaml

    try:
        recs = cast(RigDoc, yaml.safe_load(file.read_text()))['recordings']
        return [Member.from_dict(r['name'], r['own']) for r in recs if r.get('own')]
    except (OSError, yaml.YAMLError, UnicodeDecodeError):
        why = 'not readable as YAML'
    except (KeyError, TypeError, ValueError, AttributeError):
        why = "no rig's recordings in it"
    raise ConfigError(
        f'rig_file {said}: not a rig file ({why}); give a file that offline_calibrate --rig -o '
        'or this node wrote, or a new path'
    )


def write_rig_file(file: Path, document: RigDoc) -> None:
    """Write a rig document whole or not at all (a node stopped while writing leaves the
    previous file)."""
    from ..formats.result_file import write_result

    tmp = file.with_name(f'.{file.name}.tmp')
    write_result(tmp, document)
    tmp.replace(file)
