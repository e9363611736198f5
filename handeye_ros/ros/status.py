"""The calibrator's readiness status while recording (its auto mode is :mod:`.auto_mode`).

Every ``status_period`` (less often when one computation costs more than MAX_DUTY of a core over
the period) the node hands the poses that came since the last status to its worker pool, which
adds what they say to what it has gathered (:mod:`handeye_ros.core.checks.progress`: excitation
about each axis of the device, the information of the eye's consecutive pairs at one estimate);
the node judges the sum (:mod:`handeye_ros.core.checks.readiness`: the 1-sigmas a calibration
now would have against the ``precision_*`` targets, what is missing in the user's words). So a
status costs the same at 10 s and at 30 min of buffers. The whole buffers are read again (a
snapshot: stages 1 and 2, then every piece) first, while stages 1 and 2 give no estimate, when
the pairs' optimum has moved beyond its 1-sigma, and as the buffers grow by half; the pieces of
poses the buffers drop are dropped with them. The answer is published on ``~/status``
(diagnostic_msgs/DiagnosticStatus), goes into /diagnostics, and is logged as one line when it
changes (and every LOG_PERIOD_S): never redrawn in place, which would glue log lines onto it in
a terminal and its redraws into one line under ``ros2 launch``. The node's executor only copies
the poses and adds up the pieces: ingest never waits for the computation.

With ``auto_calibrate``, :mod:`.auto_mode` calibrates by the status.
"""

from __future__ import annotations

import concurrent.futures as cf
import time
from collections.abc import Callable
from typing import TypeVar

from diagnostic_msgs.msg import DiagnosticStatus

from ..core.arrays import Stamps
from ..core.checks.carry import carry_over
from ..core.checks.progress import Measured, Progress
from ..core.checks.readiness import readiness_of
from ..core.checks.verdict import BLOCKS_MARGIN
from ..core.document import ReadinessDoc
from ..core.errors import HandeyeError
from ..evaluation.terminal import status_line
from ..stream import STREAMS
from . import diagnostics
from .auto_mode import GROWTH, AutoMode
from .clocks import Arrivals, ClockWatch, jump_advice
from .host import StatusHost
from .jobs import readiness_measure, readiness_start

#: What a status job gives back (with its CPU time).
_V = TypeVar('_V')

#: Each of the status's two jobs (reading the whole buffers, reading the new poses) takes at
#: most this share of one core on average: one that cost c seconds of CPU (the node's copy of
#: the poses, in its thread, and the worker's job, in all its threads) is followed by none of
#: its kind for c / MAX_DUTY. What is not counted (the transfer to the worker and back, the
#: sum of the pieces, the publishing) is the rest of the 5 % asked for. Measured
#: (bench/node_ingest.py, 1 kHz + 200 Hz, default buffers, 10 min): a status every 1.0 s
#: (status_period 1), 2.5 % of a core in all; each status read everything buffered before,
#: and came every 34 s once 500 000 + 120 000 poses were.
MAX_DUTY = 0.03
#: A stream with no usable pose for this long (s) has stopped, or lost its poses (messages
#: still coming).
STOPPED_S = diagnostics.STOPPED_S
#: Snapshots count while both streams flow (a pose within this many periods, STOPPED_S at
#: least): after one ends, the other's stamps run at the pace of a replay, which is no clock's.
FLOWING_PERIODS = 10
#: The node taking a stream's poses this much after DDS received them (s) is said.
LATE_S = 1.0
#: What the status says while a calibration checks a predicted READY.
CHECKING = (
    'checking READY: a calibration of the data so far is judging them (for purpose extrinsic, '
    'once they are predicted to meet the targets)'
)
#: The status line is logged when it changes, and at least this often (s).
LOG_PERIOD_S = 10.0


