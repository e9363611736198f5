"""The node's status and auto mode live on real recordings: six recordings written to EuRoC
files and replayed through DDS at their own stamps (``sim_publisher --replay``, real time unless
``--speed``) to a calibrator with ``auto_calibrate`` and the defaults (purpose evaluation, or
``--purpose``), while a probe in this process takes every ``~/status`` and, after each new
result, the file ``~/save`` writes.

Counted per recording: the first READY (the buffered span its status had, s of recording); the
READY statuses, one per CHECK_S seconds of them checked by an offline calibration of what that
status had read (the recording's first ``span_s`` seconds; READY beside a calibration that is not
``good`` must not happen), and by one of the span READY's own calibration had
(``calibrated_span_s``: the node's and the offline tool's verdicts of the same data); the
published results' verdicts (each must be ``good``, as auto mode publishes only those); what auto
mode said last (``converged`` must not be said of a result that is not ``good``); how far READY's
calibration is behind the buffers (span_s less calibrated_span_s).

``--prefixes STEP`` replays nothing: it calibrates each recording's first s seconds for s every
STEP seconds, as the status does while the buffers grow, and counts, for READY from a ``good``
result and for READY from a settled one (``good``, not near its line and its 1-sigmas complete,
what READY says), the spans at which READY would be said while a calibration of up to AHEAD_S
more seconds is not ``good`` (a user who stops at READY and calibrates, READY's data behind the
buffers), and where each would first be said; and auto mode's decisions (``auto_mode.decide``) on the prefixes the
status would calibrate (each LAST_GAIN_S on from the last, on the STEP grid, and the whole
recording once it has ended; live, a calibration's own time spaces them more): the spans it
publishes, where it first says ``converged``, and the converged spans followed within AHEAD_S by
a calibration that is not ``good``.

Usage: python bench/live_real.py [--speed 1] [--only NAME] [--purpose evaluation|extrinsic]
       python bench/live_real.py --prefixes 2 [--only NAME] [--purpose ...]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import cases
import common
import numpy as np
import yaml
from common import emit, table
from live import Spun, start, stop

from handeye_ros.core.config import CalibrationConfig
from handeye_ros.core.errors import HandeyeError
from handeye_ros.core.pipeline import calibrate
from handeye_ros.formats import write_euroc

#: READY statuses are checked at most this often (recording seconds).
CHECK_S = 10.0
#: After the replay: how long results may still come (a calibration started at its end).
GRACE_S = 6.0
#: --prefixes: how far ahead of a READY span a calibration that is not good counts against it
#: (s): READY's data behind the buffers (at most 11 s live, bench/results/readiness.md) or a
#: user's stop.
AHEAD_S = 10.0


def recordings() -> list[tuple[str, object, object]]:
    """Five EuRoC runs and TUM-VI room1's ORB-SLAM3 VIO (cases.RUNS)."""
    names = ('V1_02 evo', 'V2_01 mono', 'V2_02 stereo', 'MH_01 stereo', 'MH_03 mono')
    out = [(f'EuRoC {name}', *cases.run(f'EuRoC {name}').load()) for name in names]
    out.append(('TUM-VI room1 ORB-SLAM3 VIO', *cases.run('TUM-VI room1 orbslam').load()))
    return out


