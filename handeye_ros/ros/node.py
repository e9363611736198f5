"""The ``calibrator`` node: buffer a MoCap and a VO/VIO pose stream, calibrate on request.

``ros2 run handeye_ros calibrator [--ros-args --params-file config/calibrator.yaml]``

Subscriptions feed a :class:`~handeye_ros.stream.Recorder` (the same conversion and buffers the
offline bag replay uses). Services (std_srvs/Trigger): ``~/calibrate`` runs the core on a copy
of the buffers in a worker thread while the subscriptions keep flowing (a second call while
one runs is refused), ``~/reset`` empties the buffers, ``~/save`` writes the last result.

Concurrency: one single-threaded executor runs every callback (rclpy's multi-threaded executor
costs so much per callback that a 1 kHz stream overruns it). ``~/calibrate`` is a coroutine:
it snapshots the buffers, hands the snapshot to a worker *process* and awaits the result, so
the executor keeps taking messages meanwhile. A process rather than a thread: at 1 kHz the
executor holds the GIL most of the time, and a calibration thread beside it ran ten times
slower. The worker is forked from a forkserver that has the core imported, so a call pays
no start-up.
Results go out on latched topics ``~/extrinsic`` (TransformStamped, hand frame -> eye frame)
and ``~/time_offset`` (Float64, s, eye clock minus hand clock), and as a static transform when
tf2_ros is importable. Status goes to /diagnostics.
"""

from __future__ import annotations

import concurrent.futures as cf
import importlib
import multiprocessing
import shutil
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import (
    InvalidParameterTypeException,
    InvalidParameterValueException,
    ParameterException,
)
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from ..core.config import CalibrationConfig
from ..core.errors import ConfigError, HandeyeError, InputError
from ..core.options import Spec, split_options
from ..evaluation.outputs import calibrate_snapshot
from ..report import write_result
from ..stream import STREAMS, SUPPORTED_TYPES, Recorder, StreamConfig, normalise_type
from ..stream.convert import TF_TYPE, UnsupportedTypeError
from .config import NodeConfig, all_specs

#: Latched result topics: late subscribers get the last result.
LATCHED = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Node parameters that may change while the node runs (the algorithm options); the others
#: shape subscriptions and buffers and are read once.
DYNAMIC = frozenset(CalibrationConfig.specs())
#: Seconds between two warnings about rejected messages of one stream.
REJECT_WARN_PERIOD_S = 5.0


def descriptor(name: str, spec: Spec) -> ParameterDescriptor:
    """A ParameterDescriptor with the option's description and range."""
    rng = spec.range_text()
    d = ParameterDescriptor(name=name, description=spec.description + (
        f' ({rng})' if rng and not spec.choices else ''),
        read_only=name not in DYNAMIC)
    if spec.choices:
        d.additional_constraints = 'one of: ' + ', '.join(spec.choices)
    if spec.low is not None and spec.high is not None and not spec.optional:
        if spec.kind == 'float':
            d.floating_point_range = [FloatingPointRange(
                from_value=float(spec.low), to_value=float(spec.high), step=0.0)]
        elif spec.kind == 'int':
            d.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high),
                                            step=1)]
    return d


def _default(value: Any) -> Any:
    # ROS parameters have no null: an optional float is NaN when 'automatic'
    return float('nan') if value is None else value


