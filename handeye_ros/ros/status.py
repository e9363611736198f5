"""The calibrator's readiness status while recording (its auto mode is :mod:`.auto_mode`).

READY is the verdict of a real calibration (:mod:`handeye_ros.core.checks.readiness`): the status
calibrates the buffers in the node's worker as they grow (first once they span MIN_RECORDING_S,
then each time they have grown by LAST_GAIN_S), never sooner after one calibration than it took (so
they take at most half a core and never fall behind the streams, and READY follows the data within
about one calibration's time), and READY means the latest such result is ``good`` for the chosen
purpose and settled (not near the line of its precision, with 1-sigmas that hold the errors
correlated over the recording, unless the recording has ended and it holds the whole). Between
results it shows how far the device has turned and how far apart its turns' axes are
(:class:`~handeye_ros.core.checks.excitation.Motion`, grown on the executor from the poses new
since its last look: a look costs the same at 10 s and at 30 min of buffers), the latest
result's verdict, 1-sigmas and age, and what to do. The answer is published on ``~/status``
(diagnostic_msgs/DiagnosticStatus), goes into /diagnostics, and is logged as one line when it
changes (and every LOG_PERIOD_S): never redrawn in place, which would glue log lines onto it in a
terminal and its redraws into one line under ``ros2 launch``.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticStatus

from ..core.arrays import Stamps
from ..core.checks.excitation import Motion
from ..core.checks.readiness import MIN_RECORDING_S, STILL_DPS, Outcome, readiness
from ..core.document import StatusDoc
from ..core.errors import HandeyeError
from ..core.result import CalibrationResult
from ..evaluation.terminal import status_line
from ..stream import STREAMS
from . import diagnostics
from .auto_mode import Auto, State, decide, filled, said
from .clocks import Arrivals, ClockWatch, jump_advice
from .host import Job, StatusHost

#: The buffers are calibrated again once they span this much more than the last calibration
#: did (s): not again for the jitter of a full buffer's span.
LAST_GAIN_S = 1.0
#: The status's look at the new poses takes at most this share of one core on average: one that
#: cost c seconds of the executor's CPU is followed by none for c / MAX_DUTY.
MAX_DUTY = 0.03
#: A stream with no usable pose for this long (s) has stopped, or lost its poses (messages
#: still coming).
STOPPED_S = diagnostics.STOPPED_S
#: Snapshots count while both streams flow (a pose within this many periods, STOPPED_S at
#: least): after one ends, the other's stamps run at the pace of a replay, which is no clock's.
FLOWING_PERIODS = 10
#: The node taking a stream's poses this much after DDS received them (s) is said.
LATE_S = 1.0
#: The status line is logged when it changes, and at least this often (s).
LOG_PERIOD_S = 10.0


class ReadinessStatus:
    """The status of ``node`` (a :class:`~handeye_ros.ros.node.CalibratorNode`)."""

    def __init__(
        self, node: StatusHost, auto: bool, publish: Callable[[DiagnosticStatus], None]
    ) -> None:
        """``publish``: what ``~/status`` sends with; the node ticks :meth:`tick` each
        ``status_period`` and hands every calibration's answer to :meth:`took`."""
        self._node = node
        self._send = publish
        self._on = auto
        #: the last status, or None with why_not
        self.last: StatusDoc | None = None
        self.why_not = 'waiting for data'
        self.auto = Auto.start(auto)
        self._motion = Motion()
        #: the latest calibration of these buffers, whether the status runs one now, and
        #: whether that one's snapshot holds full buffers (auto mode's ``done`` speaks of them)
        self.latest: Outcome | None = None
        self._checking = False
        self._check_full = False
        #: when the next calibration and the next look at the new poses may start (monotonic s)
        self._next_check = 0.0
        self._next_look = 0.0
        self._logged = (0.0, '')
        #: the streams' clocks against their arrivals, snapshot by snapshot
        self._watch = ClockWatch()
        self._jumped: list[str] = []
        #: the node's simulated clock when it last moved (ns) and when that was (monotonic s)
        self._sim_clock = (0, time.monotonic())

    def tick(self) -> None:
        """On the executor: look at the poses new since the last tick, maybe calibrate the
        buffers, and publish what the status says."""
        node = self._node
        if node.closing:
            return
        empty = [s for s in STREAMS if len(node.recorder.buffers[s]) < 3]
        if empty:
            self.last = None
            self.why_not = node.poses.why_no_data() or (
                f'waiting for data on the {" and ".join(empty)} stream'
            )
            standing = self.clock_standing()
            if standing:
                self.why_not += f'; {standing[0]}'
            self._publish()
            return
        now = time.monotonic()
        if now >= self._next_look:
            t0 = time.thread_time()
            self._look()
            self._next_look = now + (time.thread_time() - t0) / MAX_DUTY
        self._maybe_check(now)
        self._report()

    def _span(self) -> float:
        return min(self._node.recorder.buffers[s].span_s for s in STREAMS)

    def _full(self) -> bool:
        """Whether a buffer drops poses: its span grows no more."""
        return any(self._node.recorder.buffers[s].dropped for s in STREAMS)

    def _look(self) -> None:
        """The motion of the poses new since the last look (and the streams' clocks)."""
        buffers = self._node.recorder.buffers
        newest, oldest = (
            {s: getattr(buffers[s], k) for s in STREAMS} for k in ('newest_ns', 'oldest_ns')
        )
        if None in newest.values() or None in oldest.values():
            return
        try:
            tails = self._node.recorder.tails(self._motion.wants(newest))
        except HandeyeError:  # emptied meanwhile: the next tick says so
            return
        self._clocks(tails['hand'].t_ns, tails['eye'].t_ns)
        self._motion = self._motion.grown(tails).since(oldest)

    def _maybe_check(self, now: float) -> None:
        """Calibrate the buffers (:data:`LAST_GAIN_S`, the module docstring) unless one runs."""
        span, latest = self._span(), self.latest
        eye = self._motion.turned('eye')
        if (
            self._node.busy
            or now < self._next_check
            or span < MIN_RECORDING_S
            or eye is None
            or eye.rms_dps < STILL_DPS
        ):
            return
        last = 0.0 if latest is None else latest.span_s
        full = self._full()
        if span < last + LAST_GAIN_S:
            if latest is not None and full:
                self.auto = filled(self.auto)
            return
        # set first: a calibration that fails at once reports (took) before calibrate returns
        self._checking, self._check_full = True, full
        if self._node.calibrate(Job.CHECK) is None:
            self._checking = False

    def took(
        self,
        result: CalibrationResult | None,
        error: Exception | None,
        job: Job,
        span_s: float,
        took_s: float,
    ) -> bool:
        """On the executor, a calibration of the buffers that spanned ``span_s`` [s] ended
        after ``took_s`` [s] with ``result`` (None: it failed, raising ``error``): whether it
        is published (a call's always; a check's when auto mode says so)."""
        now = time.monotonic()
        self._next_check = now + took_s
        latest = (
            Outcome.failure(error or RuntimeError('no result'), span_s, now)
            if result is None
            else Outcome.of(
                result.quality, result.batch, span_s, now, self._node.calib_cfg.precision
            )
        )
        self.latest = latest
        publish = job is Job.CALL
        if job is Job.CHECK:
            self._checking = False
            # full when the snapshot was taken: buffers that filled while it ran hold more
            self.auto = decide(self.auto, latest, self._check_full)
            publish = self.auto.publish
        self._report()
        return publish

    def _report(self) -> None:
        """What the status says now, published."""
        buffers = self._node.recorder.buffers
        if any(len(buffers[s]) < 3 for s in STREAMS):
            return
        span, latest = self._span(), self.latest
        r = readiness(
            self._motion,
            latest,
            self._node.calib_cfg,
            span,
            time.monotonic(),
            checking=self._checking,
            final=bool(self.ended()) and latest is not None and latest.span_s > span - LAST_GAIN_S,
        )
        self.last, self.why_not = r.to_dict(), ''
        self._publish()

    def stopped(self) -> list[str]:
        """A stream that stopped while the other one still flows, said as advice: its
        messages stopped, or they keep coming without a usable pose (a MoCap that lost the
        marker and publishes NaN, or no longer names the body)."""
        seen, ticked = self._node.last_seen, self._node.last_ticked
        now = time.monotonic()
        if not all(ticked.values()):
            return []
        quiet = {s: now - t for s, t in ticked.items() if now - t > STOPPED_S}
        if len(quiet) != 1:  # both quiet: the recording has ended or paused (ended says so)
            return []
        ((s, ago),) = quiet.items()
        if now - seen[s] > STOPPED_S:
            return [
                {
                    'hand': f'the MoCap has sent nothing for {ago:.0f} s: is the device inside '
                    'its tracked volume? (else check the MoCap driver)',
                    'eye': f'the device has sent nothing for {ago:.0f} s: check its VO/VIO',
                }[s]
            ]
        return [
            {
                'hand': f'the MoCap lost the marker {ago:.0f} s ago: its messages hold no '
                'usable pose (see the log); bring the device back into its view',
                'eye': f"the device's messages have held no usable pose for {ago:.0f} s "
                '(see the log): has its tracking failed?',
            }[s]
        ]

    def ended(self) -> list[str]:
        """Both streams stopped, said as advice (what the buffers hold is still sound: a
        recording that ended can be calibrated)."""
        ticked = self._node.last_ticked
        now = time.monotonic()
        if not all(ticked.values()) or any(now - t <= STOPPED_S for t in ticked.values()):
            return []
        ago = now - max(ticked.values())
        said = (
            f'neither stream has sent a pose for {ago:.0f} s: the recording has ended or '
            'paused (the buffers are kept; call ~/reset to start a new one)'
        )
        return [said]

    def clock_standing(self) -> list[str]:
        """With ``use_sim_time``: /clock standing still (not started, paused or ended), said
        as advice. The node's timers run on the steady clock, so the status goes on."""
        clock = self._node.get_clock()
        if not getattr(clock, 'ros_time_is_active', False):
            return []
        now_ns, now = clock.now().nanoseconds, time.monotonic()
        if now_ns != self._sim_clock[0]:
            self._sim_clock = (now_ns, now)
            if now_ns:
                return []
        still = now - self._sim_clock[1]
        if now_ns and still <= STOPPED_S:
            return []
        said = (
            'waiting for /clock: use_sim_time is true and no /clock message has come yet '
            '(start ros2 bag play --clock)'
            if not now_ns
            else f'waiting for /clock: use_sim_time is true and /clock has stood still for '
            f'{still:.0f} s (the bag paused or ended?)'
        )
        return [said]

    def _clocks(self, hand_ns: Stamps, eye_ns: Stamps) -> None:
        """Whether the streams' clocks moved against each other, from the snapshots taken
        while both flow (:class:`.clocks.ClockWatch`). Kept in ``_jumped`` until :meth:`reset`:
        the buffers hold both clocks' times."""
        node = self._node
        now, ticked = time.monotonic(), node.last_ticked
        period = max((t[-1] - t[0]) * 1e-9 / (t.size - 1) for t in (hand_ns, eye_ns))
        if any(now - ticked[s] > max(STOPPED_S, FLOWING_PERIODS * period) for s in STREAMS):
            return
        # DDS's reception times where it gives them: the node's own times move with any
        # backlog of its executor (a loaded machine: a 3-s backlog of the device stream read
        # as a clock that jumped 3 s)
        received = node.last_received
        seen = received if all(received.values()) else node.last_ticked
        snap = Arrivals(int(hand_ns[-1]), int(eye_ns[-1]), seen['hand'], seen['eye'])
        moved = self._watch.moved(snap, period)
        self._jumped = [] if moved is None else [jump_advice(moved)]

    def reset(self) -> None:
        """The buffers were emptied: the motion, the latest result and the clocks start afresh,
        and auto mode starts over (a new recording: its first good result is published whatever
        the last one reported)."""
        self._watch.reset()
        self._jumped = []
        self._motion = Motion()
        self.latest = None
        self._next_check = 0.0
        self.auto = Auto.start(self._on)

    def late(self) -> list[str]:
        """A stream the node takes more than LATE_S after DDS received it, said as advice (it
        does not hold READY back: the poses buffered are sound): the machine is too busy for the
        streams' rates, and poses beyond the queue are lost."""
        now, ticked = time.monotonic(), self._node.last_ticked
        return [
            f'the node takes the {stream} poses {late:.1f} s after they arrive: this machine is '
            'too busy for their rate (poses beyond the queue are lost); close other programs'
            for stream, late in self._node.taken_late.items()
            if late > LATE_S and now - ticked[stream] < STOPPED_S  # a stream that flows
        ]

    def _publish(self) -> None:
        stopped = self.stopped() + self._jumped
        if stopped and self.last is not None:
            self.last = {**self.last, 'ready': False, 'missing': [*stopped, *self.last['missing']]}
        late = self.late() + self.ended() + self.clock_standing()  # advice only
        if late and self.last is not None:
            self.last = {**self.last, 'missing': [*self.last['missing'], *late]}
        st = self.status()
        self._send(st)
        self._say(st.message if self.last is None else status_line(self.last))

    def status(self) -> DiagnosticStatus:
        """The status as ``~/status`` and /diagnostics carry it."""
        st = diagnostics.readiness_status(
            self._node.get_fully_qualified_name(), self.last, self.why_not
        )
        if self.auto.state is not State.OFF:
            st.values.append(diagnostics.KeyValue(key='auto_calibrate', value=said(self.auto)))
        return st

    def _say(self, line: str) -> None:
        """One line, logged when READY, the latest verdict, the first thing to do or auto
        mode's state changes (and every LOG_PERIOD_S), not for every new figure."""
        if self.auto.state is not State.OFF:
            line += f' | auto_calibrate {said(self.auto)}'
        now = time.monotonic()
        last_t, last_key = self._logged
        r = self.last
        todo = r['missing'][0].split(':')[0][:60] if r and r['missing'] else ''
        key = f'{r["ready"]} {r["verdict"]} {todo}' if r else line
        key += f' {self.auto.state}'
        if key != last_key or now - last_t >= LOG_PERIOD_S:
            self._logged = (now, key)
            self._node.get_logger().info(f'status: {line}')
