"""The handover from a type probe's messages to the node's own subscription (no DDS here; the
live case is test_node.py::test_auto_types_lose_nothing)."""

from __future__ import annotations

from collections import deque

import pytest

from handeye_ros.core.errors import ConfigError
from handeye_ros.ros.type_probes import Handover, candidate_types
from handeye_ros.stream.convert import MULTI_POSE_TYPES, SUPPORTED_TYPES


def _ring(msgs: list[str], depth: int = 100) -> deque[tuple[bytes, int]]:
    """A probe's ring: serialised messages (here plain text) with their arrival."""
    return deque(((m.encode(), k) for k, m in enumerate(msgs)), maxlen=depth)


def _handover(ring: deque[tuple[bytes, int]]) -> Handover:
    return Handover(ring, lambda raw: raw.decode())


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


def test_identical_messages_are_not_handed_in_twice() -> None:
    """Zero stamps and a rig at rest make equal messages: the first equal one is where the
    node's own messages begin, so nothing the node received is added again."""
    h = _handover(_ring(['a', 'b', 'b', 'b', 'c']))
    h.hold('b', None, now=0.0)
    early, own = h.settle(now=0.0)
    assert [m for m, _ in early] == ['a'] and [m for m, _ in own] == ['b']


def test_a_ring_that_wrapped_during_the_search_is_searched_again() -> None:
    ring = _ring(['m0', 'm1', 'm2'], depth=3)
    h = _handover(ring)
    h.hold('m4', None, now=0.0)
    assert h.settle(now=0.0) is None and h.searched == 3
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
