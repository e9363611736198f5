"""The calibrator's /diagnostics: one status per stream (rate, buffered, rejected) and one for
the calibration (the last attempt's outcome, and only then the numbers of the result the latched
topics hold)."""

from __future__ import annotations

import math
from collections.abc import Mapping

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from ..core.checks.verdict import Verdict
from ..core.document import RigPartDoc, StatusDoc
from ..formats import messages
from ..stream.buffer import BufferStats
from .jobs import Calibrated

#: A stream with no message for this long (s) has stopped (wall time: it holds under simulated
#: time too).
STOPPED_S = 2.0


def stream_status(
    name: str, stream: str, s: BufferStats, topic: str, msgtype: str, quiet_s: float = 0.0
) -> DiagnosticStatus:
    """One stream's status: WARN without data, with rejected messages or stopped (no message
    for ``quiet_s`` > STOPPED_S of wall time: its rate now is 0), OK with its rate."""
    st = DiagnosticStatus(name=f'{name}: {stream} stream', hardware_id=name)
    rejected = sum(s.rejected.values())
    stopped = s.stored >= 2 and quiet_s > STOPPED_S
    rate_now = 0.0 if stopped else s.rate_hz
    if stopped:
        st.level = DiagnosticStatus.WARN
        st.message = f'stopped: no message for {quiet_s:.0f} s ({s.rate_hz:.1f} Hz before)'
    elif s.stored < 2 and rejected:
        kinds = ', '.join(f'{v} {k.replace("_", " ")}' for k, v in s.rejected.items() if v)
        st.level = DiagnosticStatus.WARN
        st.message = f'no usable data: every message was rejected ({kinds})'
    elif s.stored < 2:
        st.level, st.message = DiagnosticStatus.WARN, 'no data'
    elif rejected:
        st.level, st.message = DiagnosticStatus.WARN, f'{rejected} messages rejected'
    else:
        st.level, st.message = DiagnosticStatus.OK, f'{s.rate_hz:.1f} Hz'
    st.values = [
        KeyValue(key=k, value=str(v))
        for k, v in (
            ('topic', topic),
            ('type', msgtype),
            ('rate_hz', f'{rate_now:.2f}'),
            ('seconds_since_last_message', f'{quiet_s:.1f}'),
            ('buffered_span_s', f'{s.span_s:.2f}'),
            ('received', s.received),
            ('buffered', s.stored),
            ('dropped', s.dropped),
            *((f'rejected_{k}', v) for k, v in s.rejected.items()),
        )
    ]
    return st


def result_status(
    name: str,
    session: Calibrated | None,
    when: str,
    error: str | None,
    calibrating_s: float | None = None,
) -> DiagnosticStatus:
    """The diagnostics of the calibration: the last attempt's outcome, and only then the
    numbers of the result the latched topics hold.

    - A calibration running (``calibrating_s``: for how long): OK, ``calibrating``; the values
      still describe the result the latched topics hold.
    - No calibration yet: OK.
    - The last attempt failed: ERROR with its reason. The numbers of an earlier result are not
      shown; ``latched_outputs`` says they are stale and where they come from.
    - The last attempt succeeded: the verdict's level (good OK, doubtful WARN, failed ERROR)
      and the result's numbers.
    """
    st = DiagnosticStatus(name=f'{name}: result', hardware_id=name)
    if error is not None:
        st.level, st.message = DiagnosticStatus.ERROR, error[:500]
        if calibrating_s is not None:
            st.message = f'calibrating ({calibrating_s:.1f} s); the last attempt failed: {error}'
            st.message = st.message[:500]
        stale = (
            'none'
            if session is None
            else f'stale: from the calibration of {when} ({session.result.quality.verdict}); '
            'the latest one failed'
        )
        st.values = [KeyValue(key='latched_outputs', value=stale)]
        return st
    if session is None:
        st.level, st.message = DiagnosticStatus.OK, 'no calibration yet'
        if calibrating_s is not None:
            st.message = f'calibrating ({calibrating_s:.1f} s)'
        return st
    q = session.result.quality
    st.level = {
        Verdict.GOOD: DiagnosticStatus.OK,
        Verdict.DOUBTFUL: DiagnosticStatus.WARN,
        Verdict.FAILED: DiagnosticStatus.ERROR,
    }[q.verdict]
    st.message = session.summary[:500]
    if calibrating_s is not None:
        st.message = f'calibrating ({calibrating_s:.1f} s); the last result: ' + st.message[:400]
    st.values = _result_values(session, when)
    return st


def _result_values(session: Calibrated, when: str) -> list[KeyValue]:
    """The numbers of a result, as the latched topics hold them, and where they come from."""
    r, q = session.result, session.result.quality
    pub = messages.Published.from_result(r, session.frames)
    return [
        KeyValue(key=k, value=str(v))
        for k, v in (
            ('verdict', q.verdict),
            ('reasons', '; '.join(f'{x.code}: {x.message}' for x in q.reasons)),
            ('time_offset_s', pub.time_offset_s),
            ('translation_m', [float(v) for v in pub.translation]),
            ('rotation_xyzw', [float(v) for v in pub.rotation]),
            ('inliers', f'{r.linear.n_inliers}/{r.linear.n_motions}'),
            ('peak_correlation', _finite(r.time_alignment.peak_correlation)),
            ('ape_rmse_m', r.metrics.ape_rmse_m),
            ('warnings', len(r.warnings)),
            ('latched_outputs', f'current: from the calibration of {when}'),
            *_rig_values(session.document.get('rig')),
        )
    ]


def _rig_values(rig: RigPartDoc | None) -> list[tuple[str, object]]:
    """What a session's rig (the node's rig_file) rests on, when it has one."""
    if not rig or 'file' not in rig:
        return []
    return [
        ('rig_file', rig['file']),
        ('rig_part', rig['part']),
        ('rig_recordings', rig['recordings']),
        ('rig_verdict', rig['verdict']),
    ]


def _finite(x: float) -> float | None:
    """As the result file writes it: an unknown value (NaN) is None."""
    return float(x) if math.isfinite(x) else None


def readiness_status(name: str, ready: StatusDoc | None, why_not: str | None) -> DiagnosticStatus:
    """The readiness while recording (``~/status`` and /diagnostics): OK when ready, WARN with
    the first thing to do otherwise; the values are the status's
    (:class:`~handeye_ros.core.checks.readiness.Readiness`) flattened (``sigma.translation_mm``,
    ``rotation_deg.z``, ``missing.1``, ...)."""
    st = DiagnosticStatus(name=f'{name}: readiness', hardware_id=name)
    if ready is None:
        st.level, st.message = DiagnosticStatus.WARN, why_not or 'waiting for data'
        return st
    st.level = DiagnosticStatus.OK if ready['ready'] else DiagnosticStatus.WARN
    st.message = 'READY' if ready['ready'] else (ready['missing'] or ['not ready'])[0][:500]
    st.values = [KeyValue(key=k, value=str(v)) for k, v in _flat(ready)]
    return st


def _flat(d: Mapping[str, object], prefix: str = '') -> list[tuple[str, object]]:
    out: list[tuple[str, object]] = []
    for k, v in d.items():
        key = f'{prefix}{k}'
        if isinstance(v, Mapping):
            out += _flat(v, key + '.')
        elif isinstance(v, list):
            out += [(f'{key}.{i + 1}', x) for i, x in enumerate(v)]
        else:
            out.append((key, v))
    return out
