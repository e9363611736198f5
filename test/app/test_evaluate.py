"""Many recordings on Dask (python -m handeye_ros.evaluate): the table, failures with their
reasons, the content-hash cache, and a worker killed mid-run on a real LocalCluster on loopback.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT, recording, run_cli

from handeye_ros.app.evaluate import EXIT_UNUSABLE
from handeye_ros.core.trajectory import Trajectory
from handeye_ros.formats import write_tum

pytestmark = pytest.mark.slow  # subprocesses, bags, evo, Dask or real data: seconds each


def _write_runs(folder: Path, n: int, seed0: int = 200) -> list[dict]:
    runs = []
    for k in range(n):
        rec = recording(seed=seed0 + k, level=2.0, duration_s=60.0)
        h, e = folder / f'hand{k}.txt', folder / f'eye{k}.txt'
        write_tum(h, rec.hand)
        write_tum(e, rec.eye)
        runs.append(
            {
                'algorithm': f'alg{k % 2}',
                'sequence': f'seq{k // 2}',
                'trial': 0,
                'hand': h.name,
                'eye': e.name,
            }
        )
    return runs


def _rows(out: Path) -> list[dict]:
    with (out / 'results.csv').open() as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope='module')
def manifest(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp('manifest')
    runs = _write_runs(folder, 4)
    # a run whose file is missing, and one that cannot calibrate (the hand never rotates)
    runs.append({'name': 'missing file', 'hand': 'nowhere.txt', 'eye': 'eye0.txt'})
    still = folder / 'still.txt'
    t = np.arange(3000, dtype=np.int64) * 10_000_000 + 1_700_000_000 * 10**9
    write_tum(
        still,
        Trajectory.from_arrays(
            t, np.zeros((t.size, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (t.size, 1))
        ),
    )
    runs.append({'name': 'no motion', 'hand': 'still.txt', 'eye': 'eye1.txt'})
    path = folder / 'manifest.yaml'
    path.write_text(yaml.safe_dump({'defaults': {'batch': True}, 'runs': runs}))
    return path


def test_table_marks_failures_and_the_exit_code_counts_them(manifest, tmp_path: Path) -> None:
    out = tmp_path / 'out'
    res = run_cli(
        str(manifest),
        '--output',
        str(out),
        '--workers',
        '2',
        module='handeye_ros.evaluate',
        timeout=300,
    )
    assert 'Traceback' not in res.stderr, res.stderr
    assert res.returncode == 2, res.stderr
    rows = _rows(out)
    assert [r['name'] for r in rows] == [
        'alg0/seq0/0',
        'alg1/seq0/0',
        'alg0/seq1/0',
        'alg1/seq1/0',
        'missing file',
        'no motion',
    ]
    ok = rows[:4]
    assert all(r['status'] == 'ok' and r['verdict'] == 'good' for r in ok)
    # level 2 noise, 60 s (at 40 s seed 202's result sat at the 5 % line of its figures, 5.4 %;
    # at 60 s the four are at 1.4-3.0 %): the same bounds as the pipeline tests (a few mm and ms)
    assert all(float(r['ape_mm']) < float(r['ape_uncalibrated_mm']) for r in ok)
    assert rows[4]['status'] == 'failed' and 'no such file' in rows[4]['reason']
    assert rows[5]['status'] == 'failed' and rows[5]['reason']
    assert (out / 'results.md').read_text().count('\n') == 2 + 6
    assert (out / 'summary.png').stat().st_size > 10_000
    for r in ok:
        run = out / 'runs' / r['name'].replace('/', '_')
        assert (run / 'export' / 'groundtruth.tum').is_file() and (run / 'result.yaml').is_file()
    # every finished run is cached by content: a second evaluation runs nothing again
    again = run_cli(
        str(manifest),
        '--output',
        str(out),
        '--sequential',
        module='handeye_ros.evaluate',
        timeout=300,
    )
    assert again.returncode == 2 and '6 from the cache' in again.stdout
    assert [r['time_offset_ms'] for r in _rows(out)] == [r['time_offset_ms'] for r in rows]


def test_directory_layout_and_an_unusable_manifest(tmp_path: Path) -> None:
    runs = _write_runs(tmp_path, 2, seed0=300)
    for r in runs:
        trial = tmp_path / 'layout' / r['algorithm'] / r['sequence'] / '0'
        trial.mkdir(parents=True)
        os.replace(tmp_path / r['hand'], trial / 'hand.txt')
        os.replace(tmp_path / r['eye'], trial / 'eye.txt')
    res = run_cli(
        str(tmp_path / 'layout'),
        '-o',
        str(tmp_path / 'out'),
        '--sequential',
        module='handeye_ros.evaluate',
        timeout=300,
    )
    assert res.returncode == 0, res.stderr
    assert [r['status'] for r in _rows(tmp_path / 'out')] == ['ok', 'ok']
    bad = tmp_path / 'bad.yaml'
    bad.write_text('runs: {not: a list}\n')
    for manifest in (bad, tmp_path / 'absent.yaml'):
        res = run_cli(str(manifest), '-o', str(tmp_path / 'o2'), module='handeye_ros.evaluate')
        assert res.returncode == EXIT_UNUSABLE and 'Traceback' not in res.stderr
        assert res.stderr.startswith('evaluate: error: '), res.stderr


def test_an_internal_error_is_no_failure_of_the_run_and_is_not_cached(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A bug (here: the application raising RuntimeError) is the row's ``error``, not ``failed``
    (the inputs): it is counted, said, and not cached, so the next evaluation runs it again."""
    from handeye_ros.app import evaluate, request

    runs = _write_runs(tmp_path, 1, seed0=400)
    manifest = tmp_path / 'runs.yaml'
    manifest.write_text(yaml.safe_dump({'runs': runs}))
    out = tmp_path / 'out'

    def broken(*args: object, **kw: object) -> None:
        raise RuntimeError('a bug')

    monkeypatch.setattr(request, 'run', broken)
    assert evaluate.main([str(manifest), '-o', str(out), '--sequential']) == 1
    (row,) = _rows(out)
    assert row['status'] == 'error' and row['reason'] == 'internal error: RuntimeError: a bug'
    assert 'alg0/seq0/0: error: internal error' in capsys.readouterr().err
    monkeypatch.undo()
    assert evaluate.main([str(manifest), '-o', str(out), '--sequential']) == 0
    assert [r['status'] for r in _rows(out)] == ['ok']
    assert 'from the cache' not in capsys.readouterr().out