class CalibratorNode(Node):
    """See the module docstring."""

    def __init__(self, **kwargs: Any):
        super().__init__('calibrator', **kwargs)
        self.calib_cfg, self.stream_cfg, self.node_cfg = self._declare_and_read()
        self.recorder = Recorder(self.stream_cfg)
        self._check_tf_selectors()
        self._busy = threading.Lock()
        self._last_result: dict[str, Any] | None = None
        self._last_summary = 'no calibration yet'
        self._last_ok: bool | None = None
        self._reject_warned = dict.fromkeys(STREAMS, 0.0)
        self._subs: dict[str, Any] = {}
        self._static_subs: dict[str, Any] = {}
        self._sub_errors: dict[str, str] = {}
        self._started = time.monotonic()
        self._type_warned = dict.fromkeys(STREAMS, self._started)

        self.pub_extrinsic = self.create_publisher(TransformStamped, '~/extrinsic', LATCHED)
        self.pub_offset = self.create_publisher(Float64, '~/time_offset', LATCHED)
        self.pub_cov = self.create_publisher(PoseWithCovarianceStamped,
                                             '~/extrinsic_with_covariance', LATCHED)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        # its own reentrant group: a callback group stays busy while a coroutine in it awaits,
        # and the default (mutually exclusive) group would then hold back every subscription
        self.create_service(Trigger, '~/calibrate', self._on_calibrate,
                            callback_group=ReentrantCallbackGroup())
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.create_service(Trigger, '~/save', self._on_save)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._static_tf = self._static_broadcaster()
        self._pool = self._new_pool()

        for stream in STREAMS:
            declared = getattr(self.stream_cfg, f'{stream}_type')
            if declared != 'auto':
                self._subscribe(stream, normalise_type(declared))
        self._graph_timer = None
        if len(self._subs) < len(STREAMS):
            self._graph_timer = self.create_timer(0.2, self._discover_types)
        self.create_timer(self.node_cfg.diagnostics_period, self._publish_diagnostics)
        if self.node_cfg.calibrate_period > 0.0:
            self.create_timer(self.node_cfg.calibrate_period, self._periodic_calibrate)
        self.get_logger().info(
            f'buffering hand {self.stream_cfg.hand_topic} and eye {self.stream_cfg.eye_topic}; '
            f'call {self.get_fully_qualified_name()}/calibrate when the rig has moved')

    # ------------------------------------------------------------------ parameters

    def _declare_and_read(self) -> tuple[CalibrationConfig, StreamConfig, NodeConfig]:
        values: dict[str, Any] = {}
        defaults = {**CalibrationConfig().to_dict(), **StreamConfig().to_dict(),
                    **NodeConfig().to_dict()}
        for name, spec in all_specs().items():
            try:
                p = self.declare_parameter(name, _default(defaults[name]),
                                           descriptor(name, spec))
            except (InvalidParameterValueException, InvalidParameterTypeException,
                    ParameterException) as err:
                raise ConfigError(f'parameter {name}: {err}') from None
            values[name] = p.value
        return split_options(values, (CalibrationConfig, StreamConfig, NodeConfig),
                             source='parameters')

    def _on_set_parameters(self, params: list[Any]) -> SetParametersResult:
        changes = {p.name: p.value for p in params if p.name in DYNAMIC}
        if not changes:
            return SetParametersResult(successful=True)
        try:
            merged = {**self.calib_cfg.to_dict(), **changes}
            self.calib_cfg = CalibrationConfig.from_mapping(merged, source='parameters')
        except ConfigError as err:
            return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ subscriptions

    def _check_tf_selectors(self) -> None:
        """Say at start, not when data would arrive, that a tf selector cannot be read here:
        tf2_msgs comes with a ROS 2 install, not with the PyPI wheels."""
        for stream in STREAMS:
            sel = self.recorder.selectors[stream]
            declared = getattr(self.stream_cfg, f'{stream}_type')
            is_tf = (normalise_type(declared) == TF_TYPE if declared != 'auto' else
                     sel.item is not None and sel.topic.rstrip('/').rsplit('/', 1)[-1] == 'tf')
            if not is_tf:
                continue
            sel.frames()  # a malformed pair is a ConfigError now
            try:
                _message_class(TF_TYPE)
            except ConfigError as err:
                raise ConfigError(f'{stream}_topic {sel.text}: {err}. Bags with /tf need no '
                                  'ROS install: offline_calibrate --bag reads them') from None

    def _subscribe(self, stream: str, msgtype: str) -> None:
        """Subscribe a stream's topic (and a tf selector's static topic, transient local, as
        tf2's static broadcasters latch) once its type is known; raises ConfigError when
        the type does not fit the selector or its Python package cannot be imported."""
        self.recorder.set_type(stream, msgtype)
        cls = _message_class(msgtype)
        qos = QoSProfile(
            depth=self.node_cfg.qos_depth, history=HistoryPolicy.KEEP_LAST,
            reliability=(ReliabilityPolicy.BEST_EFFORT
                         if self.node_cfg.qos_reliability == 'best_effort'
                         else ReliabilityPolicy.RELIABLE),
            durability=DurabilityPolicy.VOLATILE)
        sel = self.recorder.selectors[stream]
        self._subs[stream] = self.create_subscription(
            cls, sel.topic, lambda msg, s=stream: self._on_pose(s, msg), qos)
        if sel.static_topic:
            static_qos = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                                    reliability=ReliabilityPolicy.RELIABLE,
                                    durability=DurabilityPolicy.TRANSIENT_LOCAL)
            self._static_subs[stream] = self.create_subscription(
                cls, sel.static_topic, lambda msg, s=stream: self._on_pose(s, msg, True),
                static_qos)
        self.get_logger().info(f'{stream}: subscribed to {sel.text} ({msgtype})')

    def _discover_types(self) -> None:
        """Learn the message type of auto-typed topics from the graph."""
        graph = dict(self.get_topic_names_and_types())
        now = time.monotonic()
        for stream in STREAMS:
            if stream in self._subs:
                continue
            topic = self.recorder.selectors[stream].topic
            types = graph.get(topic, [])
            usable = []
            for t in types:
                try:
                    usable.append(normalise_type(t))
                except UnsupportedTypeError:
                    pass
            if len(usable) == 1:
                try:
                    self._subscribe(stream, usable[0])
                except ConfigError as err:
                    self._sub_errors[stream] = str(err)
                    if now - self._type_warned[stream] > self.node_cfg.topic_wait:
                        self._type_warned[stream] = now
                        self.get_logger().error(f'{stream}: {err}')
            elif now - self._type_warned[stream] > self.node_cfg.topic_wait:
                self._type_warned[stream] = now
                if types and not usable:
                    why = (f'has type {", ".join(types)}, which carries no pose (supported: '
                           f'{", ".join(SUPPORTED_TYPES)})')
                elif usable:
                    why = f'has several pose types ({", ".join(usable)}): set {stream}_type'
                else:
                    why = 'has no publisher yet'
                self.get_logger().warning(f'{stream} topic {topic} {why}')
        if len(self._subs) == len(STREAMS) and self._graph_timer is not None:
            self._graph_timer.cancel()

    def _on_pose(self, stream: str, msg: Any, static: bool = False) -> None:
        reason = self.recorder.add(stream, msg, static)
        if reason is not None:
            now = time.monotonic()
            if now - self._reject_warned[stream] >= REJECT_WARN_PERIOD_S:
                self._reject_warned[stream] = now
                rejected = self.recorder.buffers[stream].rejected
                self.get_logger().warning(
                    f'{stream}: rejected a message ({reason.replace("_", " ")}); rejected so '
                    f'far: {", ".join(f"{k} {v}" for k, v in rejected.items() if v)}')

    # ------------------------------------------------------------------ services

    def _why_no_data(self) -> str | None:
        for stream in STREAMS:
            if stream in self._sub_errors and stream not in self._subs:
                return f'{stream}: {self._sub_errors[stream]}'
            if stream not in self._subs:
                topic = self.recorder.selectors[stream].topic
                types = dict(self.get_topic_names_and_types()).get(topic)
                if types:
                    return (f'{stream} topic {topic} has type {", ".join(types)}, which carries '
                            f'no pose this node reads (supported: {", ".join(SUPPORTED_TYPES)})')
                return (f'{stream} topic {topic} has no publisher yet: check {stream}_topic, or '
                        f'set {stream}_type to subscribe before one appears')
        return None

    def _new_pool(self) -> cf.ProcessPoolExecutor:
        ctx = multiprocessing.get_context('forkserver')
        ctx.set_forkserver_preload(['handeye_ros.core.pipeline', 'handeye_ros.stream.recorder',
                                   'handeye_ros.evaluation.outputs'])
        pool = cf.ProcessPoolExecutor(max_workers=1, mp_context=ctx)
        pool.submit(int)  # start the forkserver and the worker now, not on the first call
        return pool

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
            stage = (tempfile.mkdtemp(prefix='handeye_report_') if self.node_cfg.report_dir
                     else None)
            job = self._pool.submit(calibrate_snapshot, snapshot, self.calib_cfg, stage)
        except (HandeyeError, RuntimeError) as err:  # RuntimeError: pool shut down
            self._last_ok, self._last_summary = False, str(err)
            future.set_result((False, str(err)))
            self._drop_stage(stage)
            self._busy.release()
            return future

        def done(job: cf.Future) -> None:  # in a pool thread
            kept = False
            try:
                d = job.result()
            except HandeyeError as err:
                self._last_ok, self._last_summary = False, str(err)
                future.set_result((False, str(err)))
            except Exception as err:  # noqa: BLE001  (a crashed worker: reported, pool renewed)
                self.get_logger().error(f'calibration worker failed: {err!r}')
                if isinstance(err, cf.process.BrokenProcessPool):
                    self._pool = self._new_pool()
                self._last_ok, self._last_summary = False, f'internal error: {err!r}'
                future.set_result((False, f'internal error: {err!r}'))
            else:
                self._drop_stage(_staged_dir(self._last_result))
                kept = True
                self._last_result, self._last_ok, self._last_summary = d, True, d['summary']
                self._publish(d)
                self.get_logger().info(f'calibrated in {time.perf_counter() - t0:.2f} s: '
                                       f'{d["summary"]}')
                for w in d['warnings']:
                    self.get_logger().warning(w)
                future.set_result((True, d['summary']))
            finally:
                if not kept:  # a failed calibration leaves no report to keep
                    self._drop_stage(stage)
                self._busy.release()

        job.add_done_callback(done)
        return future

    async def _on_calibrate(self, request: Trigger.Request,
                            response: Trigger.Response) -> Any:
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
        response.message = ('buffers cleared' + (' (the running calibration works on its own '
                                                 'copy and will still answer)'
                                                 if self._busy.locked() else ''))
        return response

    def _on_save(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        if self._last_result is None:
            response.success, response.message = False, 'no result to save: call calibrate first'
            return response
        wrote = [self.node_cfg.output_file]
        try:
            write_result(self.node_cfg.output_file, self._last_result)
            staged = _staged_dir(self._last_result)
            if self.node_cfg.report_dir and staged:
                shutil.copytree(staged, self.node_cfg.report_dir, dirs_exist_ok=True)
                wrote.append(str(Path(self.node_cfg.report_dir) / 'report.html'))
            elif self.node_cfg.report_dir:
                wrote.append('no report (report_dir was set after this calibration: calibrate '
                             'again)')
        except HandeyeError as err:
            response.success, response.message = False, str(err)
            return response
        except OSError as err:
            response.success = False
            response.message = (f'report_dir {self.node_cfg.report_dir}: cannot write '
                                f'({err.strerror or err})')
            return response
        response.success, response.message = True, 'wrote ' + ', '.join(wrote)
        return response

    @staticmethod
    def _drop_stage(stage: str | None) -> None:
        """Remove a staging folder of the worker's report (replaced, or never used)."""
        if stage:
            shutil.rmtree(stage, ignore_errors=True)

    def close(self) -> None:
        """Stop the worker process (a running calibration is abandoned)."""
        self._pool.shutdown(wait=False, cancel_futures=True)
        self._drop_stage(_staged_dir(self._last_result))

    # ------------------------------------------------------------------ outputs

    def _publish(self, d: dict[str, Any]) -> None:
        e = d['extrinsic']
        tf = TransformStamped()
        tf.header.stamp = self.get_clock().now().to_msg()
        tf.header.frame_id = e['parent']
        tf.child_frame_id = e['child']
        (tf.transform.translation.x, tf.transform.translation.y,
         tf.transform.translation.z) = e['translation']
        (tf.transform.rotation.x, tf.transform.rotation.y, tf.transform.rotation.z,
         tf.transform.rotation.w) = e['rotation']
        self.pub_extrinsic.publish(tf)
        self.pub_offset.publish(Float64(data=float(d['time_offset'])))
        if d.get('covariance'):
            self.pub_cov.publish(pose_with_covariance(tf, d))
        if self._static_tf is not None:
            self._static_tf.sendTransform(tf)

    def _static_broadcaster(self) -> Any:
        try:
            from tf2_ros import StaticTransformBroadcaster
        except ImportError:
            self.get_logger().info('tf2_ros is not importable here: the extrinsic is published '
                                   'on ~/extrinsic only, not as a static transform')
            return None
        return StaticTransformBroadcaster(self)

    def _publish_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        name = self.get_fully_qualified_name()
        for stream, s in self.recorder.stats().items():
            st = DiagnosticStatus(name=f'{name}: {stream} stream', hardware_id=name)
            rejected = sum(s.rejected.values())
            if s.stored < 2:
                st.level, st.message = DiagnosticStatus.WARN, 'no data'
            elif rejected:
                st.level, st.message = DiagnosticStatus.WARN, f'{rejected} messages rejected'
            else:
                st.level, st.message = DiagnosticStatus.OK, f'{s.rate_hz:.1f} Hz'
            st.values = [KeyValue(key=k, value=str(v)) for k, v in (
                ('topic', getattr(self.stream_cfg, f'{stream}_topic')),
                ('type', self.recorder.types[stream]),
                ('rate_hz', f'{s.rate_hz:.2f}'), ('buffered_span_s', f'{s.span_s:.2f}'),
                ('received', s.received), ('buffered', s.stored), ('dropped', s.dropped),
                *((f'rejected_{k}', v) for k, v in s.rejected.items()))]
            arr.status.append(st)
        res = DiagnosticStatus(name=f'{name}: result', hardware_id=name,
                               message=self._last_summary[:500])
        if self._last_ok is None:
            res.level = DiagnosticStatus.OK
        elif not self._last_ok:
            res.level = DiagnosticStatus.ERROR
        else:
            # the verdict: good OK, doubtful WARN, failed ERROR
            verdict = self._last_result['quality']['verdict'] if self._last_result else 'good'
            res.level = {'good': DiagnosticStatus.OK, 'doubtful': DiagnosticStatus.WARN,
                         'failed': DiagnosticStatus.ERROR}[verdict]
        if self._last_result is not None:
            d = self._last_result
            q = d['quality']
            res.values = [KeyValue(key=k, value=str(v)) for k, v in (
                ('verdict', q['verdict']),
                ('reasons', '; '.join(f'{r["code"]}: {r["message"]}' for r in q['reasons'])),
                ('time_offset_s', d['time_offset']),
                ('translation_m', d['extrinsic']['translation']),
                ('rotation_xyzw', d['extrinsic']['rotation']),
                ('inliers', f'{d["linear"]["inliers"]}/{d["linear"]["motions"]}'),
                ('peak_correlation', d['time_alignment']['peak_correlation']),
                ('ape_rmse_m', d['metrics']['ape_rmse']),
                ('warnings', len(d['warnings'])))]
        arr.status.append(res)
        self.pub_diag.publish(arr)


def _message_class(msgtype: str) -> Any:
    """The rclpy class of 'pkg/msg/Name'; ConfigError naming the package when this Python
    cannot import it (tf2_msgs and mocap4r2_msgs come with a ROS 2 install, not from PyPI)."""
    pkg, _, name = msgtype.split('/')
    try:
        return getattr(importlib.import_module(f'{pkg}.msg'), name)
    except (ImportError, AttributeError):
        raise ConfigError(f'{msgtype} cannot be imported in this Python ({sys.executable}): '
                          f'install {pkg} (e.g. apt install ros-jazzy-{pkg.replace("_", "-")} '
                          'and source /opt/ros/jazzy/setup.bash)') from None


def _staged_dir(result: dict[str, Any] | None) -> str | None:
    """The folder where the worker drew a result's report, if it did."""
    staged = ((result or {}).get('files') or {}).get('report')
    return str(Path(staged).parent) if staged else None


def pose_with_covariance(tf: TransformStamped, d: dict[str, Any]) -> PoseWithCovarianceStamped:
    """T_HE with its 6x6 covariance in ROS order (x, y, z, rotation about the parent's X, Y, Z).

    The result's rotation covariance is in the tangent on the right of T_HE (eye frame);
    ROS wants fixed (parent-frame) axes: dtheta_H = R_HE dtheta_E.
    """
    import numpy as np
    msg = PoseWithCovarianceStamped()
    msg.header = tf.header
    t, r = tf.transform.translation, tf.transform.rotation
    msg.pose.pose.position.x, msg.pose.pose.position.y, msg.pose.pose.position.z = t.x, t.y, t.z
    msg.pose.pose.orientation = r
    cov = np.asarray(d['covariance']['matrix'])[1:, 1:]
    R = np.asarray(d['extrinsic']['matrix'])[:3, :3]
    J = np.eye(6)
    J[3:, 3:] = R
    msg.pose.covariance = [float(v) for v in (J @ cov @ J.T).ravel()]
    return msg


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run handeye_ros calibrator``; returns the exit code."""
    rclpy.init(args=args)
    try:
        node = CalibratorNode()
    except ConfigError as err:
        print(f'calibrator: error: {err}', file=sys.stderr)
        rclpy.try_shutdown()
        return 1
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        # a second Ctrl-C (or a signal forwarded twice) must not break the clean-up
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        node.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
