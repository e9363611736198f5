"""Replay of a bag through the node's own :class:`~handeye_ros.stream.Recorder`.

The pose messages of the hand and eye topics go, in the order they were recorded, through the
same conversion, validation and bounded buffers the node uses, so a bag gives the result the
node would have given live. Above :mod:`handeye_ros.formats` (reading the bag) and
:mod:`handeye_ros.stream` (the Recorder); used by the offline tool.
"""

from __future__ import annotations

import sys
from dataclasses import replace as _replace
from pathlib import Path
from typing import cast

from ..core.errors import ConfigError, InputError
from ..formats.bag import BagReader, Topic
from ..stream import STREAMS, SUPPORTED_TYPES, Recorder, StreamConfig
from ..stream.convert import (
    MULTI_POSE_TYPES,
    RIGID_BODIES_TYPES,
    TF_TYPE,
    UnsupportedTypeError,
    normalise_type,
)
from ..stream.shapes import Message, RigidBodies, TFMessage
from ..stream.sources import parse_selector

#: Words that mark a topic as MoCap (hand) or VO/VIO (eye) when the topics are not given.
HAND_WORDS = (
    'mocap',
    'vicon',
    'optitrack',
    'qualisys',
    'vrpn',
    'motion_capture',
    'natnet',
    'ground_truth',
    'groundtruth',
)
EYE_WORDS = (
    'vio',
    'odom',
    'slam',
    'vins',
    'msckf',
    'orb',
    'okvis',
    'estimate',
    'camera',
    'visual',
)


def choose_topics(
    bag: BagReader, config: StreamConfig, given: dict[str, bool]
) -> dict[str, Topic]:
    """The hand and eye topics: as given, else by name, else the one obvious pair.

    ``given[stream]`` says whether the user named the topic (command line or config); a
    topic not named is taken from the node's default name if the bag has it, else from the
    pose topics whose names say MoCap or VIO. Raises InputError listing the candidates.
    """
    poses = bag.pose_topics()
    by_name = {t.name: t for t in bag.topics()}
    if not any(t.count for t in by_name.values()):
        raise InputError(f'{bag.path}: the bag holds no messages')
    listing = (
        (
            '; pose topics in the bag: '
            + ', '.join(f'{t.name} ({t.msgtype}, {t.count} msgs)' for t in poses)
        )
        if poses
        else '; the bag holds no pose topic (supported types: ' + ', '.join(SUPPORTED_TYPES) + ')'
    )
    for t in bag.multi_pose_topics():
        how = 'PARENT.CHILD' if normalise_type(t.msgtype) == TF_TYPE else 'BODY_NAME'
        listing += f'; {t.name} ({t.msgtype}, {t.count} msgs): select as {t.name}:{how}'
    chosen: dict[str, Topic] = {}
    for stream, words in (('hand', HAND_WORDS), ('eye', EYE_WORDS)):
        name = parse_selector(getattr(config, f'{stream}_topic')).topic
        if name in by_name or given[stream]:
            if name not in by_name:
                raise InputError(f'{bag.path}: no topic {name} (--{stream}-topic){listing}')
            topic = by_name[name]
            try:
                normalise_type(topic.msgtype)
            except UnsupportedTypeError as err:
                raise InputError(f'{bag.path}: topic {name}: {err}') from None
            chosen[stream] = topic
            continue
        matches = [t for t in poses if any(w in t.name.lower() for w in words)]
        if len(matches) != 1:
            why = 'no pose topic looks' if not matches else f'{len(matches)} pose topics look'
            raise InputError(
                f'{bag.path}: {why} like the {stream} stream; pass --{stream}-topic{listing}'
            )
        chosen[stream] = matches[0]
    texts = [selector_text(config, s, chosen[s]) for s in STREAMS]
    if texts[0] == texts[1]:
        raise InputError(f'{bag.path}: hand and eye are the same topic {texts[0]}')
    for stream in STREAMS:
        if chosen[stream].count == 0:
            raise InputError(f'{bag.path}: topic {chosen[stream].name} holds no messages')
    return chosen


def selector_text(config: StreamConfig, stream: str, topic: Topic) -> str:
    """The stream's selector on the chosen topic: the option's own (with its tf pair or body
    name) when it names that topic, else the topic picked by name."""
    text = getattr(config, f'{stream}_topic')
    return text if parse_selector(text).topic == topic.name else topic.name


def replay(
    path: str | Path,
    config: StreamConfig,
    given: dict[str, bool] | None = None,
    progress: bool | None = None,
) -> Recorder:
    """Feed the bag's hand and eye messages through a Recorder, as the node would receive them.

    ``progress``: show a progress bar on stderr (None: only when stderr is a terminal).
    """
    from tqdm import tqdm

    given = given or {s: False for s in STREAMS}
    with BagReader(path) as bag:
        chosen = choose_topics(bag, config, given)
        config = _replace(
            config,
            hand_topic=selector_text(config, 'hand', chosen['hand']),
            eye_topic=selector_text(config, 'eye', chosen['eye']),
        )
        rec = Recorder(config)
        for stream in STREAMS:
            declared = getattr(config, f'{stream}_type')
            msgtype = chosen[stream].msgtype
            if declared != 'auto' and normalise_type(declared) != normalise_type(msgtype):
                raise InputError(
                    f'{bag.path}: topic {chosen[stream].name} is {msgtype}, but '
                    f'{stream}_type is {declared}'
                )
            try:
                rec.set_type(stream, msgtype)
            except ConfigError as err:
                raise InputError(f'{bag.path}: {err}{_items(bag, chosen[stream])}') from None
        routes = rec.routes()
        counts = {t.name: t.count for t in bag.topics()}
        # static transforms first: a recorder may log /tf_static after the first /tf samples
        static = [t for t, r in routes.items() if all(st for _, st in r) and t in counts]
        moving = [t for t in routes if t not in static and t in counts]
        total = sum(counts[t] for t in routes if t in counts)
        bar = tqdm(
            total=total,
            unit='msg',
            desc=f'replaying {bag.path.name}',
            file=sys.stderr,
            disable=None if progress is None else not progress,
            mininterval=0.5,
        )
        with bar:
            for topics in (static, moving):
                if not topics:
                    continue
                for k, (topic, t_ns, msg) in enumerate(bag.messages(topics)):
                    for stream, is_static in routes[topic]:
                        # of the type set for the stream from this topic's connection
                        rec.add(stream, cast(Message, msg), is_static, t_ns)
                    if k % 4096 == 4095:
                        bar.update(4096)
            bar.update(total - bar.n)
    return rec


def _items(bag: BagReader, topic: Topic) -> str:
    """What a many-pose topic holds (frame pairs, body names), from its first messages."""
    kind = normalise_type(topic.msgtype)
    if kind not in MULTI_POSE_TYPES:
        return ''
    seen: dict[str, None] = {}
    for k, (_, _, msg) in enumerate(bag.messages([topic.name])):
        if kind in RIGID_BODIES_TYPES:
            bodies = cast(RigidBodies, msg).rigidbodies  # of the topic's type, as kind says
            seen.update(dict.fromkeys(b.rigid_body_name for b in bodies))
        else:
            seen.update(
                dict.fromkeys(
                    f'{tf.header.frame_id.lstrip("/")}.{tf.child_frame_id.lstrip("/")}'
                    for tf in cast(TFMessage, msg).transforms
                )
            )
        if k >= 200 or len(seen) > 20:
            break
    listed = ', '.join(f'{topic.name}:{x}' for x in list(seen)[:20])
    return f'; it holds {listed}' if seen else ''
