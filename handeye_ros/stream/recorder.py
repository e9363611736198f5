"""The two buffered streams of a calibration session and the one calibration call on them.

The node feeds :meth:`Recorder.add` from its subscriptions; the bag replay feeds it from bag
messages; both then call :meth:`Recorder.calibrate`. Everything between a message and a result
is therefore the same code live and offline.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

from ..core.config import CalibrationConfig
from ..core.errors import InputError
from ..core.pipeline import calibrate
from ..core.result import CalibrationResult
from .buffer import BufferStats, PoseBuffer
from .config import StreamConfig
from .convert import StampedPose, pose_of

STREAMS = ('hand', 'eye')


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

    def calibrate(self, config: CalibrationConfig) -> CalibrationResult:
        """Calibrate on a copy of the buffers (they keep filling meanwhile).

        Raises HandeyeError subclasses with a user-facing reason (e.g. too little data).
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
        result = calibrate(trajectories['hand'], trajectories['eye'], config)
        return replace(result, warnings=result.warnings + tuple(self.stream_warnings()))

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