class LiveProbe(Spun):
    """An rclpy node in this process: /calibrator's statuses and results, and ~/save."""

    def __init__(self) -> None:
        from diagnostic_msgs.msg import DiagnosticStatus
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
        from std_msgs.msg import Float64
        from std_srvs.srv import Trigger

        super().__init__('bench_live_probe')
        self.Trigger = Trigger
        self.lock = threading.Lock()
        self.statuses: list[tuple[float, dict]] = []
        self.results: list[float] = []
        self.node.create_subscription(DiagnosticStatus, '/calibrator/status', self._status, 50)
        latched = QoSProfile(
            depth=1,
            reliability=ReliabilityPolicy.RELIABLE,
            durability=DurabilityPolicy.TRANSIENT_LOCAL,
        )
        self.node.create_subscription(Float64, '/calibrator/time_offset', self._result, latched)
        self.save = self.node.create_client(Trigger, '/calibrator/save')
        self.spin()

    def _status(self, msg) -> None:
        values = {kv.key: kv.value for kv in msg.values}
        with self.lock:
            self.statuses.append((time.monotonic(), {'message': msg.message, **values}))

    def _result(self, _) -> None:
        with self.lock:
            self.results.append(time.monotonic())

    def clear(self) -> None:
        with self.lock:
            self.statuses, self.results = [], []

    def call_save(self) -> tuple[bool, str]:
        self.save.wait_for_service(timeout_sec=30.0)
        fut = self.save.call_async(self.Trigger.Request())
        end = time.monotonic() + 30.0
        while not fut.done() and time.monotonic() < end:
            time.sleep(0.005)
        return (fut.result().success, fut.result().message) if fut.done() else (False, 'timeout')

    def results_until(self, pub: subprocess.Popen, saved: Path, grace_s: float) -> list:
        """Until ``grace_s`` after the publisher ``pub`` ends: (when, the file ``~/save`` wrote,
        or why not) of every new result."""
        docs, seen, grace = [], 0, None
        while grace is None or time.monotonic() < grace:
            if grace is None and pub.poll() is not None:
                grace = time.monotonic() + grace_s
            with self.lock:
                n = len(self.results)
            if n > seen:
                seen = n
                ok, msg = self.call_save()
                docs.append(
                    (self.results[n - 1], yaml.safe_load(saved.read_text()) if ok else msg)
                )
            time.sleep(0.05)
        return docs


def replay(probe: LiveProbe, name: str, hand, eye, out: Path, speed: float, purpose: str) -> dict:
    """One recording through the node: the statuses, and each result with its saved file."""
    probe.clear()
    tag = name.replace(' ', '_')
    files = [out / f'{tag}_hand.csv', out / f'{tag}_eye.csv']
    write_euroc(files[0], hand)
    write_euroc(files[1], eye)
    saved = out / f'{tag}.yaml'
    node = start(
        'handeye_ros.ros.calibrator',
        *('--ros-args', '-p', 'auto_calibrate:=true', '-p', f'output_dir:={out}'),
        *('-p', f'output_file:={saved.name}', '-p', f'purpose:={purpose}'),
        log=out / f'{tag}.log',
    )
    pub = start(
        'handeye_ros.ros.sim_publisher', '--replay', *map(str, files), '--speed', str(speed)
    )
    docs = probe.results_until(pub, saved, GRACE_S)
    out_text, err = pub.communicate()
    stop(node)
    with probe.lock:
        statuses = list(probe.statuses)
    return {'statuses': statuses, 'docs': docs, 'sent': out_text, 'log': err}


def _judged_at(hand, eye, cut_ns: int, cfg: CalibrationConfig):
    """The offline calibration of both streams up to ``cut_ns``, judged as the node judges it
    (for an evaluation, with the evaluation's figures); HandeyeError as calibrate raises it."""
    res = calibrate(hand.select(hand.t_ns <= cut_ns), eye.select(eye.t_ns <= cut_ns), cfg)
    return common.judged(res)[0] if cfg.purpose == 'evaluation' else res


def _verdict_at(hand, eye, cut_ns: int, cfg: CalibrationConfig) -> str:
    """The offline verdict of both streams up to ``cut_ns`` (:func:`_judged_at`)."""
    try:
        return _judged_at(hand, eye, cut_ns, cfg).quality.verdict.value
    except HandeyeError as e:
        return f'failed ({e})'[:40]


