"""The first messages of an auto-typed stream, received before its type is known.

With ``hand_type: auto`` (or ``eye_type``) the node learns a topic's type from its publisher in
the graph. A subscription receives a publisher's messages only once the two have matched, which
takes a discovery handshake. A publisher that sends as soon as it appears (``ros2 bag play``, a
MoCap driver started after the node) would therefore lose its first messages to a node that
subscribes only once it knows the type: the graph poll, the new subscription and the match
take a fraction of a second, which is hundreds of poses at 1 kHz.

Two things keep them. First, the node subscribes the stream's likeliest type at once, in its
own participant (:data:`LIKELY_TYPES`: a MoCap pose as PoseStamped, a VIO as Odometry), exactly
as a typed node does; the graph then confirms the guess or names another type, and the guess
gives way. Second, for the other candidate types, rclpy cannot subscribe to a topic before it
knows the type, and one DDS participant refuses a second subscription of another type on the
same topic. So :class:`TypeProbes` holds *raw* subscriptions (the serialised bytes, never
deserialised there) in contexts of their own (one DDS participant each, as few as the topic
with the most candidates needs), each spun by its own thread.
The probe of the right type matches the publisher as a typed subscription made at the start
would, when its participant discovers the publisher's; discovery is per participant, and with
unicast discovery (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) a probe's was seen to find a new
publisher up to 2.5 s after the node's did, in 3 of 20 runs: that probe has nothing to add.

When the node's own subscription delivers its first messages, :class:`Handover` finds where
they begin among the probe's, comparing whole messages (not stamps, which may be zero or
repeated), and gives the node the probe's messages before that point, then its own: nothing
lost, nothing twice. If the probe receives nothing more and has shown none of the node's
messages (it never matched), the handover gives up after a bounded wait and says that earlier
messages may be missing. The probes are shut down as soon as every auto-typed stream has been
handed over.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from ..core.errors import ConfigError
from ..stream.convert import MULTI_POSE_TYPES, SUPPORTED_TYPES

#: Messages a probe keeps per topic and type (the newest; at 1 kHz, 20 s: the node subscribes
#: within a graph poll, GRAPH_POLL_S in the node, of the type appearing).
PROBE_DEPTH = 20_000
#: Seconds the node's own messages wait for the probe to show where they start while the probe
#: receives nothing new, before the handover gives up (and says so): a probe that still
#: receives is behind the node (its thread shares the GIL), not lost.
HANDOVER_TIMEOUT_S = 2.0
#: Seconds they wait at most, however busy the probe.
HANDOVER_LIMIT_S = 10.0
#: Seconds a probe's thread waits for messages before it looks at its stop flag again.
SPIN_WAIT_S = 0.05


#: The type a stream's plain pose topic most likely has, subscribed before the graph says
#: (motion capture drivers publish PoseStamped; VIO estimators publish Odometry).
LIKELY_TYPES = {'hand': 'geometry_msgs/msg/PoseStamped', 'eye': 'nav_msgs/msg/Odometry'}


def probe_slots(topics: dict[str, Iterable[str]]) -> list[list[tuple[str, str]]]:
    """The (topic, type) subscriptions of each probe participant: the k-th candidate type of
    every topic in the k-th, so that no participant holds two types of one topic and there
    are as few participants as the longest candidate list."""
    slots: list[list[tuple[str, str]]] = []
    for topic, types in topics.items():
        for k, msgtype in enumerate(types):
            if k == len(slots):
                slots.append([])
            slots[k].append((topic, msgtype))
    return slots


def candidate_types(selects_item: bool, classes: Callable[[str], Any]) -> list[str]:
    """The types an auto-typed topic may have: those of one pose per message, or for a
    selector with an item (``TOPIC:PARENT.CHILD``, ``TOPIC:NAME``) those of many; only the
    ones whose package this Python can import (``classes`` raises ConfigError otherwise)."""
    out = []
    for t in MULTI_POSE_TYPES if selects_item else SUPPORTED_TYPES:
        try:
            classes(t)
        except ConfigError:
            continue
        out.append(t)
    return out


def message_key(msg: Any) -> Any:
    """A hashable value equal for equal messages: their fields, flattened into tuples.

    Not the serialised bytes: rclpy's serialiser leaves the alignment padding uninitialised,
    so equal messages may serialise differently (seen: PoseStamped after its frame id)."""
    slots = getattr(msg, '__slots__', None)
    if slots is None:
        if isinstance(msg, list | tuple):
            return tuple(message_key(m) for m in msg)
        if hasattr(msg, 'tolist'):  # numpy and array.array fields
            return tuple(msg.tolist())
        return msg
    return tuple(message_key(getattr(msg, name)) for name in slots)


@dataclass
class Handover:
    """One stream's switch from its probe's messages to its own subscription's.

    ``early``: the probe's (serialised message, arrival ns) of the stream's topic and type,
    appended by the probe's thread; ``decode``: serialised bytes -> message; ``key``: a
    message -> a hashable value equal for equal messages (:func:`message_key`).

    The node's own messages are held in ``pending`` until :meth:`settle` finds where they
    begin among ``early``: at the first probe message equal to *any* held one (the probe, a
    thread sharing the GIL, may have dropped the node's very first). Every probe message
    before it came before the node's first: had the probe held one of the node's messages
    earlier, that one would have matched."""

    early: deque[tuple[bytes, int]]
    decode: Callable[[bytes], Any]
    key: Callable[[Any], Any] = message_key
    pending: list[tuple[Any, int | None]] = field(default_factory=list)
    #: the held messages' keys
    keys: set[Any] = field(default_factory=set)
    since: float = 0.0
    #: when the probe was last seen to receive, and the arrival of its newest message then
    heard: float = 0.0
    newest: int | None = None
    #: how many of ``early`` were looked at, and the first index of each one's key
    searched: int = 0
    seen: dict[Any, int] = field(default_factory=dict)
    #: the first index in ``early`` of a message the node holds too
    meet: int | None = None
    #: '' while open; 'caught up' or 'timed out' once settled
    outcome: str = ''

    def hold(self, msg: Any, arrival_ns: int | None, now: float) -> None:
        """Keep one of the node's own messages until the handover settles."""
        if not self.pending:
            self.since = self.heard = now
            self.newest = self.early[-1][1] if self.early else None
        key = self.key(msg)
        self.keys.add(key)
        if key in self.seen:  # the probe had it already
            self._meet(self.seen[key])
        self.pending.append((msg, arrival_ns))

    def _meet(self, k: int) -> None:
        self.meet = k if self.meet is None else min(self.meet, k)

    def settle(
        self, now: float, timeout: float = HANDOVER_TIMEOUT_S, limit: float = HANDOVER_LIMIT_S
    ) -> tuple[list[tuple[Any, int]], list[tuple[Any, int | None]]] | None:
        """None while open; else (the probe's messages that came before the node's first,
        with their arrival; the node's own held messages), both in order. It gives up, with
        no probe message, once the probe has received nothing new for ``timeout`` s while
        the node's messages wait, or once they have waited ``limit`` s."""
        if self.outcome or not self.pending:
            return None
        early = list(self.early)  # a snapshot: the probe's thread may still append
        if early and early[-1][1] != self.newest:
            self.newest, self.heard = early[-1][1], now
        if len(early) == self.early.maxlen:
            # the ring may have moved under the indices: look at it all again
            self.searched, self.seen, self.meet = 0, {}, None
        for k in range(self.searched, len(early)):
            key = self.key(self.decode(early[k][0]))
            self.seen.setdefault(key, k)
            if key in self.keys:
                self._meet(k)
                break
        self.searched = len(early)
        if self.meet is not None:
            return self._done('caught up', early[: self.meet])
        if now - max(self.since, self.heard) < timeout and now - self.since < limit:
            return None
        return self._done('timed out', [])

    def _done(
        self, outcome: str, before: list[tuple[bytes, int]]
    ) -> tuple[list[tuple[Any, int]], list[tuple[Any, int | None]]]:
        self.outcome = outcome
        pending, self.pending, self.keys, self.seen = self.pending, [], set(), {}
        return [(self.decode(raw), arrival) for raw, arrival in before], pending


class TypeProbes:
    """One raw subscription per (auto-typed topic, candidate type), each type in a context of
    its own, spun by a thread of its own; see the module docstring.

    ``topics``: fully qualified topic -> candidate 'pkg/msg/Name' types (:func:`probe_slots`
    groups them into participants); ``classes``: the rclpy class of a type; ``qos``: the
    profile of the node's own subscriptions (its depth is raised); ``clock``: the node's
    clock, for arrival stamps."""

    def __init__(
        self,
        topics: dict[str, Iterable[str]],
        classes: Callable[[str], Any],
        qos: Any,
        clock: Any,
    ):
        from rclpy.qos import QoSProfile

        self.early: dict[tuple[str, str], deque[tuple[bytes, int]]] = {}
        self._runs: list[tuple[Any, Any, Any, threading.Thread]] = []
        self._stop = threading.Event()
        self._clock = clock
        # deeper than the node's: a probe's thread shares the GIL with the node's executor
        probe_qos = QoSProfile(
            history=qos.history,
            depth=max(qos.depth, 10_000),
            reliability=qos.reliability,
            durability=qos.durability,
        )
        try:
            for k, pairs in enumerate(probe_slots(topics)):
                self._start(k, pairs, classes, probe_qos)
        except BaseException:
            self.close()  # a signal during the start: no context or thread left behind
            raise

    def _start(
        self, k: int, pairs: list[tuple[str, str]], classes: Callable[[str], Any], qos: Any
    ) -> None:
        """One probe participant's context, node, raw subscriptions and spinning thread."""
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        context = rclpy.Context()
        # the node's own context has the signal handlers; the node's close() shuts these
        rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
        executor = SingleThreadedExecutor(context=context)
        node = rclpy.create_node(
            f'_handeye_type_probe_{k}',
            context=context,
            enable_rosout=False,
            start_parameter_services=False,
        )
        thread = threading.Thread(
            target=self._spin, args=(executor, context), name=f'type-probe-{k}', daemon=True
        )
        self._runs.append((context, executor, node, thread))
        for topic, msgtype in pairs:
            ring = self.early[topic, msgtype] = deque(maxlen=PROBE_DEPTH)
            node.create_subscription(
                classes(msgtype), topic, lambda raw, r=ring: self._received(r, raw), qos, raw=True
            )
        executor.add_node(node)
        thread.start()

    def _received(self, ring: deque[tuple[bytes, int]], raw: bytes) -> None:
        ring.append((raw, self._clock.now().nanoseconds))

    def _spin(self, executor: Any, context: Any) -> None:
        """Spin one probe until :meth:`close` says stop or its context is shut down.

        In short waits, not ``executor.spin()``: a SIGINT or SIGTERM makes rclpy's handler
        shut down *every* context of the process, these included, at any instant, and a wait
        set made on a context shut down a moment before raises; the stop flag is checked
        between waits, so that close() never destroys what a wait still uses."""
        try:
            while not self._stop.is_set() and context.ok():
                executor.spin_once(timeout_sec=SPIN_WAIT_S)
        except Exception:
            if context.ok() and not self._stop.is_set():
                raise
            # shut down under the wait (a signal): the end this thread was heading for

    def close(self) -> None:
        """Stop every probe's thread, then destroy its executor, node and context
        (idempotent; after a signal the contexts may already be shut down)."""
        runs, self._runs = self._runs, []
        self._stop.set()
        for _, _, _, thread in runs:
            if thread.is_alive():
                thread.join(timeout=5.0)
        for context, executor, node, thread in runs:
            if not thread.is_alive():  # else a wait still uses them: leave them to the exit
                executor.shutdown()
                node.destroy_node()
            context.try_shutdown()
