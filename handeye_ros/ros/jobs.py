"""The calibrator's worker jobs (run in :mod:`.worker`'s processes, so no rclpy here): a
calibration of a snapshot of the buffers, with its outputs.

It calls the application (:mod:`handeye_ros.app.request`) as the offline tool does; what comes
back to the node is small: the result without its poses and the paths drawn in RViz.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from ..app.request import Request, run, write_outputs

if TYPE_CHECKING:  # imported where used: a worker starts without the core's modules
    from ..core.arrays import Floats, Stamps
    from ..core.document import ResultDoc
    from ..core.result import CalibrationResult
    from ..stream.recorder import Snapshot

#: A path to draw: stamps [int64 ns, eye clock], positions (N, 3) [m], x y z w quaternions (N, 4).
Path3D = tuple['Stamps', 'Floats', 'Floats']


@dataclass(frozen=True)
class Calibrated:
    """A calibration as the node keeps it between ``~/calibrate`` and ``~/save``: the result
    dictionary as ``~/save`` writes it, the result without its poses
    (:meth:`~handeye_ros.core.result.CalibrationResult.detached`: an hour of MoCap is too large
    to send back from the worker) and its frame names (see StreamConfig.frames)."""

    document: ResultDoc
    result: CalibrationResult
    frames: dict[str, str]
    #: 'eye' and 'ground_truth' (the hand in the eye's world and clock, T_WG T_GH(t - dt)
    #: T_HE), each (stamps int64 ns on the eye clock, p (N, 3), q (N, 4) x y z w), at most
    #: MAX_PATH_POSES poses, in the eye's world frame; empty without an evaluation
    paths: dict[str, Path3D] = field(default_factory=dict)

    @property
    def summary(self) -> str:
        return self.document['summary']

    @property
    def report(self) -> str | None:
        """The report page drawn with the calibration, or None."""
        return self.document.get('files', {}).get('report')

    @property
    def staged_dir(self) -> str | None:
        """The folder where the worker drew the report, if it did (``~/save`` copies it)."""
        return str(Path(self.report).parent) if self.report else None

    @property
    def rig_said(self) -> str:
        """What the result's rig (rig_file) rests on, for the ~/calibrate answer and the log."""
        rig = self.document.get('rig') or {}
        if 'file' not in rig:
            return ''
        if rig['part'] == 'left out':
            return (
                f'; this session is left out of the rig ({rig["file"]}): its own T_HE is published'
            )
        return (
            f'; T_HE of the rig of {rig["recordings"]} recording(s) in {rig["file"]} '
            f'({rig["part"]})'
        )


def calibrate_buffers(
    snapshot: Snapshot,
    options: Mapping[str, object],
    report_dir: str | None = None,
    rig: tuple[str, str] | None = None,
) -> Calibrated:
    """The node's worker job: :func:`run` on a snapshot of the buffers, with the evaluation,
    and with ``report_dir`` the report drawn there, ready for ``~/save`` to copy. With ``rig``
    (the rig file, this session's name) the session joins the rig file
    (:func:`handeye_ros.app.rig.join_rig`) and the result is at the rig's T_HE."""
    req = Request(
        snapshot=snapshot,
        options=options,
        report=report_dir,
        progress=False,
        source='parameters',
        outputs_required=False,
    )
    if rig is None:
        out, result = run(req)
    else:
        from dataclasses import replace

        from ..app.rig import Own, join_rig

        out, result = run(replace(req, evaluation=False, report=None))
        out, result = join_rig(
            *rig,
            Own(rig[1], out, result),
            lambda doc, at: write_outputs(req, at, doc, snapshot.frames),
        )
    return Calibrated(out, result.detached(), snapshot.frames, _paths(result))


#: The node's paths hold at most this many poses (RViz draws a few thousand at ease).
MAX_PATH_POSES = 2000


def _paths(result: CalibrationResult) -> dict[str, Path3D]:
    """The eye's path and the calibrated ground truth's (see :class:`Calibrated`)."""
    from ..core.geometry import quat_from_matrix
    from ..evaluation.aligned import calibrated

    try:
        al = calibrated(result)
    except ValueError:
        return {}
    k = slice(None, None, max(1, -(-len(al) // MAX_PATH_POSES)))
    return {
        'eye': (al.t_ns[k], al.p_est[k], quat_from_matrix(al.R_est[k])),
        'ground_truth': (al.t_ns[k], al.p_ref[k], quat_from_matrix(al.R_ref[k])),
    }
