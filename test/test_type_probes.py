"""The handover from a type probe's messages to the node's own subscription (no DDS here; the
live case is test_node.py::test_auto_types_lose_nothing)."""

from __future__ import annotations

from collections import deque

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from handeye_ros.core.errors import ConfigError
from handeye_ros.ros.type_probes import Handover, candidate_types, message_key, probe_slots
from handeye_ros.stream.convert import MULTI_POSE_TYPES, SUPPORTED_TYPES


def _ring(msgs: list[str], depth: int = 100) -> deque[tuple[bytes, int]]:
    """A probe's ring: serialised messages (here plain text) with their arrival."""
    return deque(((m.encode(), k) for k, m in enumerate(msgs)), maxlen=depth)


def _handover(ring: deque[tuple[bytes, int]]) -> Handover:
    return Handover(ring, lambda raw: raw.decode(), lambda msg: msg)


def test_probe_messages_before_the_first_own_then_the_own_ones() -> None:
    msgs = [f'm{k}' for k in range(10)]
    h = _handover(_ring(msgs))
    assert h.settle(now=0.0) is None  # nothing of its own yet: nothing to place
    h.hold('m6', 106, now=0.0)
    h.hold('m7', 107, now=0.0)
    early, own = h.settle(now=0.0)
    assert [m for m, _ in early] == msgs[:6]
    assert [a for _, a in early] == list(range(6))  # the probe's arrival stamps
    assert own == [('m6', 106), ('m7', 107)]
    assert h.outcome == 'caught up'
    assert h.settle(now=1.0) is None  # settled once


def test_waits_for_a_lagging_probe_then_gives_up_after_the_timeout() -> None:
    ring = _ring(['m0', 'm1'])
    h = _handover(ring)
    h.hold('m4', None, now=10.0)
    assert h.settle(now=10.5, timeout=2.0) is None  # the probe has not reached m4 yet
    ring.extend([(b'm2', 2), (b'm3', 3), (b'm4', 4)])
    h.hold('m5', None, now=10.6)
    early, own = h.settle(now=10.7, timeout=2.0)
    assert [m for m, _ in early] == ['m0', 'm1', 'm2', 'm3'] and len(own) == 2

    h = _handover(_ring(['x0', 'x1']))  # a probe that never sees the node's messages
    h.hold('m0', None, now=0.0)
    assert h.settle(now=1.9, timeout=2.0) is None
    assert h.settle(now=2.0, timeout=2.0) == ([], [('m0', None)])
    assert h.outcome == 'timed out'


def test_a_probe_that_still_receives_is_waited_for_up_to_the_limit() -> None:
    """A probe far behind the node (its thread starved of the GIL on a loaded machine) keeps
    the handover open while it receives, past the silence timeout; the limit ends it."""
    ring = _ring(['m0'])
    h = _handover(ring)
    h.hold('m9', None, now=0.0)
    for k in range(1, 9):  # one probe message a second: never silent for 2 s
        ring.append((f'm{k}'.encode(), k))
        assert h.settle(now=float(k), timeout=2.0) is None
    ring.append((b'm9', 9))
    early, own = h.settle(now=9.0, timeout=2.0)
    assert [m for m, _ in early] == [f'm{k}' for k in range(9)] and own == [('m9', None)]

    ring = _ring(['x0'])
    h = _handover(ring)
    h.hold('m0', None, now=0.0)
    for k in range(1, 10):
        ring.append((f'x{k}'.encode(), k))
        assert h.settle(now=float(k), timeout=2.0, limit=10.0) is None
    ring.append((b'x10', 10))
    assert h.settle(now=10.0, timeout=2.0, limit=10.0) == ([], [('m0', None)])


def test_identical_messages_are_not_handed_in_twice() -> None:
    """Zero stamps and a rig at rest make equal messages: the first equal one is where the
    node's own messages begin, so nothing the node received is added again."""
    h = _handover(_ring(['a', 'b', 'b', 'b', 'c']))
    h.hold('b', None, now=0.0)
    early, own = h.settle(now=0.0)
    assert [m for m, _ in early] == ['a'] and [m for m, _ in own] == ['b']


def test_a_first_message_the_probe_dropped_is_placed_by_the_next() -> None:
    """The probe (a thread sharing the GIL) lost m5, the node's first: m6 places it."""
    h = _handover(_ring(['m0', 'm1', 'm2', 'm3', 'm4', 'm6', 'm7']))
    h.hold('m5', None, now=0.0)
    assert h.settle(now=0.0) is None
    h.hold('m6', None, now=0.0)
    early, own = h.settle(now=0.0)
    assert [m for m, _ in early] == ['m0', 'm1', 'm2', 'm3', 'm4']
    assert [m for m, _ in own] == ['m5', 'm6']


