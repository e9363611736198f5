"""The calibrator's pose subscriptions: each stream's topic subscribed with its declared type,
or, for ``auto``, with its likeliest type until the graph names the publisher's; the QoS of
pose streams; and, when a stream stays empty, the reason read from the graph (no publisher,
no pose type, several pose types, a QoS that cannot match).

Auto-typed topics (``hand_type: auto``) are subscribed at once with their likeliest type
(:data:`LIKELY_TYPES`), as a typed node subscribes them; the graph then confirms the type, or
the subscription gives way to the publisher's type. (Raw subscriptions of the other candidate
types, to keep what came before, were measured to change nothing and were removed.)
"""

from __future__ import annotations

import difflib
import time
from collections.abc import Callable, Iterator
from functools import partial
from typing import TYPE_CHECKING

from rclpy.event_handler import QoSRequestedIncompatibleQoSInfo, SubscriptionEventCallbacks
from rclpy.exceptions import InvalidHandle
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSPolicyKind,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.subscription import Subscription

from ..core.errors import ConfigError
from ..stream import STREAMS, SUPPORTED_TYPES, Recorder, normalise_type
from ..stream.convert import TF_TYPE, UnsupportedTypeError
from ..stream.shapes import Message, MessageInfo
from .lifecycle import steady_timer
from .types import message_class

if TYPE_CHECKING:  # the node owns its subscriptions; it hands them its settings
    from ..app.params_file import NodeConfig
    from ..stream import StreamConfig

#: Seconds between looks at the graph while an auto-typed stream's type is unknown: a type
#: learnt there is subscribed at the next look (one look costs ~0.02 ms).
GRAPH_POLL_S = 0.05
#: The type a stream's plain pose topic most likely has, subscribed before the graph says
#: (motion capture drivers publish PoseStamped; VIO estimators publish Odometry).
LIKELY_TYPES = {'hand': 'geometry_msgs/msg/PoseStamped', 'eye': 'nav_msgs/msg/Odometry'}
#: Messages a pose callback takes from its queue beyond the one the executor handed it: rclpy's
#: executor rebuilds its wait set of the node's ~25 entities for each message (~0.3 ms of
#: Python), a direct take costs ~0.07 ms, so a node that fell behind catches up
#: (bench/results/node.md); the executor is back to timers and services within ~10 ms.
DRAIN_MAX = 100


def taken(sub: Subscription, most: int) -> Iterator[tuple[Message, MessageInfo]]:
    """Up to ``most`` messages waiting in ``sub``'s queue, with their MessageInfo, taken as
    rclpy's executor takes them; none once the subscription is destroyed."""
    for _ in range(most):
        try:
            with sub.handle:
                got = sub.handle.take_message(sub.msg_type, sub.raw)
        except InvalidHandle:
            return
        if got is None:
            return
        yield got


