"""What the readiness status and auto mode read of the node that holds them
(:class:`StatusHost`): a Protocol the node meets, so that neither imports the node."""

from __future__ import annotations

import concurrent.futures as cf
from collections.abc import Callable, Mapping
from typing import Protocol, TypeVar

from rclpy.clock import Clock
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.task import Future

from ..core.config import CalibrationConfig
from ..stream import Recorder

_R = TypeVar('_R')


class Waiting(Protocol):
    """The node's pose subscriptions, as the status reads them."""

    def why_no_data(self) -> str | None:
        """Why no pose has come yet (a topic without publisher, a type that does not match),
        or None."""
        ...


class StatusHost(Protocol):
    """The node, as its status and auto mode use it: its options and buffers, when each stream
    was last seen, received and taken, its worker and executor, and a calibration."""

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

    def options(self) -> Mapping[str, object]: ...

    def submit(self, fn: Callable[..., _R], *args: object) -> cf.Future[_R]: ...

    def on_executor(self, fn: Callable[..., object], *args: object) -> None: ...

    def calibrate(self, auto: bool = False, check: bool = False) -> Future | None: ...

    def get_clock(self) -> Clock: ...

    def get_logger(self) -> RcutilsLogger: ...

    def get_fully_qualified_name(self) -> str: ...