def test_message_keys_equal_for_equal_messages_whatever_their_bytes() -> None:
    """rclpy's serialiser leaves the padding after a string uninitialised, so bytes cannot
    tell equal messages; the keys can, down to arrays and nested lists."""
    pytest.importorskip('rclpy')
    from geometry_msgs.msg import PoseStamped, TransformStamped
    from nav_msgs.msg import Odometry

    a, b = Odometry(), Odometry()
    for m in (a, b):
        m.header.frame_id, m.pose.pose.position.x = 'odom', 1.5
        m.pose.covariance[7] = 0.25
    assert message_key(a) == message_key(b) and hash(message_key(a)) == hash(message_key(b))
    b.pose.covariance[7] = 0.5
    assert message_key(a) != message_key(b)
    p = PoseStamped()
    q = PoseStamped()
    q.header.stamp.nanosec = 1
    assert message_key(p) != message_key(q)
    assert message_key([TransformStamped(), TransformStamped()]) == message_key(
        [TransformStamped(), TransformStamped()]
    )


def test_a_ring_that_wrapped_during_the_search_is_searched_again() -> None:
    ring = _ring(['m0', 'm1', 'm2'], depth=3)
    h = _handover(ring)
    h.hold('m4', None, now=0.0)
    assert h.settle(now=0.0) is None
    ring.extend([(b'm3', 3), (b'm4', 4)])  # m0, m1 fall out of the ring
    early, _ = h.settle(now=0.0)
    assert [m for m, _ in early] == ['m2', 'm3']


def test_candidates_are_the_importable_types_that_fit_the_selector() -> None:
    def only_geometry(t: str) -> object:
        if not t.startswith('geometry_msgs/'):
            raise ConfigError(f'{t} cannot be imported')
        return object

    assert candidate_types(False, lambda t: object) == list(SUPPORTED_TYPES)
    assert candidate_types(True, lambda t: object) == list(MULTI_POSE_TYPES)
    assert candidate_types(False, only_geometry) == [
        t for t in SUPPORTED_TYPES if t.startswith('geometry_msgs/')
    ]
    assert candidate_types(True, only_geometry) == []


@pytest.mark.parametrize('n', [0, 1])
def test_an_empty_probe_times_out(n: int) -> None:
    h = _handover(_ring([]))
    for k in range(n):
        h.hold(f'm{k}', None, now=0.0)
    out = h.settle(now=5.0, timeout=2.0)
    assert out == (None if n == 0 else ([], [('m0', None)]))


@given(
    n=st.integers(5, 60),
    data=st.data(),
)
@settings(max_examples=300, deadline=None)
def test_handover_gives_each_message_once_in_order(n: int, data: st.DataObject) -> None:
    """Any point where the node's subscription starts, any messages the probe drops (not all
    of the node's), any interleaving of the two threads: the node gets the probe's messages
    from before its own first, then its own, each once and in order."""
    sent = [f'm{k}' for k in range(n)]
    node_from = data.draw(st.integers(1, n - 1))
    probe_from = data.draw(st.integers(0, node_from))
    probe_got = [
        m for m in sent[probe_from:] if data.draw(st.booleans()) or m == sent[-1]
    ]  # the probe keeps the last one, so a meeting point exists
    ring: deque[tuple[bytes, int]] = deque(maxlen=1000)
    h = _handover(ring)
    own = sent[node_from:]
    i = j = 0
    out = None
    while out is None:
        if i < len(probe_got) and (j == len(own) or data.draw(st.booleans())):
            ring.append((probe_got[i].encode(), i))
            i += 1
        elif j < len(own):
            h.hold(own[j], None, now=0.0)
            j += 1
        out = h.settle(now=0.0)
        assert out is not None or i < len(probe_got) or j < len(own)
    early, held = out
    # what a thread-safe handover must give: then the node's later messages go straight in
    got = [m for m, _ in early] + [m for m, _ in held] + own[j:]
    before = [m for m in probe_got if int(m[1:]) < node_from]
    assert got == before + own


def test_probe_slots_hold_one_type_of_a_topic_each_and_no_more_than_needed() -> None:
    """A DDS participant refuses a second type on one topic: the k-th candidates of every
    topic share the k-th participant, so two topics of three candidates need three."""
    topics = {'/hand': ['A', 'B', 'C'], '/eye': ['B', 'D'], '/other': []}
    slots = probe_slots(topics)
    assert slots == [
        [('/hand', 'A'), ('/eye', 'B')],
        [('/hand', 'B'), ('/eye', 'D')],
        [('/hand', 'C')],
    ]
    for pairs in slots:
        names = [t for t, _ in pairs]
        assert len(names) == len(set(names))
    assert sorted(p for pairs in slots for p in pairs) == sorted(
        (t, m) for t, ms in topics.items() for m in ms
    )
