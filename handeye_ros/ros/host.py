"""What the readiness status reads of the node that holds it (:class:`StatusHost`): a
Protocol the node meets, so that the status does not import the node; and the kinds of
calibration the node runs (:class:`Job`)."""

from __future__ import annotations

from enum import Enum
from typing import Protocol

from rclpy.clock import Clock
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.task import Future

from ..core.config import CalibrationConfig
from ..stream import Recorder


class Job(Enum):
    """A calibration of the buffers: asked for (``~/calibrate``, ``calibrate_period``: always
    published) or the status's own check of READY (published when auto mode says so)."""

    CALL = 'call'
    CHECK = 'check'


class Waiting(Protocol):
    """The node's pose subscriptions, as the status reads them."""

    def why_no_data(self) -> str | None:
        """Why no pose has come yet (a topic without publisher, a type that does not match),
        or None."""
        ...


class StatusHost(Protocol):
    """The node, as its status uses it: its options and buffers, when each stream was last
    seen, received and taken, and a calibration."""

    calib_cfg: CalibrationConfig
    recorder: Recorder
    last_seen: dict[str, float]
    last_ticked: dict[str, float]
    last_received: dict[str, float]
    taken_late: dict[str, float]

    @property
    def closing(self) -> bool: ...

    @property
    def poses(self) -> Waiting: ...

    @property
    def busy(self) -> bool: ...

    def calibrate(self, job: Job = Job.CALL) -> Future | None: ...

    def get_clock(self) -> Clock: ...

    def get_logger(self) -> RcutilsLogger: ...

    def get_fully_qualified_name(self) -> str: ...
