"""The ``calibrator`` node: buffer a MoCap and a VO/VIO pose stream, calibrate on request.

``ros2 run handeye_ros calibrator [--ros-args --params-file config/calibrator.yaml]``

Subscriptions feed a :class:`~handeye_ros.stream.Recorder` (the same conversion and buffers the
offline bag replay uses). Services (std_srvs/Trigger): ``~/calibrate`` runs the core on a copy
of the buffers in a worker process while the subscriptions keep flowing (a second call while
one runs is refused), ``~/reset`` empties the buffers, ``~/save`` writes the last result.

Concurrency: one single-threaded executor runs every callback (rclpy's multi-threaded executor
costs so much per callback that a 1 kHz stream overruns it). ``~/calibrate`` is a coroutine:
it snapshots the buffers, hands the snapshot to a worker *process* and awaits the result, so
the executor keeps taking messages meanwhile. A process rather than a thread: at 1 kHz the
executor holds the GIL most of the time, and a calibration thread beside it ran ten times
slower. A worker is spawned, and imports the core, when the node starts, so a call pays no
start-up; a second when a job comes while the first is busy. A job's answer comes back on the
executor's thread (:meth:`CalibratorNode.on_executor`), which alone publishes and changes the
node's state.
SIGINT or SIGTERM stop the node (exit code 0) after its workers (:meth:`CalibratorNode.close`;
a running calibration is abandoned, a waiting caller told "aborted: shutting down").
Every calibration, successful or not, updates every output together: a success publishes on
every latched output at once, stamped alike (:mod:`.outputs`); a failure, which cannot
unpublish latched messages, says ERROR on /diagnostics with the reason and names the latched
outputs as stale (the result they come from and when).

The subscriptions (types learnt from the graph, QoS, why a stream is empty) are in
:mod:`.subscriptions`, the parameters (declared from the option specs, changed at run time,
misspelt names said) in :mod:`.parameters`, the /diagnostics statuses in :mod:`.diagnostics`,
the worker processes in :mod:`.worker`, the result's publishers in :mod:`.outputs` (its
messages in :mod:`handeye_ros.formats.messages`), the start and stop in :mod:`.calibrator`.
"""

from __future__ import annotations

import concurrent.futures as cf
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Mapping
from typing import TypeVar

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from std_srvs.srv import Trigger

from ..core.errors import HandeyeError, InputError
from ..stream import STREAMS, Recorder
from ..stream.shapes import Message, MessageInfo
from . import diagnostics, parameters, worker
from .calls import ABORTED, BUSY, QUEUED, answer_with, waiting
from .files import inside
from .host import Job
from .jobs import Calibrated, calibrate_buffers
from .lifecycle import steady_timer
from .outputs import Outputs, quiet_publisher, save
from .status import ReadinessStatus
from .subscriptions import Subscriptions
from .types import RclpyTypes

#: Seconds between two warnings about rejected messages of one stream.
REJECT_WARN_PERIOD_S = 5.0
_R = TypeVar('_R')


