"""The two buffered streams of a calibration session and the one calibration call on them.

The node feeds :meth:`Recorder.add` from its subscriptions; the bag replay feeds it from bag
messages; both then calibrate a :meth:`Recorder.snapshot` (:meth:`Snapshot.result`).
Everything between a message and a result is therefore the same code live and offline.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import cast

from ..core.config import CalibrationConfig
from ..core.document import ResultDoc, StreamDoc
from ..core.errors import ConfigError, InputError
from ..core.result import CalibrationResult
from ..core.trajectory import Trajectory
from .buffer import BufferStats, PoseBuffer
from .config import StreamConfig
from .convert import (
    RIGID_BODIES_TYPES,
    TF_TYPE,
    Converter,
    frame_name,
    frames_of,
    normalise_type,
    pose_of,
)
from .shapes import Message, OnePose, RigidBodies, TFMessage
from .sources import TF_STATIC, RigidBodyPicker, Selector, TfChain, parse_selector

STREAMS = ('hand', 'eye')


@dataclass(frozen=True)
class Snapshot:
    """What a calibration needs from the buffers; plain data, so it can go to another process."""

    hand: Trajectory
    eye: Trajectory
    #: frame names: hand (H), eye (E), hand_world (G), eye_world (W); see StreamConfig.frames
    frames: dict[str, str]
    streams: dict[str, StreamDoc]
    warnings: tuple[str, ...]

    @property
    def span_s(self) -> float:
        """The span both streams cover [s]: the shorter of their durations."""
        return min(self.hand.duration_s, self.eye.duration_s)

    def result(
        self, config: CalibrationConfig, progress: Callable[[str], None] | None = None
    ) -> CalibrationResult:
        """Calibrate the snapshot; the streams' dropped/rejected messages join the warnings.
        ``progress``: as :func:`~handeye_ros.core.pipeline.calibrate`'s."""
        # imported here: the node buffers with this module and calibrates in its worker, whose
        # start imports the pipeline (ros/worker.MODULES); the node's own start need not
        from ..core.pipeline import calibrate

        result = calibrate(self.hand, self.eye, config, progress)
        return replace(result, warnings=result.warnings + self.warnings)

    def describe(self, result: CalibrationResult) -> ResultDoc:
        """The result dictionary (schema of CalibrationResult.to_dict with this snapshot's
        frame names, plus ``streams`` and a one-line ``summary``)."""
        f = self.frames
        out = result.to_dict(
            hand_frame=f['hand'],
            eye_frame=f['eye'],
            hand_world=f['hand_world'],
            eye_world=f['eye_world'],
        )
        out['streams'] = self.streams
        out['summary'] = result.summary()
        return out