def test_a_worker_killed_mid_run_costs_only_a_retry(tmp_path: Path, monkeypatch) -> None:
    from distributed import Client, LocalCluster

    monkeypatch.setenv('PYTHONPATH', str(ROOT))  # the workers import the package from here
    runs = _write_runs(tmp_path, 6, seed0=400)
    manifest = tmp_path / 'm.yaml'
    manifest.write_text(yaml.safe_dump({'runs': runs}))
    out = tmp_path / 'out'
    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host='127.0.0.1',
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        proc = subprocess.Popen(
            [
                sys.executable,
                '-m',
                'handeye_ros.evaluate',
                str(manifest),
                '-o',
                str(out),
                '--scheduler',
                cluster.scheduler_address,
            ],
            env=env,
            cwd=ROOT,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        killed = None
        deadline = time.monotonic() + 120
        while killed is None and time.monotonic() < deadline and proc.poll() is None:
            busy = {w: keys for w, keys in client.processing().items() if keys}
            if busy:
                worker = min(busy)
                pid = client.run(os.getpid, workers=[worker])[worker]
                os.kill(pid, signal.SIGKILL)
                killed = (worker, pid)
            time.sleep(0.05)
        stdout, stderr = proc.communicate(timeout=300)
    assert killed is not None, 'no task was seen running'
    assert proc.returncode == 0, stderr
    assert 'Traceback' not in stderr
    rows = _rows(out)
    names = [r['name'] for r in rows]
    assert sorted(names) == sorted(f'{r["algorithm"]}/{r["sequence"]}/0' for r in runs)
    assert len(set(names)) == len(names) == 6  # no run lost, none twice
    assert all(r['status'] == 'ok' for r in rows), stdout


def _dask_cluster(tmp: Path, preload: Path | None = None):
    """A scheduler and a one-process worker started as a user would, from this venv's ``dask``
    command on loopback (with ``preload`` in both when given); yields the address."""
    import contextlib

    dask = Path(sys.executable).with_name('dask')
    if not dask.is_file():
        pytest.skip(f'no dask command beside {sys.executable}')
    env = {k: v for k, v in os.environ.items() if k != 'PYTHONPATH'}
    extra = ['--preload', str(preload)] if preload else []
    info = tmp / 'scheduler.json'

    @contextlib.contextmanager
    def started():
        procs = [
            subprocess.Popen(
                [
                    str(dask),
                    'scheduler',
                    '--host',
                    '127.0.0.1',
                    '--port',
                    '0',
                    '--no-dashboard',
                    '--scheduler-file',
                    str(info),
                    *extra,
                ],
                env=env,
                cwd=tmp,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        ]
        try:
            # the scheduler creates its file, then writes it: wait for what it says, not for
            # the file to exist (an empty file was read once in a loaded CI run)
            deadline = time.monotonic() + 60
            while _said_address(info) is None and time.monotonic() < deadline:
                time.sleep(0.1)
            address = _said_address(info)
            assert address is not None, f'the scheduler wrote no address in {info} within 60 s'
            procs.append(
                subprocess.Popen(
                    [
                        str(dask),
                        'worker',
                        address,
                        '--nworkers',
                        '1',
                        '--nthreads',
                        '1',
                        '--no-dashboard',
                        '--host',
                        '127.0.0.1',
                        *extra,
                    ],
                    env=env,
                    cwd=tmp,
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            )
            yield address
        finally:
            for p in reversed(procs):
                p.terminate()
            for p in procs:
                try:
                    p.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    p.kill()

    return started()


def _evaluate_outside(tmp: Path, *args: str) -> subprocess.CompletedProcess:
    """The evaluate command of this venv run from a folder outside the repository, without
    PYTHONPATH: the package must be installed (scripts/setup installs it editable)."""
    env = {k: v for k, v in os.environ.items() if k != 'PYTHONPATH'}
    cmd = Path(sys.executable).with_name('handeye-ros-evaluate')
    if not cmd.is_file():
        pytest.skip(f'handeye_ros is not installed in {sys.prefix} (scripts/setup installs it)')
    return subprocess.run(
        [str(cmd), *args],
        env=env,
        cwd=tmp,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )


def test_running_cluster_from_the_venv(tmp_path: Path) -> None:
    """evaluate --scheduler against a scheduler and a worker started from the venv's dask
    command: every run ok, from any directory."""
    runs = _write_runs(tmp_path, 2, seed0=500)
    manifest = tmp_path / 'm.yaml'
    manifest.write_text(yaml.safe_dump({'runs': runs}))
    with _dask_cluster(tmp_path) as address:
        res = _evaluate_outside(
            tmp_path, str(manifest), '-o', str(tmp_path / 'o'), '--scheduler', address
        )
    assert res.returncode == 0, res.stderr
    assert [r['status'] for r in _rows(tmp_path / 'o')] == ['ok', 'ok']


def test_cluster_that_cannot_import_the_package_is_named(tmp_path: Path) -> None:
    """A cluster whose processes cannot import handeye_ros (a preload hides it, as an
    environment without the package would): one line saying so and how to fix it, exit 101,
    instead of every run failing with a deserialization error."""
    hide = tmp_path / 'hide.py'
    hide.write_text("import sys\nsys.modules['handeye_ros'] = None\n")
    runs = _write_runs(tmp_path, 1, seed0=510)
    manifest = tmp_path / 'm.yaml'
    manifest.write_text(yaml.safe_dump({'runs': runs}))
    with _dask_cluster(tmp_path, preload=hide) as address:
        res = _evaluate_outside(
            tmp_path, str(manifest), '-o', str(tmp_path / 'o'), '--scheduler', address
        )
    assert res.returncode == EXIT_UNUSABLE, res.stderr
    assert 'Traceback' not in res.stderr
    line = res.stderr.strip().splitlines()[-1]
    assert (
        line.startswith('evaluate: error: the Dask cluster at')
        and 'cannot run handeye_ros' in line
    )
    assert 'its scheduler' in line and '1 of its 1 workers' in line and 'pip install -e' in line


def _said_address(info: Path) -> str | None:
    """The scheduler's address from its file, or None while the file is absent or not yet
    whole."""
    try:
        return json.loads(info.read_text())['address']
    except (OSError, ValueError, KeyError):
        return None