class CalibratorNode(Node):
    """See the module docstring."""

    def __init__(self, pool: worker.Pool) -> None:
        """``pool``: the worker (:func:`.worker.new_pool`, started before rclpy.init); the
        node owns it from here and stops it in :meth:`close`."""
        super().__init__('calibrator')
        self.calib_cfg, self.stream_cfg, self.node_cfg = parameters.declare_and_read(self)
        parameters.refuse_unknown(self)
        self.recorder = Recorder(self.stream_cfg)
        self._busy = False  # a calibration runs (set and cleared on the executor's thread)
        #: its kind, and a call waiting for it to end
        self._running: tuple[Job, Future | None] = (Job.CALL, None)
        #: the last successful result, when it came (wall clock), and the last failure's
        #: reason (None after a success): the three things every output is made from
        self._last_result: Calibrated | None = None
        self._last_when = ''
        self._last_error: str | None = None
        self._reject_warned = dict.fromkeys(STREAMS, 0.0)
        #: this session's name in a rig file (rig_file): the buffers since the start or ~/reset
        self._session = _session_name()
        #: when each stream's last message came (monotonic s; 0: never), and its last pose
        #: that moved its clock (PoseBuffer.ticked): messages without a usable pose leave it
        self.last_seen = dict.fromkeys(STREAMS, 0.0)
        self.last_ticked = dict.fromkeys(STREAMS, 0.0)
        #: that last pose's reception by DDS (system clock, s; 0: not said by the middleware) and
        #: how late the node took it (s): a busy node's own arrival times move with its backlog
        self.last_received = dict.fromkeys(STREAMS, 0.0)
        self.taken_late = dict.fromkeys(STREAMS, 0.0)
        self._types = RclpyTypes()
        self._outputs = Outputs(self, self._types)
        self.pub_diag = quiet_publisher(self, DiagnosticArray, '/diagnostics', 10)
        # reentrant: an awaiting coroutine keeps its group busy (the default one: every callback)
        self.create_service(
            Trigger, '~/calibrate', self._on_calibrate, callback_group=ReentrantCallbackGroup()
        )
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(Trigger, '~/save', self._on_save)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._closing, self._open_calls = False, 0  # ~/calibrate calls awaiting their answer
        self._busy_since = 0.0
        self._pool: worker.Pool | None = pool
        self.poses = Subscriptions(
            self, self.recorder, self._on_pose, lambda: (self.stream_cfg, self.node_cfg)
        )
        status = quiet_publisher(self, DiagnosticStatus, '~/status', 10)
        self.status = ReadinessStatus(self, self.node_cfg.auto_calibrate, status.publish)
        if self.node_cfg.status_period > 0.0:
            steady_timer(self, self.node_cfg.status_period, self.status.tick)
        steady_timer(self, self.node_cfg.diagnostics_period, self._publish_diagnostics)
        if self.node_cfg.calibrate_period > 0.0:
            steady_timer(self, self.node_cfg.calibrate_period, self._periodic_calibrate)
        parameters.warn_unused_params_files(self, sys.argv)
        self.get_logger().info(
            f'buffering hand {self.poses.shown("hand")} and eye {self.poses.shown("eye")}; '
            f'call {self.get_fully_qualified_name()}/calibrate when the rig has moved'
        )

    @property
    def open_calls(self) -> int:
        """``~/calibrate`` calls still waiting for their calibration's answer."""
        return self._open_calls

    @property
    def busy(self) -> bool:
        """Whether a calibration runs."""
        return self._busy

    @property
    def closing(self) -> bool:
        """Whether the node is stopping (its worker is being stopped)."""
        return self._closing

    def options(self) -> Mapping[str, object]:
        """The algorithm's options as the worker's jobs take them."""
        return self.calib_cfg.to_dict()

    def submit(self, fn: Callable[..., _R], *args: object) -> cf.Future[_R]:
        """A job for the worker pool (RuntimeError once it is shut down)."""
        if self._pool is None:
            raise RuntimeError('the node is closing: its worker pool is stopped')
        return self._pool.submit(fn, *args)

    def on_executor(self, fn: Callable[..., object], *args: object) -> None:
        """Run ``fn(*args)`` on the executor's thread, from any thread (a worker job's done
        callback runs in the pool's): every output is published, and every state changed,
        from the one thread that spins the node."""
        executor = self.executor
        if executor is None:  # not spun (a test's node): nothing else runs
            fn(*args)
        else:
            executor.create_task(fn, *args)

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        answer, self.calib_cfg, self.node_cfg = parameters.apply_changes(
            params, self.calib_cfg, self.node_cfg
        )
        return answer

    def _on_pose(self, stream: str, msg: Message, static: bool, info: MessageInfo) -> None:
        self.last_seen[stream] = now = time.monotonic()
        arrival = self.get_clock().now().nanoseconds if stream in self.recorder.arrival else None
        buffer = self.recorder.buffers[stream]
        ticked = buffer.ticked
        self._add(stream, msg, static, arrival)
        if buffer.ticked != ticked:
            self.last_ticked[stream] = now
            received = int(info.get('received_timestamp', 0)) * 1e-9
            self.last_received[stream] = received
            self.taken_late[stream] = time.time() - received if received else 0.0

    def _add(self, stream: str, msg: Message, static: bool, arrival: int | None) -> None:
        reason = self.recorder.add(stream, msg, static, arrival)
        if reason is not None:
            now = time.monotonic()
            if now - self._reject_warned[stream] >= REJECT_WARN_PERIOD_S:
                self._reject_warned[stream] = now
                rejected = self.recorder.buffers[stream].rejected
                hint = (
                    ' (a publisher restarted? call ~/reset to start the buffers over)'
                    if reason == 'stamp_not_increasing'
                    else ''
                )
                self.get_logger().warning(
                    f'{stream}: rejected a message ({reason.replace("_", " ")}){hint}; rejected '
                    f'so far: {", ".join(f"{k} {v}" for k, v in rejected.items() if v)}'
                )

    def calibrate(self, job: Job = Job.CALL) -> Future | None:
        """Calibrate a snapshot of the buffers in the worker process, unless one runs.

        Returns an rclpy Future that completes on the executor with (success, message), or
        None when a calibration is already running (a call during a check waits for it to end).
        A check (the status's) is published when auto mode says so
        (:meth:`.ReadinessStatus.took`).
        """
        if self._busy:  # a call during a check calibrates the buffers once that ends
            queued = None if job is Job.CHECK else waiting(self._running, self.executor)
            if queued is not None:
                self._running = (self._running[0], queued)
                self.get_logger().info(QUEUED)
            return queued
        self._busy = True
        future = Future(executor=self.executor)
        # a done callback makes the completion wake the executor (it schedules a task)
        future.add_done_callback(lambda _: None)
        if self._closing:  # a call taken while the stop answers the others: no worker left
            future.set_result((False, ABORTED))
            self._busy = False
            return future
        self._busy_since = time.monotonic()
        why = self.poses.why_no_data()
        stage = None
        span = 0.0
        try:
            if why is not None:
                raise InputError(why)
            snapshot = self.recorder.snapshot()
            span = snapshot.span_s
            t0 = time.perf_counter()
            stage = (
                tempfile.mkdtemp(prefix='handeye_report_') if self.node_cfg.report_dir else None
            )
            rig_file = self.node_cfg.rig_file
            rig = (
                (str(inside(self.node_cfg.output_dir, rig_file, 'rig_file')), self._session)
                if rig_file
                else None
            )
            work = self.submit(calibrate_buffers, snapshot, self.calib_cfg.to_dict(), stage, rig)
            self.get_logger().info(
                f'calibrating {len(snapshot.hand)} MoCap and {len(snapshot.eye)} device poses'
                + (' (checking READY)' if job is Job.CHECK else '')
            )
        except (HandeyeError, RuntimeError) as err:  # RuntimeError: pool shut down
            if job is Job.CALL:
                self._failed(str(err))
            self.status.took(None, err, job, span, 0.0)
            future.set_result((False, str(err)))
            self._drop_stage(stage)
            self._busy = False
            return future

        self._running = (job, None)
        work.add_done_callback(
            lambda work: self.on_executor(self._calibrated, work, future, stage, (t0, span))
        )
        return future

    def _calibrated(
        self,
        work: cf.Future[Calibrated],
        future: Future,
        stage: str | None,
        started: tuple[float, float],
    ) -> None:
        """The worker's answer to the running calibration (started at ``started``:
        perf_counter s, of a buffered span [s]), on the executor: the status's, then the
        outputs, the log, the answer (ABORTED when the node's stop ended it); a call that waited
        for a check is calibrated next. A success keeps the report's staging folder."""
        job, queued = self._running
        t0, span = started
        took = time.perf_counter() - t0
        kept = False
        try:
            session = work.result()
        except HandeyeError as err:
            if job is Job.CHECK:  # no result was asked for: the status says it failed
                self.get_logger().info(f'checking READY: the calibration failed ({err})')
            else:
                self._failed(str(err))
            self.status.took(None, err, job, span, took)
            future.set_result((False, str(err)))
        except Exception as err:  # noqa: BLE001  (a crashed worker: reported, pool renewed)
            if self._closing:  # the node stopped it
                future.set_result((False, ABORTED))
                return
            self.get_logger().error(f'calibration worker failed: {err!r}')
            if isinstance(err, cf.process.BrokenProcessPool):
                self._pool = worker.new_pool()
            self._failed(f'internal error: {err!r}')
            self.status.took(None, RuntimeError(f'internal error: {err!r}'), job, span, took)
            future.set_result((False, f'internal error: {err!r}'))
        else:
            said = session.result.said() + session.rig_said
            if not self.status.took(session.result, None, job, span, took):
                said = f'checked READY in {took:.2f} s, not published: {said}'
                self.get_logger().info(said)
                future.set_result((True, said))
                return
            self._drop_stage(self._last_result)
            kept = True
            self._succeeded(session)
            self.get_logger().info(f'calibrated in {took:.2f} s: {said}')
            for w in session.result.warnings:
                self.get_logger().warning(w)
            future.set_result((True, said))
        finally:
            if not kept:  # a failed calibration leaves no report to keep
                self._drop_stage(stage)
            self._busy = False
            if queued is not None:
                answer_with(queued, self.calibrate())

    async def _on_calibrate(self, req: Trigger.Request, res: Trigger.Response) -> Trigger.Response:
        future = self.calibrate()
        if future is None:
            res.success = False
            res.message = BUSY
            return res
        self._open_calls += 1
        try:
            res.success, res.message = await future
        finally:
            # the executor sends the response in the same step, right after this returns
            self._open_calls -= 1
        return res

    def _periodic_calibrate(self) -> None:
        if self.poses.why_no_data() is None:
            self.calibrate()

    def _on_reset(self, req: Trigger.Request, res: Trigger.Response) -> Trigger.Response:
        self.recorder.reset()
        self._session = _session_name()
        self.status.reset()
        res.success = True
        res.message = 'buffers cleared' + (
            ' (the running calibration works on its own copy and will still answer)'
            if self._busy
            else ''
        )
        return res

    def _on_save(self, req: Trigger.Request, res: Trigger.Response) -> Trigger.Response:
        if self._last_result is None:
            res.success = False
            res.message = (
                'no result to save: call calibrate first'
                if self._last_error is None
                else f'no result to save: the calibration failed ({self._last_error})'
            )
            return res
        res.success, res.message = save(self._last_result, self.node_cfg)
        if res.success and self._last_error is not None:
            res.message += (
                f' (the latest calibration failed: this is the result of {self._last_when})'
            )
        return res

    @staticmethod
    def _drop_stage(stage: str | Calibrated | None) -> None:
        """Remove a staging folder of the worker's report (this one, or a result's)."""
        folder = stage.staged_dir if isinstance(stage, Calibrated) else stage
        if folder:
            shutil.rmtree(folder, ignore_errors=True)

    def close(self) -> None:
        """Stop the worker process and wait for it (a running calibration is abandoned), so
        that no process outlives the node."""
        self._closing = True
        if self._pool is not None:
            worker.stop(self._pool)
            self._pool = None
        self._drop_stage(self._last_result)

    def _succeeded(self, session: Calibrated) -> None:
        """A new result: every output at once, one stamp (on the executor)."""
        self._last_result, self._last_error = session, None
        self._last_when = time.strftime('%Y-%m-%d %H:%M:%S')
        self._outputs.publish(session, self.get_clock().now().nanoseconds)
        self._publish_diagnostics()

    def _failed(self, why: str) -> None:
        """A failed calibration: the diagnostics say so at once; the latched outputs, which
        cannot be withdrawn, are named stale there."""
        self._last_error = why
        self._publish_diagnostics()

    def _publish_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        name = self.get_fully_qualified_name()
        now = time.monotonic()
        for stream, s in self.recorder.stats().items():
            topic = getattr(self.stream_cfg, f'{stream}_topic')
            msgtype = self.recorder.types[stream] or 'not known yet'
            if stream in self.poses.guessed:
                msgtype += ' (likeliest; not yet seen on the graph)'
            seen = self.last_seen[stream]
            quiet = now - seen if seen else 0.0
            arr.status.append(diagnostics.stream_status(name, stream, s, topic, msgtype, quiet))
        busy = time.monotonic() - self._busy_since if self._busy else None
        arr.status.append(
            diagnostics.result_status(
                name, self._last_result, self._last_when, self._last_error, busy
            )
        )
        arr.status.append(self.status.status())
        self.pub_diag.publish(arr)


def _session_name() -> str:
    """A session's name in a rig file: when its buffers started (local time, to the ms)."""
    now = time.time()
    stamp = time.strftime('%Y-%m-%d %H:%M:%S', time.localtime(now))
    return f'session {stamp}.{int(now * 1000) % 1000:03d}'
