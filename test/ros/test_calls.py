"""The answers of the node's calibrate calls that do not simply run (ros/calls.py): a call during
the status's check of READY waits for it and is then calibrated; any other call while a
calibration runs is refused."""

from __future__ import annotations

import pytest

pytest.importorskip('rclpy')

from rclpy.task import Future

from handeye_ros.ros.calls import BUSY, answer_with, waiting
from handeye_ros.ros.host import Job


def test_only_one_call_waits_and_only_for_a_check() -> None:
    queued = waiting((Job.CHECK, None), None)
    assert isinstance(queued, Future) and not queued.done()
    assert waiting((Job.CHECK, queued), None) is None  # one waits already: refused
    assert waiting((Job.CALL, None), None) is None  # a user's calibration runs: refused


def test_a_waiting_call_gets_the_answer_of_the_calibration_started_for_it() -> None:
    queued, started = Future(), Future()
    answer_with(queued, started)
    assert not queued.done()
    started.set_result((True, 'good: ...'))
    assert queued.result() == (True, 'good: ...')
    refused = Future()
    answer_with(refused, None)  # another calibration came first
    assert refused.result() == (False, BUSY)