def _outcome_at(args: tuple):
    """The status's :class:`Outcome` of a calibration of both streams' first ``s`` seconds
    from their common start ``t0`` [ns], judged as the node judges it."""
    from handeye_ros.core.checks.readiness import Outcome

    hand, eye, t0, s, cfg = args
    try:
        res = _judged_at(hand, eye, t0 + int(s * 1e9), cfg)
    except HandeyeError as e:
        return Outcome.failure(e, s, 0.0)
    return Outcome.of(res.quality, res.batch, s, 0.0, cfg.precision)


def _auto_mode(got: list) -> list[str]:
    """Auto mode on the prefixes the status would calibrate (module docstring): the spans
    published, the first converged, the converged spans followed by one that is not good."""
    from handeye_ros.ros.auto_mode import Auto, State, decide
    from handeye_ros.ros.status import LAST_GAIN_S

    auto, published, converged = Auto.start(True), [], []
    k = 0
    while k < len(got):
        o = got[k]
        auto = decide(auto, o, full=False)
        if auto.publish:
            published.append(f'{o.span_s:.0f}')
        if auto.state is State.CONVERGED:
            converged.append(k)
        after = o.span_s + LAST_GAIN_S
        # once the recording has ended the status calibrates all of it (the last prefix)
        last = len(got) - 1 if k < len(got) - 1 else len(got)
        k = next((j for j in range(k + 1, len(got)) if got[j].span_s >= after - 1e-9), last)
    early = [
        f'{got[k].span_s:.0f}'
        for k in converged
        if not all(o.good for o in got[k:] if o.span_s <= got[k].span_s + AHEAD_S)
    ]
    first = f'{got[converged[0]].span_s:.0f}' if converged else '-'
    return [', '.join(published) or '-', first, ', '.join(early) or '0']


def prefixes(step_s: float, only: str, cfg: CalibrationConfig) -> None:
    """The ``--prefixes`` table (module docstring), two processes."""
    from concurrent.futures import ProcessPoolExecutor

    from handeye_ros.core.checks.readiness import MIN_RECORDING_S

    rows = []
    with ProcessPoolExecutor(2) as pool:
        for name, hand, eye in recordings():
            if only not in name:
                continue
            t0 = max(int(hand.t_ns[0]), int(eye.t_ns[0]))
            end = (min(int(hand.t_ns[-1]), int(eye.t_ns[-1])) - t0) * 1e-9
            spans = np.arange(MIN_RECORDING_S, end + 1e-9, step_s)
            got = list(pool.map(_outcome_at, [(hand, eye, t0, float(s), cfg) for s in spans]))
            row = [name, f'{end:.0f}', str(len(got))]
            for rule in (lambda o: o.good, lambda o: o.settled):
                ready = [rule(o) for o in got]
                early = [
                    f'{o.span_s:.0f}'
                    for k, o in enumerate(got)
                    if ready[k]
                    and not all(q.good for q in got[k:] if q.span_s <= o.span_s + AHEAD_S)
                ]
                first = next((f'{o.span_s:.0f}' for k, o in enumerate(got) if ready[k]), '-')
                row += [f'{sum(ready)}', ', '.join(early) or '0', first]
            near = [o for o in got if o.good and not o.settled]
            row.append(f'{len(near)}')
            row += _auto_mode(got)
            rows.append(row)
            print(row, flush=True)
    emit(
        f'live_real_prefixes_{cfg.purpose}',
        table(
            f"Each recording's first s seconds calibrated, s every {step_s:g} s from "
            f'{MIN_RECORDING_S:g} s (purpose {cfg.purpose}): READY from a good result, and from a '
            'settled one (good, not near its line, its 1-sigmas complete); "followed by not '
            f'good": READY spans with a calibration that is not good within {AHEAD_S:g} s more; '
            'auto mode on the spans the status would calibrate',
            [
                'recording',
                'seconds',
                'spans',
                'good',
                'good, followed by not good',
                'first good [s]',
                'settled',
                'settled, followed by not good',
                'first settled [s]',
                'good, not settled',
                'auto mode published [s]',
                'first converged [s]',
                'converged, followed by not good',
            ],
            rows,
        ),
        seeds={'step_s': step_s, 'ahead_s': AHEAD_S},
    )


