"""Calibrate and evaluate many recordings on Dask: ``python -m handeye_ros.evaluate MANIFEST
--output DIR`` (also ``ros2 run handeye_ros evaluate``).

Each run of the manifest (see :mod:`handeye_ros.app.runs`) is calibrated, exported
(evo-ready files) and evaluated (APE/RPE with and without the calibration) as one Dask task.
By default a LocalCluster with one single-threaded worker process per core runs them on this
machine (nothing to install beyond the pinned requirements); ``--scheduler ADDRESS`` sends them
to a running cluster instead. Every finished run is cached by the content hash of its inputs
and options, so an interrupted evaluation resumes; a worker that dies costs only a retry of
its task (Dask reschedules it), never a lost or a duplicated row.

Writes ``DIR/results.csv`` and ``DIR/results.md`` (one row per run, failures with their
reason), the box plots ``DIR/summary.png``, and per run ``DIR/runs/<name>/`` (result.yaml,
export/, report/ when asked). Exit code: the number of failed runs (at most 100); 101 when the
manifest or the options cannot be used.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from .commands import prog

if TYPE_CHECKING:  # imported where used: --help answers before the core is loaded
    from distributed import Client

    from ..core.document import Row
    from .runs import RunSpec

LOG = logging.getLogger('handeye_ros.evaluate')  # not __name__: it is __main__ under -m
#: Exit code when nothing could be run (a bad manifest or option).
EXIT_UNUSABLE = 101
MAX_EXIT_FAILED = 100
#: How long a running cluster is given to show its first worker (s).
WORKER_WAIT_S = 20.0
#: Modules a LocalCluster's workers import as they start.
WORKER_PRELOAD = (
    'handeye_ros.app.runs',
    'handeye_ros.app.offline',
    'handeye_ros.core.pipeline',
    'handeye_ros.evaluation.outputs',
)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=prog('evaluate'),
        description=__doc__.split('\n\n')[0].replace('``', ''),
        epilog='Exit code: the number of failed runs (capped at 100); 101 when the manifest or '
        'the options cannot be used.',
    )
    p.add_argument(
        'manifest',
        help='a YAML manifest (runs: [{name, hand, eye | bag, ...}]) or '
        'a directory laid out as ALGORITHM/SEQUENCE/TRIAL/',
    )
    p.add_argument(
        '-o',
        '--output',
        required=True,
        metavar='DIR',
        help="where the table, the summary plots and each run's files go",
    )
    p.add_argument(
        '--scheduler',
        metavar='ADDRESS',
        help='a running Dask scheduler (tcp://host:port); default: a LocalCluster on this machine',
    )
    p.add_argument(
        '--workers',
        type=int,
        default=None,
        help='LocalCluster worker processes (default: one per core)',
    )
    p.add_argument(
        '--sequential',
        action='store_true',
        help='run every recording in this process, without Dask (for comparison)',
    )
    p.add_argument(
        '--reports',
        action='store_true',
        help="write every run's report.html (a run can also ask with report: true)",
    )
    p.add_argument(
        '--shared-extrinsic',
        action='store_true',
        help='the recordings are of one rig: one T_HE shared by all, each its own time '
        'offset (rig.yaml); those that disagree are named and left out; every row is '
        "evaluated at the rig's T_HE (no cache)",
    )
    p.add_argument(
        '--no-cache',
        action='store_true',
        help='calibrate every run again even when its inputs did not change',
    )
    p.add_argument(
        '--progress',
        action=argparse.BooleanOptionalAction,
        default=None,
        help='a progress bar on stderr (default: when stderr is a terminal)',
    )
    p.add_argument(
        '-v',
        '--verbose',
        action='store_true',
        help="log the phases' timings (cluster start, runs, tables)",
    )
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format='%(name)s: %(message)s', stream=sys.stderr)
    LOG.setLevel(logging.INFO if args.verbose else logging.WARNING)
    from dataclasses import replace

    from ..core.errors import HandeyeError
    from ..evaluation.outputs import check_directory
    from .runs import Status, read_manifest

    try:
        if args.workers is not None and not 1 <= args.workers <= 256:
            raise HandeyeError(f'--workers must be 1-256, got {args.workers}')
        runs = read_manifest(args.manifest)
        output = check_directory(args.output, '--output')
    except HandeyeError as err:
        print(f'evaluate: error: {err}', file=sys.stderr)
        return EXIT_UNUSABLE
    if args.reports:
        runs = [replace(r, report=True) for r in runs]
    try:
        if args.shared_extrinsic and len(runs) < 2:
            print(
                f'evaluate: error: {args.manifest}: --shared-extrinsic needs at least two '
                f'recordings, it has {len(runs)}',
                file=sys.stderr,
            )
            return EXIT_UNUSABLE
        rows = (evaluate_rig if args.shared_extrinsic else evaluate_runs)(runs, output, args)
    except KeyboardInterrupt:
        print(
            'evaluate: interrupted; finished runs are cached and will not run again',
            file=sys.stderr,
        )
        return 130
    except OSError as err:  # a scheduler that cannot be reached, a full disk
        print(f'evaluate: error: {err}', file=sys.stderr)
        return EXIT_UNUSABLE
    failed = [r for r in rows if r['status'] != Status.OK]
    for r in failed:
        print(f'evaluate: {r["name"]}: {r["status"]}: {r["reason"]}', file=sys.stderr)
    cached = sum(bool(r.get('cached')) for r in rows)
    print(
        f'{len(rows)} runs, {len(rows) - len(failed)} ok, {len(failed)} failed'
        + (f', {cached} from the cache' if cached else '')
        + f'; table: {output / "results.csv"}'
    )
    return min(len(failed), MAX_EXIT_FAILED)


def evaluate_runs(runs: list[RunSpec], output: Path, args: argparse.Namespace) -> list[Row]:
    """Every run's row, in manifest order (cached rows reused); writes the tables and plots."""
    from tqdm import tqdm

    from .runs import (
        Status,
        cache_key,
        calibrate_run,
        code_fingerprint,
        read_cached,
        write_cached,
    )

    cache = output / 'cache'
    code = code_fingerprint()
    keys = {r.name: cache_key(r, code) for r in runs}
    rows: dict[str, Row] = {}
    todo = []
    for r in runs:
        hit = None if args.no_cache else read_cached(cache, keys[r.name])
        if hit is not None:
            rows[r.name] = {**hit, 'name': r.name, 'cached': True}
        else:
            todo.append(r)
    bar = tqdm(
        total=len(runs),
        initial=len(runs) - len(todo),
        unit='run',
        desc='evaluating',
        file=sys.stderr,
        disable=None if args.progress is None else not args.progress,
    )

    def done(run: RunSpec, row: Row) -> None:
        row['cached'] = False
        if row['status'] != Status.ERROR:
            write_cached(cache, keys[run.name], row)
        rows[run.name] = row
        bar.update(1)

    with bar:
        if args.sequential or not todo:
            t0 = time.perf_counter()
            for r in todo:
                done(r, calibrate_run(r, str(output)))
            LOG.info('timing: runs %.2f s', time.perf_counter() - t0)
        else:
            _on_dask(todo, output, args, done)
    ordered = [rows[r.name] for r in runs]
    _tables(output, ordered)
    return ordered


