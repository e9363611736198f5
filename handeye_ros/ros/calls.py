"""What the node answers a ``~/calibrate`` call with when its calibration does not simply run:
the node stopped it, another one runs, or it waited for the status's check of READY."""

from __future__ import annotations

from rclpy.task import Future

from .host import Job

#: The answer to a call whose calibration the node's stop abandoned.
ABORTED = 'aborted: shutting down'
#: Logged when a call waits for the status's check of READY, which runs, to end.
QUEUED = '~/calibrate: calibrating the buffers once the running check of READY ends'
#: The answer to a call while a calibration runs (other than a check of READY).
BUSY = 'a calibration is already running; call again when it has finished'


def waiting(running: tuple[Job, Future | None], executor: object) -> Future | None:
    """A call's future that waits for the running calibration (``running``: its kind and the
    call already waiting, if one) to end, when that is a check of READY that no call waits for
    yet; else None (the call is refused)."""
    kind, queued = running
    if kind is not Job.CHECK or queued is not None:
        return None
    queued = Future(executor=executor)
    queued.add_done_callback(lambda _: None)  # its completion wakes the executor
    return queued


def answer_with(queued: Future, started: Future | None) -> None:
    """Answer a call that waited (``queued``) with the calibration started for it."""
    if started is None:  # another one came first
        queued.set_result((False, BUSY))
        return
    started.add_done_callback(lambda f: queued.set_result(f.result()))
