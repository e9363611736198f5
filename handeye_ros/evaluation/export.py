"""evo-ready files: the calibrated ground truth and the estimate as TUM, the extrinsic as evo's
transform JSON.

- ``groundtruth.tum``: ``T_WG T_GH(t - dt) T_HE`` at the eye's stamps, on the eye's clock, in
  the eye's world (see :mod:`.aligned`); ``evo_ape tum groundtruth.tum estimate.tum`` needs no
  ``-a``, no ``--t_offset``.
- ``estimate.tum``: the eye poses those stamps belong to, as the calibration used them (unit and
  convention corrections applied, outliers screened, positions times the scale if one was
  estimated).
- ``T_HE.json`` / ``T_EH.json``: ``{x, y, z, qx, qy, qz, qw}``, evo's transform JSON, so that
  ``evo_traj tum hand.tum --transform_right T_HE.json`` moves the MoCap marker poses onto the
  eye frame (``T_GH T_HE``), and ``--transform_right T_EH.json`` does the reverse for the eye.
- ``export.json``: what the files hold, the offset, scale and segments, for scripts.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from ..core.arrays import Floats, Stamps
from ..core.errors import InputError
from ..core.geometry import inverse, matrix_from_quat, quat_from_matrix
from ..core.result import CalibrationResult
from ..core.trajectory import Trajectory
from ..formats import write_tum
from .aligned import AlignedTrajectories

FILES = ('groundtruth.tum', 'estimate.tum', 'T_HE.json', 'T_EH.json', 'export.json')


def transform_json(R: Floats, p: Floats) -> dict[str, float]:
    """evo's transform JSON of ``(R, p)``: ``{x, y, z, qx, qy, qz, qw}``."""
    q = quat_from_matrix(np.asarray(R, dtype=float))
    return {
        'x': float(p[0]),
        'y': float(p[1]),
        'z': float(p[2]),
        'qx': float(q[0]),
        'qy': float(q[1]),
        'qz': float(q[2]),
        'qw': float(q[3]),
    }


def write_exports(
    directory: str | Path, result: CalibrationResult, cal: AlignedTrajectories
) -> list[Path]:
    """Write :data:`FILES` into ``directory`` (created); returns their paths.

    Raises InputError when the directory cannot be written.
    """
    out = Path(directory)
    try:
        out.mkdir(parents=True, exist_ok=True)
        paths = [out / name for name in FILES]
        gt, est, he, eh, meta = paths
        write_tum(gt, _trajectory(cal.t_ns, cal.R_ref, cal.p_ref, 'groundtruth'))
        write_tum(est, _trajectory(cal.t_ns, cal.R_est, cal.p_est, 'estimate'))
        R_HE = matrix_from_quat(result.q_HE)
        R_EH, p_EH = inverse((R_HE, np.asarray(result.p_HE, dtype=float)))
        _write_json(he, transform_json(R_HE, result.p_HE))
        _write_json(eh, transform_json(R_EH, p_EH))
        _write_json(meta, _meta(result, cal))
    except OSError as err:
        raise InputError(f'{out}: cannot write the exports ({err.strerror or err})') from None
    return paths


def _trajectory(t_ns: Stamps, R: Floats, p: Floats, name: str) -> Trajectory:
    return Trajectory.from_arrays(t_ns, p, quat_from_matrix(R), name=name)


def _write_json(path: Path, data: dict[str, Any]) -> None:
    path.write_text(json.dumps(data, indent=2) + '\n')


def _meta(result: CalibrationResult, cal: AlignedTrajectories) -> dict[str, Any]:
    return {
        'groundtruth.tum': 'T_WG * T_GH(t - dt(t)) * T_HE at the eye stamps t (eye clock), in '
        'the eye world W; each eye segment (between VIO resets) has its own '
        'T_WG',
        'estimate.tum': 'T_WE at the same stamps, as calibrated (corrections and screening '
        'applied' + (', positions times the scale)' if result.scale is not None else ')'),
        'T_HE.json': 'eye frame E in hand frame H (evo transform JSON)',
        'T_EH.json': 'hand frame H in eye frame E (evo transform JSON)',
        'time_offset': float(result.time_offset_s),
        'time_offset_ns': int(result.time_offset_ns),
        'clock_drift': result.clock_drift,
        'scale': result.scale,
        'poses': len(cal),
        'segments': int(np.unique(cal.segment).size),
        'evo': 'evo_ape tum groundtruth.tum estimate.tum  (no -a: already aligned)',
    }