def _tables(output: Path, rows: list[Row]) -> None:
    """results.csv, results.md and summary.png."""
    from .results_table import write_tables

    t0 = time.perf_counter()
    write_tables(output, rows)
    try:
        from ..evaluation.plots import summary

        summary(rows, output / 'summary.png')
    except Exception as err:  # noqa: BLE001  (the table matters more than the picture)
        LOG.warning('summary plot not written: %s', err)
    LOG.info('timing: tables and plots %.2f s', time.perf_counter() - t0)


class ClusterError(OSError):
    """A running cluster that cannot run the tasks (it cannot import the package)."""


def _check_cluster(client: Client, address: str) -> None:
    """Refuse a cluster whose scheduler or workers cannot import the package: they unpickle
    every task, and without it each run would fail with "Error during deserialization of the
    task graph" and nothing more."""
    import importlib

    where = []
    try:
        client.run_on_scheduler(importlib.import_module, WORKER_PRELOAD[0])
    except Exception as err:  # noqa: BLE001  (any error the scheduler raises back)
        where.append(f'its scheduler ({type(err).__name__}: {err})')
    try:
        client.wait_for_workers(1, timeout=WORKER_WAIT_S)
    except TimeoutError:
        pass  # said below
    failed = client.run(importlib.import_module, WORKER_PRELOAD[0], on_error='return')
    bad = sorted(w for w, r in failed.items() if isinstance(r, BaseException))
    if bad:
        where.append(f'{len(bad)} of its {len(failed)} workers ({", ".join(bad[:3])})')
    if not failed:
        where.append(f'it has no workers (none joined within {WORKER_WAIT_S:g} s)')
    if where:
        here = Path(__file__).resolve().parents[1]
        raise ClusterError(
            f'the Dask cluster at {address} cannot run handeye_ros: {"; ".join(where)}. '
            'Its scheduler and workers must import the package: start them from the '
            f'environment this tool runs in ({sys.prefix}/bin/dask scheduler, dask worker '
            f'ADDRESS), or install it in theirs (pip install -e {here})'
        )