class Recorder:
    """Hand and eye pose buffers with their message converters.

    A stream's topic option is a selector (see :mod:`.sources`): a topic of single poses, or a
    tf pair / rigid body out of a topic of many. :meth:`set_type` fixes how its messages are
    read once the topic's type is known (from the graph, the bag, or the options)."""

    def __init__(self, config: StreamConfig):
        self.config = config
        self.selectors: dict[str, Selector] = {
            name: parse_selector(getattr(config, name + '_topic')) for name in STREAMS
        }
        self.buffers = {
            name: PoseBuffer(
                f'{name} ({getattr(config, name + "_topic")})',
                config.buffer_size,
                config.buffer_duration,
            )
            for name in STREAMS
        }
        self.types: dict[str, str | None] = {name: None for name in STREAMS}
        self._convert: dict[str, Converter] = {}
        self._tf: dict[str, TfChain] = {}
        self._bodies: dict[str, RigidBodyPicker] = {}
        #: (world, body) frame ids the first message of each stream named
        self.seen_frames: dict[str, tuple[str, str]] = {}
        #: streams stamped on arrival (use_arrival_time) rather than by header.stamp
        self.arrival = frozenset(s for s in STREAMS if config.use_arrival_time in (s, 'both'))

    def set_type(self, stream: str, msgtype: str) -> None:
        """Fix the message type of a stream's topic (raises UnsupportedTypeError, or
        ConfigError when the selector does not fit the type)."""
        msgtype = normalise_type(msgtype)
        sel = self.selectors[stream]
        if msgtype == TF_TYPE:
            if sel.item is None:
                raise ConfigError(
                    f'{stream} topic {sel.topic} is {msgtype}: select the pose '
                    f'of a frame in another, as {sel.topic}:PARENT.CHILD'
                )
            self._tf[stream] = TfChain(*sel.frames(), sel.text)
            self.seen_frames[stream] = sel.frames()
            if sel.static_topic is None:
                self.selectors[stream] = Selector(sel.text, sel.topic, sel.item, TF_STATIC)
        elif msgtype in RIGID_BODIES_TYPES:
            if sel.item is None or sel.static_topic is not None:
                raise ConfigError(
                    f'{stream} topic {sel.text} is {msgtype}: select one rigid '
                    f'body by its name, as {sel.topic}:NAME'
                )
            self._bodies[stream] = RigidBodyPicker(sel.item)
        else:
            if sel.item is not None:
                raise ConfigError(
                    f'{stream} topic {sel.topic} is {msgtype}, one pose per '
                    f'message: name the topic alone, without :{sel.item}'
                )
            self._convert[stream] = pose_of(msgtype)
        self.types[stream] = msgtype

    def routes(self) -> dict[str, list[tuple[str, bool]]]:
        """Which streams read each topic: topic -> [(stream, static)] (a tf topic may feed
        both streams; its static topic comes with static=True)."""
        out: dict[str, list[tuple[str, bool]]] = {}
        for stream in STREAMS:
            sel = self.selectors[stream]
            for topic in sel.topics:
                out.setdefault(topic, []).append((stream, topic == sel.static_topic))
        return out

    def add(
        self, stream: str, msg: Message, static: bool = False, arrival_ns: int | None = None
    ) -> str | None:
        """Convert and buffer one message; returns None or why (one of) its pose(s) was
        rejected. ``static``: the message came on a tf selector's static topic.
        ``arrival_ns``: when it arrived (node clock, or the bag's record time); it replaces
        header.stamp for the streams in :attr:`arrival`. The message is of the type
        :meth:`set_type` was told for the stream (hence the casts)."""
        restamp = arrival_ns if stream in self.arrival else None
        convert = self._convert.get(stream)
        if convert is not None:
            if stream not in self.seen_frames:
                self.seen_frames[stream] = frames_of(cast(OnePose, msg))
            pose = convert(cast(OnePose, msg))
            if restamp is not None:
                pose = (restamp, *pose[1:])
            return self.buffers[stream].add(pose)
        picker = self._bodies.get(stream)
        if picker is not None:
            bodies = cast(RigidBodies, msg)
            if stream not in self.seen_frames:
                self.seen_frames[stream] = (frame_name(bodies.header.frame_id), picker.name)
            body = picker.pose(bodies)
            if body is None:
                return self.buffers[stream].reject('not_in_message')
            if restamp is not None:
                body = (restamp, *body[1:])
            return self.buffers[stream].add(body)
        reason = None
        for pose in self._tf[stream].poses(cast(TFMessage, msg), static):
            if restamp is not None:
                pose = (restamp, *pose[1:])
            reason = self.buffers[stream].add(pose) or reason
        return reason

    def stamp_trouble(self, stream: str) -> str | None:
        """What the rejected stamps of a stream say about its publisher, with the way out;
        None when its stamps look sound."""
        buf = self.buffers[stream]
        r, way_out = (
            buf.rejected,
            (
                f'use_arrival_time: {stream} stamps them on arrival (a start parameter: '
                'restart the node with it)'
                if stream not in self.arrival
                else ''
            ),
        )
        if r['zero_stamp']:
            return (
                f'{r["zero_stamp"]} message(s) had no stamp (header.stamp 0): the publisher '
                f'leaves it unset; {way_out or "their arrival times are zero too"}'
            )
        bad = r['stamp_repeated'] + r['stamp_not_increasing']
        if bad and bad >= 0.1 * buf.received:
            return (
                f'{r["stamp_repeated"]} message(s) repeated the previous stamp and '
                f'{r["stamp_not_increasing"]} went back: the publisher stamps with a frozen '
                f'or coarse clock, or several sources share the topic'
                + (f'; {way_out}' if way_out else '')
                + (
                    '; a publisher restarted with an older clock needs ~/reset'
                    if r['stamp_not_increasing']
                    else ''
                )
            )
        return None

    def diagnose(self, stream: str) -> str | None:
        """Why a many-pose selector gave no pose (None for one-pose topics)."""
        source = self._tf.get(stream) or self._bodies.get(stream)
        return source.diagnose() if source is not None else None

    def frames(self) -> dict[str, str]:
        """The frame names of the result: options, else the messages', else the fallbacks."""
        seen = {}
        for stream, (world, body) in self.seen_frames.items():
            seen[stream], seen[f'{stream}_world'] = body, world
        return self.config.frames(seen)

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
                why = self.diagnose(name)
                if why is not None and len(buf) == 0:
                    raise InputError(f'{name} stream {topic} gave no pose: {why}')
                trouble = self.stamp_trouble(name)
                msg = (
                    f'{name} stream {topic}: {len(buf)} pose(s) buffered '
                    f'({buf.received} received, {sum(buf.rejected.values())} rejected); '
                    + (trouble if trouble else 'need a recording of both streams first')
                )
                raise InputError(msg)
            trajectories[name] = buf.trajectory()
            if name in self._tf:
                trajectories[name] = self._tf[name].finish(trajectories[name])
        return Snapshot(
            trajectories['hand'],
            trajectories['eye'],
            self.frames(),
            self.stream_dict(),
            tuple(self.stream_warnings()),
        )

    def tails(self, since_ns: dict[str, int]) -> dict[str, Trajectory]:
        """Each stream's poses from the newest one at or before its stamp in ``since_ns`` on
        (:meth:`PoseBuffer.since`), as :meth:`snapshot` gives them: what the status reads of
        the poses that came since it last read."""
        out = {}
        for name, t_ns in since_ns.items():
            out[name] = self.buffers[name].since(t_ns)
            if name in self._tf:
                out[name] = self._tf[name].finish(out[name])
        return out

    def stream_warnings(self) -> list[str]:
        """Dropped or rejected messages, said in the result."""
        out = []
        for name, s in self.stats().items():
            topic = getattr(self.config, name + '_topic')
            if s.dropped:
                out.append(
                    f'{name} stream {topic}: the {s.dropped} oldest poses were dropped '
                    f'(buffer_size {self.config.buffer_size}, buffer_duration '
                    f'{self.config.buffer_duration:g} s)'
                )
            bad = {k: v for k, v in s.rejected.items() if v}
            if bad:
                out.append(
                    f'{name} stream {topic}: rejected messages: '
                    + ', '.join(f'{v} {k.replace("_", " ")}' for k, v in bad.items())
                )
            if name in self._tf:
                out += self._tf[name].warnings()
            trouble = self.stamp_trouble(name)
            if trouble:
                out.append(f'{name} stream {topic}: {trouble}')
            if name in self.arrival:
                out.append(
                    f'{name} stream {topic}: stamped on arrival (use_arrival_time), not '
                    'by header.stamp: the transport delay is part of the time offset '
                    'and its jitter adds noise'
                )
        return out

    def stream_dict(self) -> dict[str, StreamDoc]:
        """Per-stream bookkeeping for the result file."""
        out: dict[str, StreamDoc] = {
            name: {
                'topic': getattr(self.config, name + '_topic'),
                'type': self.types[name],
                'stamps': 'arrival' if name in self.arrival else 'header',
                'received': s.received,
                'buffered': s.stored,
                'dropped': s.dropped,
                'rejected': s.rejected,
                'span_s': s.span_s,
                'rate_hz': s.rate_hz,
            }
            for name, s in self.stats().items()
        }
        for name, (world, body) in self.seen_frames.items():
            out[name]['frames'] = {'world': world, 'body': body}
        for name, chain in self._tf.items():
            out[name]['tf_chain'] = chain.describe()
        return out
