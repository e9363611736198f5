"""Result files: a calibration result as YAML or JSON (``~/save``, ``offline_calibrate -o``),
and read back (``publish_calibration``)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import cast

import yaml

from ..core.document import ResultDoc
from ..core.errors import InputError


def write_result(path: str | Path, data: Mapping[str, object]) -> None:
    """Write a result document (or the rig's) as JSON (``.json``) or YAML (anything else)."""
    path = Path(path)
    try:
        with path.open('w') as f:
            if path.suffix.lower() == '.json':
                json.dump(data, f, indent=2)
                f.write('\n')
            else:
                yaml.safe_dump(data, f, sort_keys=False, default_flow_style=None)
    except OSError as err:
        raise InputError(f'{path}: cannot write the result ({err.strerror})') from None


def check_result_path(path: str | Path) -> None:
    """InputError unless a result can be written to ``path`` (not a folder, in a folder that
    exists): said before a calibration, not after it."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f'{path}: cannot write the result (it is a folder)')
    if not path.parent.is_dir():
        raise InputError(f'{path}: cannot write the result (no folder {path.parent})')


def read_result(path: str | Path) -> ResultDoc:
    """A result file written by :func:`write_result` (``~/save``, ``offline_calibrate -o``).

    Raises InputError naming what is missing when the file is no such result."""
    path = Path(path)
    try:
        data = yaml.safe_load(path.read_text())  # YAML reads JSON too
    except OSError as err:
        raise InputError(f'{path}: cannot read ({err.strerror})') from None
    except yaml.YAMLError as err:
        raise InputError(f'{path}: not YAML or JSON ({str(err).splitlines()[0]})') from None
    e = data.get('extrinsic') if isinstance(data, dict) else None
    try:
        ok = (
            isinstance(e, dict)
            and isinstance(e['parent'], str)
            and isinstance(e['child'], str)
            and len(e['translation']) == 3
            and len(e['rotation']) == 4
            and all(isinstance(v, (int, float)) for v in [*e['translation'], *e['rotation']])
            and isinstance(data['time_offset'], (int, float))
            and isinstance(data['time_offset_ns'], int)
        )
    except (KeyError, TypeError):
        ok = False
    if not ok:
        raise InputError(
            f'{path}: not a handeye_ros result (needs extrinsic.parent, child, '
            'translation [3], rotation [4], time_offset and time_offset_ns, as '
            '~/save and offline_calibrate -o write them)'
        )
    return cast(ResultDoc, data)  # the keys read back checked above