@contextmanager
def _client(args: argparse.Namespace) -> Iterator[Client]:
    """A Dask client on a LocalCluster (or ``args.scheduler``), closed on leaving."""
    from distributed import Client, LocalCluster

    # the scheduler runs in this process: its INFO lines would bury the table's summary
    logging.getLogger('distributed').setLevel(logging.ERROR)
    cluster = None
    t0 = time.perf_counter()
    if args.scheduler:
        client = Client(args.scheduler, timeout='20s')
        try:
            _check_cluster(client, args.scheduler)
        except ClusterError:
            client.close()
            raise
    else:
        n = args.workers or os.cpu_count() or 1
        # the workers import the package while the cluster starts, not in their first run
        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host='127.0.0.1',
            dashboard_address=None,
            # CRITICAL: a worker whose heartbeat meets the scheduler closing at the end logs an
            # ERROR with a traceback (seen once under load); a task's own error comes back
            # through its future, and its row says it
            silence_logs=logging.CRITICAL,
            preload=list(WORKER_PRELOAD),
        )
        client = Client(cluster)
    LOG.info('timing: cluster start %.2f s', time.perf_counter() - t0)
    try:
        yield client
    finally:
        t0 = time.perf_counter()
        client.close()
        if cluster is not None:
            cluster.close()
        LOG.info('timing: cluster stop %.2f s', time.perf_counter() - t0)


def _on_dask(
    todo: list[RunSpec],
    output: Path,
    args: argparse.Namespace,
    done: Callable[[RunSpec, Row], None],
) -> None:
    """Run ``todo`` on a LocalCluster (or ``args.scheduler``); ``done(run, row)`` as each ends.

    A task whose worker died is rescheduled by Dask itself (the scheduler's allowed-failures);
    if it keeps killing workers its row says so. Rows arrive once per future, whatever the
    retries, so none is lost or duplicated.
    """
    from distributed import as_completed

    from .runs import Status, calibrate_run

    with _client(args) as client:
        t0 = time.perf_counter()
        futures = {
            client.submit(
                calibrate_run, r, str(output), key=f'calibrate-{k}-{r.slug()}', pure=False
            ): r
            for k, r in enumerate(todo)
        }
        for fut in as_completed(futures):
            run = futures[fut]
            try:
                row = fut.result()
            except Exception as err:  # noqa: BLE001  (KilledWorker after repeated deaths)
                row = {
                    'name': run.name,
                    'algorithm': run.algorithm,
                    'sequence': run.sequence,
                    'trial': run.trial,
                    'status': Status.ERROR,
                    'reason': f'internal error: {type(err).__name__}: {err}',
                }
            done(run, row)
        LOG.info('timing: runs %.2f s', time.perf_counter() - t0)


def evaluate_rig(runs: list[RunSpec], output: Path, args: argparse.Namespace) -> list[Row]:
    """``--shared-extrinsic``: the rig's two rounds (:mod:`handeye_ros.app.rig`) on Dask, or in
    this process with ``--sequential``; writes rig.yaml, the tables and the plots; the rows at
    the rig's T_HE. Nothing is cached: the rig changes with any of its recordings."""
    from .rig import calibrate_rig
    from .rig_file import rig_summary
    from .runs import rig_row

    t0 = time.perf_counter()
    if args.sequential:
        document, docs = calibrate_rig(runs, output)
    else:
        with _client(args) as client:
            submit = lambda fn, *a: client.submit(fn, *a, pure=False)
            document, docs = calibrate_rig(runs, output, submit, client.gather)
    LOG.info('timing: rig %.2f s', time.perf_counter() - t0)
    try:
        from ..evaluation.rig_report import write_rig_report

        write_rig_report(document, output)
    except Exception as err:  # noqa: BLE001  (the rig's file matters more than its page)
        LOG.warning('rig.html not written: %s', err)
    print(rig_summary(document))
    rows = [rig_row(r, d, document) for r, d in zip(runs, docs, strict=True)]
    _tables(output, rows)
    return rows


if __name__ == '__main__':
    sys.exit(main())
