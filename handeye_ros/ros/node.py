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
slower. The worker is spawned, and imports the core, when the node starts, so a call pays no
start-up. Ctrl-C, SIGINT or SIGTERM stop the node with exit code 0: the worker (a running
calibration is abandoned) is stopped and joined first.
Every calibration, successful or not, updates every output together. A success publishes on
the latched topics of :mod:`handeye_ros.formats.messages` (``~/extrinsic``,
``~/extrinsic_with_covariance``, ``~/time_offset``, ``~/time_reference``), all stamped alike,
and on /tf_static where tf2_msgs is importable. A failure cannot unpublish latched
messages: /diagnostics then says ERROR with the reason, and names the latched outputs as stale
(the result they come from and when). Status goes to /diagnostics.

Auto-typed topics (``hand_type: auto``) are subscribed at once with their likeliest type
(:data:`LIKELY_TYPES`), as a typed node subscribes them; the graph then confirms the type, or
the subscription gives way to the publisher's type. (Raw subscriptions of the other candidate
types, to keep what came before, were measured to change nothing and were removed: RESULTS.md.)

The parameters (declared from the option specs, changed at run time, misspelt names said) are
in :mod:`.parameters`, the /diagnostics statuses in :mod:`.diagnostics`, the worker process in
:mod:`.worker`, the output messages in :mod:`handeye_ros.formats.messages`.
"""

from __future__ import annotations

import concurrent.futures as cf
import shutil
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import (
    SetParametersResult,
)
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSPolicyKind,
    QoSProfile,
    ReliabilityPolicy,
)
from rclpy.task import Future
from std_srvs.srv import Trigger

from ..core.errors import ConfigError, HandeyeError, InputError
from ..evaluation.outputs import calibrate_snapshot
from ..formats import messages
from ..formats.result_file import write_result
from ..stream import STREAMS, SUPPORTED_TYPES, Recorder, normalise_type
from ..stream.convert import TF_TYPE, UnsupportedTypeError
from ..stream.recorder import SessionResult
from . import diagnostics, parameters, worker
from .lifecycle import spin, stop_requested
from .types import RclpyTypes, message_class

#: Latched result topics: late subscribers get the last result.
LATCHED = QoSProfile(
    depth=1,
    history=HistoryPolicy.KEEP_LAST,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
#: Seconds between two warnings about rejected messages of one stream.
REJECT_WARN_PERIOD_S = 5.0
#: Seconds between looks at the graph while an auto-typed stream's type is unknown: a type
#: learnt there is subscribed at the next look (one look costs ~0.02 ms).
GRAPH_POLL_S = 0.05
#: The type a stream's plain pose topic most likely has, subscribed before the graph says
#: (motion capture drivers publish PoseStamped; VIO estimators publish Odometry).
LIKELY_TYPES = {'hand': 'geometry_msgs/msg/PoseStamped', 'eye': 'nav_msgs/msg/Odometry'}


class CalibratorNode(Node):
    """See the module docstring."""

    def __init__(self, pool: cf.ProcessPoolExecutor, **kwargs: Any):
        """``pool``: the worker (:func:`.worker.new_pool`, started before rclpy.init); the
        node owns it from here and stops it in :meth:`close`."""
        super().__init__('calibrator', **kwargs)
        self.calib_cfg, self.stream_cfg, self.node_cfg = parameters.declare_and_read(self)
        self.recorder = Recorder(self.stream_cfg)
        self._check_tf_selectors()
        self._busy = threading.Lock()
        #: the last successful result, when it came (wall clock), and the last failure's
        #: reason (None after a success): the three things every output is made from
        self._last_result: SessionResult | None = None
        self._last_when = ''
        self._last_error: str | None = None
        self._reject_warned = dict.fromkeys(STREAMS, 0.0)
        self._subs: dict[str, Any] = {}
        self._static_subs: dict[str, Any] = {}
        self._sub_errors: dict[str, str] = {}
        self._qos_problems: dict[str, str] = {}
        self._started = time.monotonic()
        self._type_warned = dict.fromkeys(STREAMS, self._started)

        self._types = RclpyTypes()
        self._outputs = {
            name: self.create_publisher(self._types[t], f'~/{name}', LATCHED)
            for name, t in messages.OUTPUT_TYPES.items()
        }
        self._static_tf = self._static_broadcaster()
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        # its own reentrant group: a callback group stays busy while a coroutine in it awaits,
        # and the default (mutually exclusive) group would then hold back every subscription
        self.create_service(
            Trigger, '~/calibrate', self._on_calibrate, callback_group=ReentrantCallbackGroup()
        )
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(Trigger, '~/save', self._on_save)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._closing = False

        self._check_topics()
        #: auto-typed streams subscribed with their likeliest type, not yet confirmed by the
        #: graph (a wrong guess matches no publisher, and gives way to the graph's type)
        self._guessed: set[str] = set()
        for stream in STREAMS:
            declared = getattr(self.stream_cfg, f'{stream}_type')
            if declared != 'auto':
                self._subscribe(stream, normalise_type(declared))
            elif self.recorder.selectors[stream].item is None:
                self._subscribe(stream, LIKELY_TYPES[stream], guess=True)
        self._graph_timer = None
        if len(self._subs) < len(STREAMS) or self._guessed:
            self._graph_timer = self.create_timer(GRAPH_POLL_S, self._discover_types)
        self.create_timer(self.node_cfg.diagnostics_period, self._publish_diagnostics)
        if self.node_cfg.calibrate_period > 0.0:
            self.create_timer(self.node_cfg.calibrate_period, self._periodic_calibrate)
        parameters.warn_unknown(self)
        self._pool = pool
        self.get_logger().info(
            f'buffering hand {self.stream_cfg.hand_topic} and eye {self.stream_cfg.eye_topic}; '
            f'call {self.get_fully_qualified_name()}/calibrate when the rig has moved'
        )

    # ------------------------------------------------------------------ parameters

    def _on_set_parameters(self, params: list[Any]) -> SetParametersResult:
        answer, self.calib_cfg, self.node_cfg = parameters.apply_changes(
            params, self.calib_cfg, self.node_cfg
        )
        return answer

    # ------------------------------------------------------------------ subscriptions

    def _check_topics(self) -> None:
        """Every topic a selector names is a valid ROS name (ConfigError naming the rule)."""
        for stream in STREAMS:
            sel = self.recorder.selectors[stream]
            for topic in sel.topics:
                try:
                    self.resolve_topic_name(topic)
                except RuntimeError as err:  # rclpy's RCLError (exported privately only)
                    why = str(err).split('failed to resolve name: ', 1)[-1].split(', at ')[0]
                    raise ConfigError(
                        f'{stream}_topic {sel.text}: {topic!r} is no valid topic name: {why}'
                    ) from None

    def _check_tf_selectors(self) -> None:
        """Say at start, not when data would arrive, that a tf selector cannot be read here:
        tf2_msgs comes with a ROS 2 install, not with the PyPI wheels."""
        for stream in STREAMS:
            sel = self.recorder.selectors[stream]
            declared = getattr(self.stream_cfg, f'{stream}_type')
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
            depth=self.node_cfg.qos_depth,
            history=HistoryPolicy.KEEP_LAST,
            reliability=(
                ReliabilityPolicy.BEST_EFFORT
                if self.node_cfg.qos_reliability == 'best_effort'
                else ReliabilityPolicy.RELIABLE
            ),
            durability=DurabilityPolicy.VOLATILE,
        )

    def _unknown(self) -> list[str]:
        """The auto-typed streams whose type the graph has not named yet."""
        return [s for s in STREAMS if s not in self._subs or s in self._guessed]

    def _subscribe(self, stream: str, msgtype: str, guess: bool = False) -> None:
        """Subscribe a stream's topic (and a tf selector's static topic, transient local, as
        tf2's static broadcasters latch) once its type is known, or with its likeliest type
        (``guess``) until the graph says; raises ConfigError when the type does not fit the
        selector or its Python package cannot be imported."""
        self.recorder.set_type(stream, msgtype)
        cls = message_class(msgtype)
        sel = self.recorder.selectors[stream]
        self._subs[stream] = self.create_subscription(
            cls,
            sel.topic,
            lambda msg, s=stream: self._on_pose(s, msg),
            self._pose_qos(),
            event_callbacks=SubscriptionEventCallbacks(
                incompatible_qos=lambda event, s=stream: self._on_incompatible_qos(s, event)
            ),
        )
        if sel.static_topic:
            static_qos = QoSProfile(
                depth=100,
                history=HistoryPolicy.KEEP_LAST,
                reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.TRANSIENT_LOCAL,
            )
            self._static_subs[stream] = self.create_subscription(
                cls,
                sel.static_topic,
                lambda msg, s=stream: self._on_pose(s, msg, True),
                static_qos,
            )
        if guess:
            self._guessed.add(stream)
            self.get_logger().info(
                f'{stream}: subscribed to {sel.text} as {msgtype}, its likeliest type, until '
                'its publisher says which it has'
            )
        else:
            self.get_logger().info(f'{stream}: subscribed to {sel.text} ({msgtype})')

    def _on_incompatible_qos(self, stream: str, event: Any) -> None:
        """A publisher whose QoS this subscription cannot match: nothing of it will arrive."""
        why = self._qos_mismatch(stream)
        if why is None:
            policy = QoSPolicyKind(event.last_policy_kind).name.lower()
            why = (
                f'{stream} topic {self.recorder.selectors[stream].topic}: a publisher offers '
                f'a QoS this subscription cannot match ({policy}); nothing it sends arrives'
            )
        self._qos_problems[stream] = why
        self.get_logger().warning(why)

    def _qos_mismatch(self, stream: str) -> str | None:
        """The reason no message of a stream's publishers can arrive, read from the QoS they
        offer in the graph; None when every one matches."""
        sub = self._subs.get(stream)
        if sub is None or sub.qos_profile.reliability != ReliabilityPolicy.RELIABLE:
            return None
        topic = self.recorder.selectors[stream].topic
        for info in self.get_publishers_info_by_topic(topic):
            if info.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT:
                return (
                    f'{stream} topic {topic}: its publisher {info.node_name} is best_effort '
                    'and this node asks reliable delivery (qos_reliability: reliable), so '
                    'nothing it sends arrives: set qos_reliability: best_effort'
                )
        return None

    def _discover_types(self) -> None:
        """Learn the message type of auto-typed topics from the graph."""
        now = time.monotonic()
        for stream in self._unknown():
            topic = self.recorder.selectors[stream].topic
            types = self._publisher_types(topic)
            usable = _pose_types(types)
            guess = self.recorder.types[stream] if stream in self._guessed else None
            if usable == [guess]:
                self._guessed.discard(stream)
                self.get_logger().info(
                    f'{stream}: {topic} is {guess}, as subscribed from the start'
                )
            elif len(usable) == 1:
                try:
                    if guess is not None:
                        # a wrong guess gives way: one participant holds one type of a topic
                        self.destroy_subscription(self._subs.pop(stream))
                        self._guessed.discard(stream)
                    self._subscribe(stream, usable[0])
                    self.get_logger().info(
                        f'{stream}: {topic} learnt from its publisher; messages it sent '
                        'before this subscription matched are not received (set '
                        f'{stream}_type: {usable[0].rsplit("/", 1)[-1]} to subscribe at start)'
                    )
                except ConfigError as err:
                    self._sub_errors[stream] = str(err)
                    if now - self._type_warned[stream] > self.node_cfg.topic_wait:
                        self._type_warned[stream] = now
                        self.get_logger().error(f'{stream}: {err}')
            elif now - self._type_warned[stream] > self.node_cfg.topic_wait:
                self._type_warned[stream] = now
                if types and not usable:
                    why = (
                        f'has type {", ".join(types)}, which carries no pose (supported: '
                        f'{", ".join(SUPPORTED_TYPES)})'
                    )
                elif usable:
                    why = f'has several pose types ({", ".join(usable)}): set {stream}_type'
                    if guess in usable:
                        why += f'; meanwhile the {guess} one is received'
                else:
                    why = 'has no publisher yet'
                self.get_logger().warning(f'{stream} topic {topic} {why}')
        if not self._unknown() and self._graph_timer is not None:
            self._graph_timer.cancel()

    def _publisher_types(self, topic: str) -> list[str]:
        """The types a topic's publishers send, in the order first seen (the graph's types
        of a topic also hold its subscriptions')."""
        types: list[str] = []
        for info in self.get_publishers_info_by_topic(topic):
            if info.topic_type not in types:
                types.append(info.topic_type)
        return types

    def _on_pose(self, stream: str, msg: Any, static: bool = False) -> None:
        arrival = self.get_clock().now().nanoseconds if stream in self.recorder.arrival else None
        self._add(stream, msg, static, arrival)

    def _add(self, stream: str, msg: Any, static: bool, arrival: int | None) -> None:
        reason = self.recorder.add(stream, msg, static, arrival)
        if reason is not None:
            now = time.monotonic()
            if now - self._reject_warned[stream] >= REJECT_WARN_PERIOD_S:
                self._reject_warned[stream] = now
                rejected = self.recorder.buffers[stream].rejected
                self.get_logger().warning(
                    f'{stream}: rejected a message ({reason.replace("_", " ")}); rejected so '
                    f'far: {", ".join(f"{k} {v}" for k, v in rejected.items() if v)}'
                )

    # ------------------------------------------------------------------ services

    def _why_no_data(self) -> str | None:
        unknown = self._unknown()
        for stream in STREAMS:
            empty = len(self.recorder.buffers[stream]) < 2
            if stream in self._subs and stream not in unknown and empty:
                # the graph now, or what the QoS event said of a publisher since gone
                why = self._qos_mismatch(stream) or self._qos_problems.get(stream)
                if why is not None:
                    return why
            if stream in self._sub_errors and stream not in self._subs:
                return f'{stream}: {self._sub_errors[stream]}'
            if stream in unknown and empty:
                topic = self.recorder.selectors[stream].topic
                types = self._publisher_types(topic)
                usable = _pose_types(types)
                if len(usable) > 1:
                    return (
                        f'{stream} topic {topic} has several pose types ({", ".join(usable)}): '
                        f'set {stream}_type'
                    )
                if types and not usable:
                    return (
                        f'{stream} topic {topic} has type {", ".join(types)}, which carries '
                        f'no pose this node reads (supported: {", ".join(SUPPORTED_TYPES)})'
                    )
                if not types:
                    return (
                        f'{stream} topic {topic} has no publisher yet: check {stream}_topic, '
                        f'or set {stream}_type to subscribe before one appears'
                    )
        return None

    def _start_worker(self) -> Future | None:
        """Calibrate a snapshot of the buffers in the worker process, unless one runs.

        Returns an rclpy Future that completes on the executor with (success, message), or
        None when a calibration is already running.
        """
        if not self._busy.acquire(blocking=False):
            return None
        future = Future(executor=self.executor)
        # a done callback makes the completion wake the executor (it schedules a task)
        future.add_done_callback(lambda _: None)
        why = self._why_no_data()
        stage = None
        try:
            if why is not None:
                raise InputError(why)
            snapshot = self.recorder.snapshot()
            t0 = time.perf_counter()
            stage = (
                tempfile.mkdtemp(prefix='handeye_report_') if self.node_cfg.report_dir else None
            )
            job = self._pool.submit(calibrate_snapshot, snapshot, self.calib_cfg, stage)
        except (HandeyeError, RuntimeError) as err:  # RuntimeError: pool shut down
            self._failed(str(err))
            future.set_result((False, str(err)))
            self._drop_stage(stage)
            self._busy.release()
            return future

        def done(job: cf.Future) -> None:  # in a pool thread
            kept = False
            try:
                session: SessionResult = job.result()
            except HandeyeError as err:
                self._failed(str(err))
                future.set_result((False, str(err)))
            except Exception as err:  # noqa: BLE001  (a crashed worker: reported, pool renewed)
                if self._closing:  # the node stopped it
                    future.set_result((False, 'the node is shutting down'))
                    return
                self.get_logger().error(f'calibration worker failed: {err!r}')
                if isinstance(err, cf.process.BrokenProcessPool):
                    self._pool = worker.new_pool(ignore_sigint=False)
                self._failed(f'internal error: {err!r}')
                future.set_result((False, f'internal error: {err!r}'))
            else:
                self._drop_stage(_staged_dir(self._last_result))
                kept = True
                self._succeeded(session)
                self.get_logger().info(
                    f'calibrated in {time.perf_counter() - t0:.2f} s: {session.summary}'
                )
                for w in session.result.warnings:
                    self.get_logger().warning(w)
                future.set_result((True, session.summary))
            finally:
                if not kept:  # a failed calibration leaves no report to keep
                    self._drop_stage(stage)
                self._busy.release()

        job.add_done_callback(done)
        return future

    async def _on_calibrate(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        future = self._start_worker()
        if future is None:
            response.success = False
            response.message = 'a calibration is already running; call again when it has finished'
            return response
        response.success, response.message = await future
        return response

    def _periodic_calibrate(self) -> None:
        if self._why_no_data() is None:
            self._start_worker()

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        self.recorder.reset()
        response.success = True
        response.message = 'buffers cleared' + (
            ' (the running calibration works on its own copy and will still answer)'
            if self._busy.locked()
            else ''
        )
        return response

    def _on_save(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        if self._last_result is None:
            response.success = False
            response.message = (
                'no result to save: call calibrate first'
                if self._last_error is None
                else f'no result to save: the calibration failed ({self._last_error})'
            )
            return response
        out, report = self.node_cfg.output_file, self.node_cfg.report_dir
        wrote = [out]
        try:
            Path(out).parent.mkdir(parents=True, exist_ok=True)  # a run-time path: make it
            write_result(out, self._last_result.to_dict())
            staged = _staged_dir(self._last_result)
            if report and staged:
                shutil.copytree(staged, report, dirs_exist_ok=True)
                wrote.append(str(Path(report) / 'report.html'))
            elif report:
                wrote.append(
                    'no report (report_dir was set after this calibration: calibrate again)'
                )
        except HandeyeError as err:
            response.success, response.message = False, str(err)
            return response
        except OSError as err:
            response.success = False
            where = err.filename or report
            response.message = f'{where}: cannot write ({err.strerror or err})'
            return response
        response.success, response.message = True, 'wrote ' + ', '.join(wrote)
        if self._last_error is not None:
            response.message += (
                f' (the latest calibration failed: this is the result of {self._last_when})'
            )
        return response

    @staticmethod
    def _drop_stage(stage: str | None) -> None:
        """Remove a staging folder of the worker's report (replaced, or never used)."""
        if stage:
            shutil.rmtree(stage, ignore_errors=True)

    def close(self) -> None:
        """Stop the worker process and wait for it (a running calibration is abandoned), so
        that no process outlives the node."""
        self._closing = True
        if self._pool is not None:
            worker.stop(self._pool)
            # dropped, so that its queues' semaphores are released before the resource
            # tracker stops (worker.stop_tracker); else they are unlinked twice at exit
            self._pool = None
        self._drop_stage(_staged_dir(self._last_result))

    # ------------------------------------------------------------------ outputs

    def _succeeded(self, session: SessionResult) -> None:
        """A new result: every output at once, one stamp (in a pool thread; rclpy's publish
        is thread-safe)."""
        self._last_result, self._last_error = session, None
        self._last_when = time.strftime('%Y-%m-%d %H:%M:%S')
        stamp = self.get_clock().now().nanoseconds
        published = messages.Published.from_result(session.result, session.frames)
        out = messages.outputs(self._types, published, stamp)
        for name, pub in self._outputs.items():
            if name in out:
                pub.publish(out[name])
        if messages.TIME_REFERENCE not in out:
            self.get_logger().warning(
                'the time offset is not published as a TimeReference: its instant on one of '
                'the clocks is no ROS time (before 1970); ~/time_offset has it'
            )
        if self._static_tf is not None:
            self._static_tf.publish(self._types[TF_TYPE](transforms=[out[messages.EXTRINSIC]]))
        self._publish_diagnostics()

    def _failed(self, why: str) -> None:
        """A failed calibration: the diagnostics say so at once; the latched outputs, which
        cannot be withdrawn, are named stale there."""
        self._last_error = why
        self._publish_diagnostics()

    def _static_broadcaster(self) -> Any:
        """A latched /tf_static publisher, as tf2's static broadcaster keeps one, where
        tf2_msgs is importable (a ROS 2 install; the PyPI wheels have neither tf2_msgs nor
        tf2_ros); None otherwise, said once."""
        try:
            cls = self._types[TF_TYPE]
        except ConfigError:
            self.get_logger().info(
                'tf2_msgs is not importable here: the extrinsic is published '
                'on ~/extrinsic, not on /tf_static (publish_calibration FILE '
                'writes it into a bag)'
            )
            return None
        return self.create_publisher(cls, '/tf_static', LATCHED)

    def _publish_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        name = self.get_fully_qualified_name()
        for stream, s in self.recorder.stats().items():
            topic = getattr(self.stream_cfg, f'{stream}_topic')
            msgtype = self.recorder.types[stream]
            if stream in self._guessed:
                msgtype += ' (likeliest; not yet seen on the graph)'
            arr.status.append(diagnostics.stream_status(name, stream, s, topic, msgtype))
        arr.status.append(
            diagnostics.result_status(name, self._last_result, self._last_when, self._last_error)
        )
        self.pub_diag.publish(arr)


def _pose_types(types: list[str]) -> list[str]:
    """Those of a topic's types this node reads poses from, normalised."""
    usable = []
    for t in types:
        try:
            usable.append(normalise_type(t))
        except UnsupportedTypeError:
            pass
    return usable


def _staged_dir(session: SessionResult | None) -> str | None:
    """The folder where the worker drew a result's report, if it did."""
    return str(Path(session.report).parent) if session is not None and session.report else None


def run(args: list[str] | None = None) -> int:
    """Run the node until a signal or an external shutdown; returns the exit code (0, or 1
    when the options are refused). The entry point, which installs the quiet signal handlers
    of :mod:`.lifecycle` first, is :func:`handeye_ros.ros.calibrator.main`."""
    pool = worker.new_pool()  # before rclpy.init: see worker's docstring
    rclpy.init(args=args)
    failure = None
    node = None
    try:
        if not stop_requested():
            node = CalibratorNode(pool)
    except ConfigError as err:
        failure = str(err)
    except Exception:
        if rclpy.ok() and not stop_requested():
            worker.stop(pool)
            rclpy.try_shutdown()
            raise
        # a signal during the start shut the context down under the constructor
    if node is None:
        worker.stop(pool)
    # the node owns the pool now; no other reference may keep its semaphores alive until
    # the resource tracker stops (worker.stop_tracker)
    del pool
    if node is None:
        worker.stop_tracker()
        rclpy.try_shutdown()
        if failure is not None:
            print(f'calibrator: error: {failure}', file=sys.stderr)
            return 1
        return 0
    try:
        spin(node, node.close)
    finally:
        worker.stop_tracker()
    return 0


if __name__ == '__main__':
    from .calibrator import main

    sys.exit(main())