class ReadinessStatus:
    """The status of ``node`` (a :class:`~handeye_ros.ros.node.CalibratorNode`)."""

    def __init__(
        self, node: StatusHost, auto: bool, publish: Callable[[DiagnosticStatus], None]
    ) -> None:
        """``publish``: what ``~/status`` sends with; the node ticks :meth:`tick` each
        ``status_period``."""
        self._node = node
        self._send = publish
        #: the last readiness (the result's ``readiness`` section), or None with why_not
        self.last: ReadinessDoc | None = None
        self.why_not = 'waiting for data'
        self.auto = AutoMode(node, auto)
        #: what the status has gathered of the buffers
        self._progress: Progress | None = None
        #: bumped when the buffers are read whole again or reset: older answers are dropped
        self._generation = 0
        #: a job of each kind under way; when the next may start (monotonic s)
        self._pending = {'start': False, 'measure': False}
        self._next = {'start': 0.0, 'measure': 0.0}
        self._logged = (0.0, '')
        #: the streams' clocks against their arrivals, snapshot by snapshot
        self._watch = ClockWatch()
        #: the clocks' advice (:meth:`_clocks`), on the executor with each snapshot
        self._jumped: list[str] = []
        #: the buffered span (s) when a check of READY was last started
        self._checked_span = 0.0
        #: the node's simulated clock when it last moved (ns) and when that was (monotonic s)
        self._sim_clock = (0, time.monotonic())

    def tick(self) -> None:
        """On the executor: maybe calibrate (auto mode), then ask the workers for a status:
        of the whole buffers when :meth:`_restart_due`, else of the poses new since the last
        one."""
        node = self._node
        self.auto.step(self.last, ended=bool(self.ended()))
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
        if self._restart_due() and not self._pending['start'] and now >= self._next['start']:
            self._start()
        if self._progress and not self._pending['measure'] and now >= self._next['measure']:
            self._measure()

    def _restart_due(self) -> bool:
        """Whether the status reads the whole buffers again
        (:meth:`~handeye_ros.core.checks.progress.Progress.due`)."""
        p = self._progress
        span = min(self._node.recorder.buffers[s].span_s for s in STREAMS)
        return p is None or p.due(span) is not None

    def _start(self) -> None:
        node, t0 = self._node, time.thread_time()
        try:
            snapshot = node.recorder.snapshot()
        except HandeyeError as err:
            self.last, self.why_not = None, str(err)
            self._publish()
            return
        self._clocks(snapshot.hand.t_ns, snapshot.eye.t_ns)
        self._ask('start', readiness_start, (snapshot, node.options()), t0, self._started)

    def _measure(self) -> None:
        node, t0, p = self._node, time.thread_time(), self._progress
        buffers = node.recorder.buffers
        hand_ns, eye_ns = (buffers[s].newest_ns for s in STREAMS)
        if p is None or hand_ns is None or eye_ns is None:
            return
        try:
            tails = node.recorder.tails(dict(zip(STREAMS, p.wants(hand_ns, eye_ns), strict=True)))
        except HandeyeError:  # emptied meanwhile: the next tick says so
            return
        self._clocks(tails['hand'].t_ns, tails['eye'].t_ns)
        self._ask(
            'measure', readiness_measure, (p.cursor(), tails, node.options()), t0, self._measured
        )

    def _ask(
        self,
        kind: str,
        fn: Callable[..., tuple[_V, float]],
        args: tuple[object, ...],
        t0: float,
        then: Callable[[_V], None],
    ) -> None:
        """Submit one of the status's jobs; its answer goes to ``then`` on the executor, unless
        the buffers were reset or read whole again meanwhile."""
        node, generation = self._node, self._generation
        self._pending[kind] = True
        try:
            job = node.submit(fn, *args)
        except RuntimeError:  # the pool is shut down: the node stops
            self._pending[kind] = False
            return
        node_cpu = time.thread_time() - t0
        job.add_done_callback(
            lambda job: node.on_executor(self._done, kind, generation, job, node_cpu, then)
        )

    def _done(
        self,
        kind: str,
        generation: int,
        job: cf.Future[tuple[_V, float]],
        node_cpu: float,
        then: Callable[[_V], None],
    ) -> None:
        """On the executor: a job's answer; the next job of its kind waits for its cost."""
        self._pending[kind] = False
        if self._node.closing:  # the node stopped the worker under this job: nothing to say
            return
        try:
            value, job_cpu = job.result()
        except Exception as err:  # noqa: BLE001  (a status is not worth a crash)
            self.last, self.why_not = None, f'no status: {type(err).__name__}: {err}'
            self._publish()
            return
        self._next[kind] = time.monotonic() + (node_cpu + job_cpu) / MAX_DUTY
        if generation != self._generation:
            return
        try:
            then(value)
        except Exception as err:  # noqa: BLE001  (as above)
            self.last, self.why_not = None, f'no status: {type(err).__name__}: {err}'
            self._publish()

    def _started(self, progress: Progress) -> None:
        self._generation += 1  # the measures under way are of the old pieces
        self._progress = progress
        self._report()

    def _measured(self, measured: Measured) -> None:
        if self._progress is not None:  # a measure is asked of started pieces only
            self._progress.take(measured)
            self._report()

    def _report(self) -> None:
        """Judge the pieces of the poses still buffered, and publish."""
        p, buffers = self._progress, self._node.recorder.buffers
        hand_ns, eye_ns = (buffers[s].oldest_ns for s in STREAMS)
        if p is None or hand_ns is None or eye_ns is None:
            return
        p.drop_before(hand_ns, eye_ns)
        durations = (buffers['hand'].span_s, buffers['eye'].span_s)
        found = readiness_of(p, self._node.calib_cfg, durations).to_dict()
        auto = self.auto
        decide = self._node.calib_cfg.purpose == 'extrinsic'
        last = carry_over(
            found, auto.factors, auto.held, margin=BLOCKS_MARGIN, sigmas_decide=decide
        )
        if last['ready'] and not auto.confirmed:
            # READY is said once a calibration of these buffers agrees: auto mode's first one,
            # or a check of its own
            last = {
                **last,
                'ready': False,
                'checking': True,
                'missing': [CHECKING, *last['missing']],
            }
            if auto.said == 'off':
                self._check(min(durations))
        elif (
            auto.held
            and auto.said == 'off'
            and carry_over(found, auto.factors, [], margin=BLOCKS_MARGIN, sigmas_decide=decide)[
                'ready'
            ]
        ):
            self._check(min(durations))  # READY but for the last result's reasons: check again
        self.last, self.why_not = last, ''
        self._publish()

    def _check(self, span_s: float) -> None:
        """Calibrate the buffers to confirm a predicted READY (not published), and again only
        once the buffers have grown by GROWTH since (the check failed, or its result was doubtful
        for another reason than its precision), or once the recording has ended on more than the
        last check had (it grows no more)."""
        grown = span_s >= GROWTH * self._checked_span
        last_of_it = bool(self.ended()) and span_s > self._checked_span
        if (grown or last_of_it) and self._node.calibrate(check=True) is not None:
            self._checked_span = span_s

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
        """The buffers were emptied: the clocks are compared afresh, and auto mode starts over
        (a new recording: its first result is published whatever the last one reported)."""
        self._watch.reset()
        self._jumped = []
        self._checked_span = 0.0
        self._progress = None
        self._generation += 1
        self._next['start'] = 0.0
        self.auto.reset()

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
        if self.auto.said != 'off':
            st.values.append(diagnostics.KeyValue(key='auto_calibrate', value=self.auto.said))
        return st

    def _say(self, line: str) -> None:
        """One line, logged when it changes (and every LOG_PERIOD_S)."""
        if self.auto.ended:
            line += f' | {self.auto.said}'
        now = time.monotonic()
        last_t, last_key = self._logged
        # said again when READY or the first thing to do changes, not for every new figure
        todo = self.last['missing'] if self.last else [line]
        key = line.split('|')[0] + (todo[0].split(':')[0][:60] if todo else '')
        if key != last_key or now - last_t >= LOG_PERIOD_S:
            self._logged = (now, key)
            self._node.get_logger().info(f'status: {line}')
