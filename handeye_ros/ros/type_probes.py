"""The first messages of an auto-typed stream, received before its type is known.

With ``hand_type: auto`` (or ``eye_type``) the node learns a topic's type from its publisher in
the graph and subscribes then. A subscription receives a publisher's messages only once the two
have matched, which takes a discovery handshake. A publisher that sends as soon as it appears
(``ros2 bag play``, a MoCap driver started after the node) therefore lost its first messages to
the node: the graph poll, the new subscription and the match take a fraction of a second, which
is hundreds of poses at 1 kHz.

rclpy cannot subscribe to a topic before it knows the type, and one DDS participant refuses a
second subscription of another type on the same topic. So :class:`TypeProbes` gives every
candidate type its own rclpy context (its own participant) with a *raw* subscription (the
serialised bytes, never deserialised there) on every auto-typed topic, spun by its own thread.
The probe of the right type matches the publisher as early as a typed subscription made at the
start would.

When the node's own subscription delivers its first message, :class:`Handover` finds that
message among the probe's by comparing whole messages (not stamps, which may be zero or
repeated; not bytes, whose alignment padding the publisher need not initialise) and gives the
node the probe's messages before it, then its own: nothing lost, nothing twice. If the probe
never saw that message (it matched later, or not at all) the handover gives up after a bounded
wait and says that earlier messages may be missing. The probes are shut down as soon as every
auto-typed stream has been handed over.
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
#: within a graph poll, 0.2 s, of the type appearing).
PROBE_DEPTH = 20_000
#: Seconds the node's own messages wait for the probe to show where they start, before the
#: handover gives up (and says so).
HANDOVER_TIMEOUT_S = 2.0


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


@dataclass
class Handover:
    """One stream's switch from its probe's messages to its own subscription's.

    ``early``: the probe's (serialised message, arrival ns) of the stream's topic and type,
    appended by the probe's thread; ``decode``: serialised bytes -> message. The node's own
    messages are held in ``pending`` until :meth:`settle` finds the first of them among
    ``early``."""

    early: deque[tuple[bytes, int]]
    decode: Callable[[bytes], Any]
    pending: list[tuple[Any, int | None]] = field(default_factory=list)
    since: float = 0.0
    #: how many of ``early`` were decoded and found unequal to the node's first message
    searched: int = 0
    decoded: list[tuple[Any, int]] = field(default_factory=list)
    #: '' while open; 'caught up' or 'timed out' once settled
    outcome: str = ''

    def hold(self, msg: Any, arrival_ns: int | None, now: float) -> None:
        """Keep one of the node's own messages until the handover settles."""
        if not self.pending:
            self.since = now
        self.pending.append((msg, arrival_ns))

    def settle(
        self, now: float, timeout: float = HANDOVER_TIMEOUT_S
    ) -> tuple[list[tuple[Any, int]], list[tuple[Any, int | None]]] | None:
        """None while open; else (the probe's messages that came before the node's first,
        with their arrival; the node's own held messages), both in order."""
        if self.outcome or not self.pending:
            return None
        first = self.pending[0][0]
        early = list(self.early)  # a snapshot: the probe's thread may still append
        if len(early) == self.early.maxlen and self.searched:
            # the ring wrapped while we searched: where we were is gone (a probe ahead by
            # its whole depth); start again from what it holds
            self.searched, self.decoded = 0, []
        for raw, arrival in early[self.searched :]:
            msg = self.decode(raw)
            if msg == first:
                self.outcome = 'caught up'
                return self.decoded, self._release()
            self.decoded.append((msg, arrival))
            self.searched += 1
        if now - self.since < timeout:
            return None
        self.outcome = 'timed out'
        self.decoded = []
        return [], self._release()

    def _release(self) -> list[tuple[Any, int | None]]:
        pending, self.pending = self.pending, []
        return pending


class TypeProbes:
    """One raw subscription per (auto-typed topic, candidate type), each type in a context of
    its own, spun by a thread of its own; see the module docstring.

    ``topics``: fully qualified topic -> candidate 'pkg/msg/Name' types; ``classes``: the rclpy
    class of a type; ``qos``: the profile of the node's own subscriptions (its depth is
    raised); ``clock``: the node's clock, for arrival stamps."""

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
        self._clock = clock
        by_type: dict[str, list[str]] = {}
        for topic, types in topics.items():
            for t in types:
                by_type.setdefault(t, []).append(topic)
        # deeper than the node's: a probe's thread shares the GIL with the node's executor
        probe_qos = QoSProfile(
            history=qos.history,
            depth=max(qos.depth, 10_000),
            reliability=qos.reliability,
            durability=qos.durability,
        )
        try:
            for k, (msgtype, names) in enumerate(sorted(by_type.items())):
                self._start(k, names, classes(msgtype), msgtype, probe_qos)
        except BaseException:
            self.close()  # a signal during the start: no context or thread left behind
            raise

    def _start(self, k: int, topics: list[str], cls: Any, msgtype: str, qos: Any) -> None:
        """One candidate type's context, node, raw subscriptions and spinning thread."""
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
            target=self._spin, args=(executor,), name=f'type-probe-{k}', daemon=True
        )
        self._runs.append((context, executor, node, thread))
        for topic in topics:
            ring = self.early[topic, msgtype] = deque(maxlen=PROBE_DEPTH)
            node.create_subscription(
                cls, topic, lambda raw, r=ring: self._received(r, raw), qos, raw=True
            )
        executor.add_node(node)
        thread.start()

    def _received(self, ring: deque[tuple[bytes, int]], raw: bytes) -> None:
        ring.append((raw, self._clock.now().nanoseconds))

    @staticmethod
    def _spin(executor: Any) -> None:
        from rclpy.executors import ExternalShutdownException

        try:
            executor.spin()
        except ExternalShutdownException:
            pass

    def close(self) -> None:
        """Shut every probe down and join its thread (idempotent)."""
        runs, self._runs = self._runs, []
        for context, _, _, _ in runs:
            context.try_shutdown()
        for _, executor, node, thread in runs:
            if thread.is_alive():
                thread.join(timeout=5.0)
            executor.shutdown()
            node.destroy_node()