def judged(run: dict, hand, eye, cfg: CalibrationConfig) -> dict:
    """READY statuses (the first, and at most one per CHECK_S seconds checked), the results'
    verdicts, what auto mode said last."""
    t0 = max(int(hand.t_ns[0]), int(eye.t_ns[0]))
    ready, checked, last_s, first, lags = 0, [], -np.inf, None, []
    for _, st in run['statuses']:
        if st['message'] != 'READY':
            continue
        ready += 1
        s, own = float(st['span_s']), float(st['calibrated_span_s'])
        lags.append(s - own)
        first = s if first is None else first
        if s - last_s < CHECK_S:
            continue
        last_s = s
        checked.append(
            (
                s,
                _verdict_at(hand, eye, t0 + int(s * 1e9), cfg),
                _verdict_at(hand, eye, t0 + int(own * 1e9), cfg),
            )
        )
    results = [
        doc['quality']['verdict'] if isinstance(doc, dict) else 'no result'
        for _, doc in run['docs']
    ]
    auto = [st.get('auto_calibrate', '') for _, st in run['statuses']]
    return {
        'span': (min(hand.t_ns[-1], eye.t_ns[-1]) - t0) * 1e-9,
        'first': first,
        'ready': ready,
        'lag': (float(np.median(lags)), max(lags)) if lags else None,
        'checked': checked,
        'results': results,
        'auto': next((a.split(':')[0] for a in reversed(auto) if a), '-'),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--speed', type=float, default=1.0, help='times real time (default 1)')
    p.add_argument('--only', default='', help='only the recordings whose name contains this')
    p.add_argument('--purpose', default='evaluation', choices=('evaluation', 'extrinsic'))
    p.add_argument('--prefixes', type=float, default=0.0, help='STEP s: prefixes, no replay')
    a = p.parse_args()
    cfg = CalibrationConfig(purpose=a.purpose)
    if a.prefixes > 0.0:
        prefixes(a.prefixes, a.only, cfg)
        return
    probe = LiveProbe()
    rows = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for name, hand, eye in recordings():
                if a.only not in name:
                    continue
                run = replay(probe, name, hand, eye, Path(tmp), a.speed, a.purpose)
                if not run['sent'].strip():
                    print(name, 'the replay did not end:', run['log'][-400:], flush=True)
                    continue
                j = judged(run, hand, eye, cfg)
                bad = [f'{s:.0f} s' for s, v, _ in j['checked'] if v != 'good']
                own = [f'{s:.0f} s' for s, _, v in j['checked'] if v != 'good']
                rows.append(
                    [
                        name,
                        f'{j["span"]:.0f}',
                        '-' if j['first'] is None else f'{j["first"]:.0f}',
                        f'{j["ready"]} ({len(j["checked"])})',
                        ', '.join(bad) or '0',
                        ', '.join(own) or '0',
                        '-' if j['lag'] is None else '{:.1f} / {:.1f}'.format(*j['lag']),
                        ', '.join(j['results']) or '-',
                        j['auto'],
                    ]
                )
                print(rows[-1], json.dumps(j['checked']), flush=True)
    finally:
        probe.close()
    emit(
        f'live_real_{a.purpose}',
        table(
            f'Real recordings replayed live at {a.speed:g}x their stamps through the node '
            f'(auto_calibrate, purpose {a.purpose}): the first READY, READY statuses (checked, '
            f'one per {CHECK_S:g} s) against a calibration of what the node had then; results',
            [
                'recording',
                'seconds',
                'first READY [s]',
                'READY statuses (checked)',
                'READY, calibration not good',
                'READY, its own span not good offline',
                "READY's data behind the buffers [s] (median / max)",
                'results published (verdicts)',
                'auto mode said last',
            ],
            rows,
        ),
    )


if __name__ == '__main__':
    main()
