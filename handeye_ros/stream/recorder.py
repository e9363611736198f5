"""The two buffered streams of a calibration session and the one calibration call on them.

The node feeds :meth:`Recorder.add` from its subscriptions; the bag replay feeds it from bag
messages; both then call :meth:`Recorder.calibrate`. Everything between a message and a result
is therefore the same code live and offline.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

from ..core.config import CalibrationConfig
from ..core.errors import InputError
from ..core.pipeline import calibrate
from ..core.result import CalibrationResult
from ..core.trajectory import Trajectory
from .buffer import BufferStats, PoseBuffer
from .config import StreamConfig
from .convert import StampedPose, pose_of

STREAMS = ('hand', 'eye')


@dataclass(frozen=True)
class Snapshot:
    """What a calibration needs from the buffers; plain data, so it can go to another process."""

    hand: Trajectory
    eye: Trajectory
    hand_frame: str
    eye_frame: str
    streams: dict[str, Any]
    warnings: tuple[str, ...]

    def result(self, config: CalibrationConfig,
               progress: Callable[[str], None] | None = None) -> CalibrationResult:
        """Calibrate the snapshot; the streams' dropped/rejected messages join the warnings.
        ``progress``: as :func:`~handeye_ros.core.pipeline.calibrate`'s."""
        result = calibrate(self.hand, self.eye, config, progress)
        return replace(result, warnings=result.warnings + self.warnings)

    def describe(self, result: CalibrationResult) -> dict[str, Any]:
        """The result dictionary (schema of CalibrationResult.to_dict, plus ``streams`` and a
        one-line ``summary``) with this snapshot's frame names."""
        out = result.to_dict(hand_frame=self.hand_frame, eye_frame=self.eye_frame)
        out['streams'] = self.streams
        out['summary'] = result.summary()
        return out

    def calibrate(self, config: CalibrationConfig,
                  progress: Callable[[str], None] | None = None) -> dict[str, Any]:
        """:meth:`result` as :meth:`describe`'s dictionary."""
        return self.describe(self.result(config, progress))


class Recorder:
    """Hand and eye pose buffers with their message converters."""

    def __init__(self, config: StreamConfig):
        self.config = config
        self.buffers = {
            name: PoseBuffer(f'{name} ({getattr(config, name + "_topic")})',
                             config.buffer_size, config.buffer_duration)
            for name in STREAMS}
        self.types: dict[str, str | None] = {name: None for name in STREAMS}
        self._convert: dict[str, Callable[[Any], StampedPose]] = {}

    def set_type(self, stream: str, msgtype: str) -> None:
        """Fix the message type of a stream (raises UnsupportedTypeError)."""
        self._convert[stream] = pose_of(msgtype)
        self.types[stream] = msgtype

    def add(self, stream: str, msg: Any) -> str | None:
        """Convert and buffer one message; returns None or why it was rejected."""
        return self.buffers[stream].add(*self._convert[stream](msg))

    def reset(self) -> None:
        """Empty both buffers and their counters."""
        for b in self.buffers.values():
            b.clear()

    def stats(self) -> dict[str, BufferStats]:
        return {name: b.stats() for name, b in self.buffers.items()}

    def snapshot(self) -> Snapshot:
        """Copies of both buffers and their bookkeeping, to calibrate on while they keep filling.

        Raises InputError when a stream holds fewer than two poses.
        """
        trajectories = {}
        for name, buf in self.buffers.items():
            if len(buf) < 2:
                topic = getattr(self.config, name + '_topic')
                msg = (f'{name} stream {topic}: {len(buf)} pose(s) buffered '
                       f'({buf.received} received, {sum(buf.rejected.values())} rejected); '
                       'need a recording of both streams first')
                raise InputError(msg)
            trajectories[name] = buf.trajectory()
        return Snapshot(trajectories['hand'], trajectories['eye'], self.config.hand_frame_id,
                        self.config.eye_frame_id, self.stream_dict(),
                        tuple(self.stream_warnings()))

    def calibrate(self, config: CalibrationConfig,
                  progress: Callable[[str], None] | None = None) -> dict[str, Any]:
        """Calibrate on a snapshot of the buffers; the result dictionary (see Snapshot.calibrate).

        Raises HandeyeError subclasses with a user-facing reason (e.g. too little data).
        """
        return self.snapshot().calibrate(config, progress)

    def stream_warnings(self) -> list[str]:
        """Dropped or rejected messages, said in the result."""
        out = []
        for name, s in self.stats().items():
            topic = getattr(self.config, name + '_topic')
            if s.dropped:
                out.append(f'{name} stream {topic}: the {s.dropped} oldest poses were dropped '
                           f'(buffer_size {self.config.buffer_size}, buffer_duration '
                           f'{self.config.buffer_duration:g} s)')
            bad = {k: v for k, v in s.rejected.items() if v}
            if bad:
                out.append(f'{name} stream {topic}: rejected messages: '
                           + ', '.join(f'{v} {k.replace("_", " ")}' for k, v in bad.items()))
        return out

    def stream_dict(self) -> dict[str, Any]:
        """Per-stream bookkeeping for the result file."""
        return {name: {'topic': getattr(self.config, name + '_topic'), 'type': self.types[name],
                       'received': s.received, 'buffered': s.stored, 'dropped': s.dropped,
                       'rejected': s.rejected, 'span_s': s.span_s, 'rate_hz': s.rate_hz}
                for name, s in self.stats().items()}