class Subscriptions:
    """The pose subscriptions of ``node``, feeding ``on_pose(stream, msg, static, info)``
    (``info``: the message's rclpy MessageInfo); ``settings()``: the node's stream and node
    options as they are now (a parameter set later changes them)."""

    def __init__(
        self,
        node: Node,
        recorder: Recorder,
        on_pose: Callable[[str, Message, bool, MessageInfo], None],
        settings: Callable[[], tuple[StreamConfig, NodeConfig]],
    ) -> None:
        self._node, self._recorder, self._on_pose = node, recorder, on_pose
        self._settings = settings
        self._log = node.get_logger()
        self.subs: dict[str, Subscription] = {}
        self._static_subs: dict[str, Subscription] = {}
        self._sub_errors: dict[str, str] = {}
        self._qos_problems: dict[str, str] = {}
        self._type_warned = dict.fromkeys(STREAMS, time.monotonic())
        #: auto-typed streams subscribed with their likeliest type, not yet confirmed by the
        #: graph (a wrong guess matches no publisher, and gives way to the graph's type)
        self.guessed: set[str] = set()
        self.check_tf_selectors()
        self.check_topics()
        for stream in STREAMS:
            declared = getattr(settings()[0], f'{stream}_type')
            if declared != 'auto':
                self.subscribe(stream, normalise_type(declared))
            elif recorder.selectors[stream].item is None:
                self.subscribe(stream, LIKELY_TYPES[stream], guess=True)
        self._graph_timer = None
        if len(self.subs) < len(STREAMS) or self.guessed:
            self._graph_timer = steady_timer(node, GRAPH_POLL_S, self.discover_types)

    def topic(self, stream: str) -> str:
        """A stream's topic as the graph knows it: expanded and remapped (``--ros-args -r``)."""
        return self._node.resolve_topic_name(self._recorder.selectors[stream].topic)

    def shown(self, stream: str) -> str:
        """A stream's selector for messages, with the remapped topic where it differs."""
        sel = self._recorder.selectors[stream]
        topic = self.topic(stream)
        same = topic == self._node.resolve_topic_name(sel.topic, only_expand=True)
        return sel.text if same else f'{topic} (remapped from {sel.text})'

    def check_topics(self) -> None:
        """Every topic a selector names is a valid ROS name (ConfigError naming the rule)."""
        for stream in STREAMS:
            sel = self._recorder.selectors[stream]
            for topic in sel.topics:
                try:
                    self._node.resolve_topic_name(topic)
                except RuntimeError as err:  # rclpy's RCLError (exported privately only)
                    why = str(err).split('failed to resolve name: ', 1)[-1].split(', at ')[0]
                    raise ConfigError(
                        f'{stream}_topic {sel.text}: {topic!r} is no valid topic name: {why}'
                    ) from None

    def check_tf_selectors(self) -> None:
        """Say at start, not when data would arrive, that a tf selector cannot be read here:
        tf2_msgs comes with a ROS 2 install, not with the PyPI wheels."""
        for stream in STREAMS:
            sel = self._recorder.selectors[stream]
            declared = getattr(self._settings()[0], f'{stream}_type')
            is_tf = (
                normalise_type(declared) == TF_TYPE
                if declared != 'auto'
                else sel.item is not None and sel.topic.rstrip('/').rsplit('/', 1)[-1] == 'tf'
            )
            if not is_tf:
                continue
            sel.frames()  # a malformed pair is a ConfigError now
            try:
                message_class(TF_TYPE)
            except ConfigError as err:
                raise ConfigError(
                    f'{stream}_topic {sel.text}: {err}. Bags with /tf need no '
                    'ROS install: offline_calibrate --bag reads them'
                ) from None

    def _pose_qos(self) -> QoSProfile:
        """The QoS of the pose subscriptions."""
        return QoSProfile(
            depth=self._settings()[1].qos_depth,
            history=HistoryPolicy.KEEP_LAST,
            reliability=(
                ReliabilityPolicy.BEST_EFFORT
                if self._settings()[1].qos_reliability == 'best_effort'
                else ReliabilityPolicy.RELIABLE
            ),
            durability=DurabilityPolicy.VOLATILE,
        )

    def unknown(self) -> list[str]:
        """The auto-typed streams whose type the graph has not named yet."""
        return [s for s in STREAMS if s not in self.subs or s in self.guessed]

    def _callback(self, stream: str, static: bool) -> Callable[[Message, MessageInfo], None]:
        """The subscription's callback: rclpy hands it the message and its MessageInfo; it then
        takes what else waits in the queue of the stream's (static) subscription."""
        subs = self._static_subs if static else self.subs

        def on_message(msg: Message, info: MessageInfo) -> None:
            self._on_pose(stream, msg, static, info)
            sub = subs.get(stream)  # none once a wrong guess gave way to a type that failed
            for more, more_info in taken(sub, DRAIN_MAX) if sub is not None else ():
                self._on_pose(stream, more, static, more_info)

        return on_message

    def subscribe(self, stream: str, msgtype: str, guess: bool = False) -> None:
        """Subscribe a stream's topic (and a tf selector's static topic, transient local, as
        tf2's static broadcasters latch) once its type is known, or with its likeliest type
        (``guess``) until the graph says; raises ConfigError when the type does not fit the
        selector or its Python package cannot be imported."""
        self._recorder.set_type(stream, msgtype)
        cls = message_class(msgtype)
        sel = self._recorder.selectors[stream]
        # rclpy calls a callback of two parameters with the message and its MessageInfo; its
        # annotation names the one-parameter form only
        self.subs[stream] = self._node.create_subscription(
            cls,
            sel.topic,
            self._callback(stream, static=False),  # type: ignore[arg-type]
            self._pose_qos(),
            event_callbacks=SubscriptionEventCallbacks(
                incompatible_qos=partial(self._on_incompatible_qos, stream)
            ),
        )
        if sel.static_topic:
            static_qos = QoSProfile(
                depth=100,
                history=HistoryPolicy.KEEP_LAST,
                reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.TRANSIENT_LOCAL,
            )
            self._static_subs[stream] = self._node.create_subscription(
                cls,
                sel.static_topic,
                self._callback(stream, static=True),  # type: ignore[arg-type]
                static_qos,
            )
        if guess:
            self.guessed.add(stream)
            self._log.info(
                f'{stream}: subscribed to {self.shown(stream)} as {msgtype}, its likeliest type, until '
                'its publisher says which it has'
            )
        else:
            self._log.info(f'{stream}: subscribed to {self.shown(stream)} ({msgtype})')

    def _on_incompatible_qos(self, stream: str, event: QoSRequestedIncompatibleQoSInfo) -> None:
        """A publisher whose QoS this subscription cannot match: nothing of it will arrive."""
        why = self.qos_mismatch(stream)
        if why is None:
            policy = QoSPolicyKind(event.last_policy_kind).name.lower()
            why = (
                f'{stream} topic {self.topic(stream)}: a publisher offers '
                f'a QoS this subscription cannot match ({policy}); nothing it sends arrives'
            )
        self._qos_problems[stream] = why
        self._log.warning(why)

    def qos_mismatch(self, stream: str) -> str | None:
        """The reason no message of a stream's publishers can arrive, read from the QoS they
        offer in the graph; None when every one matches."""
        sub = self.subs.get(stream)
        if sub is None or sub.qos_profile.reliability != ReliabilityPolicy.RELIABLE:
            return None
        topic = self.topic(stream)
        for info in self._node.get_publishers_info_by_topic(topic):
            if info.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT:
                who = (
                    'its publisher'
                    if info.node_name in ('', '_NODE_NAME_UNKNOWN_')
                    else f'its publisher {info.node_namespace.rstrip("/")}/{info.node_name}'
                )
                return (
                    f'{stream} topic {topic}: {who} is best_effort '
                    'and this node asks reliable delivery (qos_reliability: reliable), so '
                    'nothing it sends arrives: set qos_reliability: best_effort'
                )
        return None

    def discover_types(self) -> None:
        """Learn the message type of auto-typed topics from the graph."""
        now = time.monotonic()
        for stream in self.unknown():
            topic = self.topic(stream)
            types = self.publisher_types(topic)
            usable = _pose_types(types)
            guess = self._recorder.types[stream] if stream in self.guessed else None
            if usable == [guess]:
                self.guessed.discard(stream)
                self._log.info(f'{stream}: {topic} is {guess}, as subscribed from the start')
            elif len(usable) == 1:
                try:
                    if guess is not None:
                        # a wrong guess gives way: one participant holds one type of a topic
                        self._node.destroy_subscription(self.subs.pop(stream))
                        self.guessed.discard(stream)
                    self.subscribe(stream, usable[0])
                    self._log.info(
                        f'{stream}: {topic} learnt from its publisher; messages it sent '
                        'before this subscription matched are not received (set '
                        f'{stream}_type: {usable[0].rsplit("/", 1)[-1]} to subscribe at start)'
                    )
                except ConfigError as err:
                    self._sub_errors[stream] = str(err)
                    if now - self._type_warned[stream] > self._settings()[1].topic_wait:
                        self._type_warned[stream] = now
                        self._log.error(f'{stream}: {err}')
            elif now - self._type_warned[stream] > self._settings()[1].topic_wait:
                self._type_warned[stream] = now
                if types and not usable:
                    why = (
                        f'has type {", ".join(types)}, which carries no pose (supported: '
                        f'{", ".join(SUPPORTED_TYPES)})'
                    )
                elif usable:
                    why = (
                        f'has several pose types ({", ".join(usable)}): restart the node with '
                        f'-p {stream}_type:=ONE_OF_THEM'
                    )
                    if guess in usable:
                        why += f'; meanwhile the {guess} one is received'
                else:
                    why = 'has no publisher yet' + self.near(topic)
                self._log.warning(f'{stream} topic {topic} {why}')
        if not self.unknown() and self._graph_timer is not None:
            self._graph_timer.cancel()

    def publisher_types(self, topic: str) -> list[str]:
        """The types a topic's publishers send, in the order first seen (the graph's types
        of a topic also hold its subscriptions')."""
        types: list[str] = []
        for info in self._node.get_publishers_info_by_topic(topic):
            if info.topic_type not in types:
                types.append(info.topic_type)
        return types

    def why_no_data(self) -> str | None:
        unknown = self.unknown()
        for stream in STREAMS:
            empty = len(self._recorder.buffers[stream]) < 2
            if stream in self.subs and stream not in unknown and empty:
                # the graph now, or what the QoS event said of a publisher since gone
                why = self.qos_mismatch(stream) or self._qos_problems.get(stream)
                if why is not None:
                    return why
            if stream in self._sub_errors and stream not in self.subs:
                return f'{stream}: {self._sub_errors[stream]}'
            if stream in unknown and empty:
                topic = self.topic(stream)
                types = self.publisher_types(topic)
                usable = _pose_types(types)
                if len(usable) > 1:
                    return (
                        f'{stream} topic {topic} has several pose types ({", ".join(usable)}): '
                        f'restart the node with -p {stream}_type:=ONE_OF_THEM'
                    )
                if types and not usable:
                    return (
                        f'{stream} topic {topic} has type {", ".join(types)}, which carries '
                        f'no pose this node reads (supported: {", ".join(SUPPORTED_TYPES)})'
                    )
                if not types:
                    source = {'hand': 'the MoCap driver', 'eye': 'the VO/VIO'}[stream]
                    return (
                        f'{stream} topic {topic} has no publisher yet{self.near(topic)}: start '
                        f'{source}, or restart the node with -p {stream}_topic:=YOUR_TOPIC'
                    )
        return None

    def near(self, topic: str) -> str:
        """' (did you mean /vio/odom?)' for a pose topic in the graph whose name is close to
        ``topic`` (a misspelt topic), else ''."""
        names = [
            name
            for name, types in self._node.get_topic_names_and_types()
            if name != topic and _pose_types(types)
        ]
        near = difflib.get_close_matches(topic, names, n=1, cutoff=0.7)
        return f' (did you mean {near[0]}?)' if near else ''


def _pose_types(types: list[str]) -> list[str]:
    """Those of a topic's types this node reads poses from, normalised."""
    usable = []
    for t in types:
        try:
            usable.append(normalise_type(t))
        except UnsupportedTypeError:
            pass
    return usable
