"""Many recordings: the manifest, and one run (calibrate, export, evaluate) with its cached row
(the table of all rows: :mod:`.results_table`).

A manifest is YAML::

    defaults: {clock_drift: true}           # options for every run (optional)
    runs:
      - name: V1_01/openvins/0              # unique; default: algorithm/sequence/trial
        algorithm: openvins                 # for grouping (optional)
        sequence: V1_01
        trial: 0
        hand: gt/V1_01.csv                  # MoCap file, or bag: PATH (with hand_topic, ...)
        eye: openvins/V1_01/0.txt
        options: {scale: true}              # this run's options (optional)

or a directory laid out as ``ALGORITHM/SEQUENCE/TRIAL/`` holding ``hand.*`` and ``eye.*`` files
(or one bag). Relative paths are taken from the manifest's folder.

Every run is keyed by the content hash of its inputs and options (and this package's version):
its row is cached under ``OUTPUT/cache/`` when it ends (unless :class:`Status` ``error``), so an
interrupted evaluation resumes where it stopped and a changed file is calibrated again.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, TypedDict, Unpack

from ..core.errors import ConfigError
from .results_table import row_of

if TYPE_CHECKING:  # imported where used: a manifest is read without the core
    from ..core.document import ResultDoc, Row
    from ..core.rig_document import RigDoc
    from .request import Request


class Status(StrEnum):
    """How a run ended (its row's ``status``; a ``str``, as the tables write it): ``ok``;
    ``failed`` by its inputs, which the reason names, as it would again (cached); ``error`` by
    this machine or this package (out of memory, a worker lost, a bug), not cached: the next
    evaluation runs it again."""

    OK = 'ok'
    FAILED = 'failed'
    ERROR = 'error'


#: Keys of a manifest run that are not calibration options.
RUN_KEYS = ('name', 'algorithm', 'sequence', 'trial', 'hand', 'eye', 'bag', 'options', 'report')
#: Bumped when a row's meaning changes, so that old cache entries are not reused.
CACHE_VERSION = 2
HASH_CHUNK = 1 << 20
BAG_SUFFIXES = ('.mcap', '.db3', '.bag')


class Writes(TypedDict, total=False):
    """What a run's Request writes (the fields of :class:`~.request.Request` a run sets)."""

    evaluation: bool
    export: str | None
    report: str | None
    progress: bool | None


@dataclass(frozen=True)
class RunSpec:
    """One recording to calibrate: inputs (absolute paths), grouping labels and options."""

    name: str
    hand: str | None = None
    eye: str | None = None
    bag: str | None = None
    algorithm: str = ''
    sequence: str = ''
    trial: str = ''
    options: Mapping[str, object] = field(default_factory=dict)
    report: bool = False

    def inputs(self) -> list[str]:
        return [p for p in (self.hand, self.eye, self.bag) if p]

    def slug(self) -> str:
        """A file-system name for the run's output folder."""
        keep = ''.join(c if c.isalnum() or c in '-_.' else '_' for c in self.name)
        return keep.strip('._') or 'run'

    def request(self, **fields: Unpack[Writes]) -> Request:
        """The application's Request for this run's inputs and options, with ``fields`` (what
        to write); ConfigError when it names neither two files nor a bag (missing or
        unreadable files are named by the readers themselves)."""
        from .request import Request

        if not (self.bag or (self.hand and self.eye)):
            given = [f'{k} {v}' for k, v in (('hand', self.hand), ('eye', self.eye)) if v]
            raise ConfigError(
                f'a run needs hand and eye files, or a bag (given: {", ".join(given) or "none"}'
                '); a folder layout finds them by their names, hand.* and eye.*'
            )
        return Request(
            hand=None if self.bag else self.hand,
            eye=None if self.bag else self.eye,
            bag=self.bag or None,
            options=dict(self.options),
            **fields,
        )


def read_manifest(path: str | Path) -> list[RunSpec]:
    """The runs of a manifest file or directory layout (module docstring).

    Raises ConfigError when the manifest itself cannot be used (unreadable, not YAML, no runs,
    duplicate names); a run whose files are missing is kept and fails on its own.
    """
    path = Path(path)
    if path.is_dir():
        runs = _from_layout(path)
    else:
        runs = _from_yaml(path)
    if not runs:
        raise ConfigError(f'{path}: no runs found')
    names = [r.name for r in runs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ConfigError(f'{path}: run names must be unique; repeated: {", ".join(dup)}')
    return runs


def _from_yaml(path: Path) -> list[RunSpec]:
    import yaml

    try:
        data = yaml.safe_load(path.read_text(encoding='utf-8'))
    except FileNotFoundError:
        raise ConfigError(f'{path}: no such manifest') from None
    except (OSError, UnicodeDecodeError) as err:
        raise ConfigError(f'{path}: cannot read the manifest ({err})') from None
    except yaml.YAMLError as err:
        first = str(err).splitlines()[0] if str(err) else 'syntax error'
        raise ConfigError(f'{path}: not valid YAML ({first})') from None
    if not isinstance(data, dict) or not isinstance(data.get('runs'), list):
        raise ConfigError(f'{path}: expected a mapping with a list under "runs:"')
    defaults = data.get('defaults') or {}
    if not isinstance(defaults, dict):
        raise ConfigError(f'{path}: "defaults" must be a mapping of options')
    base = path.parent
    out = []
    for k, item in enumerate(data['runs']):
        if not isinstance(item, dict):
            raise ConfigError(f'{path}: run {k + 1} is not a mapping')
        extra = {key: v for key, v in item.items() if key not in RUN_KEYS}
        options = {**defaults, **(item.get('options') or {}), **extra}
        labels: dict[str, str] = {
            key: str(item.get(key, '')) for key in ('algorithm', 'sequence', 'trial')
        }
        name = str(item.get('name') or '/'.join(v for v in labels.values() if v) or f'run{k + 1}')
        files = {
            key: str((base / str(item[key])).resolve()) if item.get(key) else None
            for key in ('hand', 'eye', 'bag')
        }
        out.append(
            RunSpec(
                name=name,
                options=options,
                report=bool(item.get('report', False)),
                algorithm=labels['algorithm'],
                sequence=labels['sequence'],
                trial=labels['trial'],
                hand=files['hand'],
                eye=files['eye'],
                bag=files['bag'],
            )
        )
    return out


def _from_layout(root: Path) -> list[RunSpec]:
    out = []
    for trial in sorted(p for p in root.glob('*/*/*') if p.is_dir()):
        algorithm, sequence = trial.parent.parent.name, trial.parent.name
        files = {f.stem: f for f in sorted(trial.iterdir()) if f.is_file()}
        bags = [
            f
            for f in trial.iterdir()
            if f.suffix in BAG_SUFFIXES or (f.is_dir() and (f / 'metadata.yaml').is_file())
        ]
        spec = RunSpec(
            name=f'{algorithm}/{sequence}/{trial.name}',
            algorithm=algorithm,
            sequence=sequence,
            trial=trial.name,
            hand=str(files['hand']) if 'hand' in files else None,
            eye=str(files['eye']) if 'eye' in files else None,
            bag=str(bags[0]) if bags and 'hand' not in files else None,
        )
        out.append(spec)
    return out


def code_fingerprint() -> str:
    """sha256 of this package's Python sources: a changed algorithm invalidates the cache."""
    h = hashlib.sha256()
    root = Path(__file__).resolve().parent  # the handeye_ros package
    for f in sorted(root.rglob('*.py')):
        h.update(str(f.relative_to(root)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:16]


def cache_key(run: RunSpec, code: str) -> str:
    """sha256 of the run's input contents, options and the code (:func:`code_fingerprint`); no
    paths or names, so a moved file keeps its result."""
    h = hashlib.sha256(f'{CACHE_VERSION} {code}'.encode())
    h.update(
        json.dumps(
            {'options': run.options, 'report': run.report}, sort_keys=True, default=str
        ).encode()
    )
    for p in run.inputs():
        path = Path(p)
        files = sorted(f for f in path.rglob('*') if f.is_file()) if path.is_dir() else [path]
        for f in files:
            h.update(f.name.encode())
            try:
                with f.open('rb') as fh:
                    while chunk := fh.read(HASH_CHUNK):
                        h.update(chunk)
            except OSError:
                h.update(b'<unreadable>')  # the run itself will say why
    return h.hexdigest()[:32]


def calibrate_run(run: RunSpec, output: str) -> Row:
    """Calibrate, export and evaluate one run into ``output/runs/<slug>/``; its table row.

    Never raises: the row says ``status: failed`` (bad input) or ``error`` and why.
    """
    from ..core.errors import HandeyeError
    from ..formats.result_file import write_result
    from .request import run as run_request

    t0 = time.perf_counter()
    row: Row = {
        'name': run.name,
        'algorithm': run.algorithm,
        'sequence': run.sequence,
        'trial': run.trial,
    }
    folder = Path(output) / 'runs' / run.slug()
    try:
        request = run.request(
            export=str(folder / 'export'),
            report=str(folder / 'report') if run.report else None,
            progress=None,
        )
        out, _ = run_request(request)
        write_result(folder / 'result.yaml', out)
        row.update(row_of(out))
        row['status'], row['reason'] = Status.OK, ''
    except HandeyeError as err:
        row['status'], row['reason'] = Status.FAILED, str(err)
    except MemoryError:
        row['status'], row['reason'] = Status.ERROR, 'out of memory'
    except Exception as err:  # noqa: BLE001  (a bug: the table says so, the evaluation goes on)
        row['status'] = Status.ERROR
        row['reason'] = f'internal error: {type(err).__name__}: {err}'
    row['seconds'] = round(time.perf_counter() - t0, 3)
    row['pid'] = os.getpid()
    row['rss_mb'] = _rss_mb()
    return row


def rig_row(run: RunSpec, doc: ResultDoc | None, rig: RigDoc) -> Row:
    """A run's row of ``evaluate --shared-extrinsic``: its result at the rig's T_HE (its own
    when left out), and in ``rig`` its part in the rig (used, follows, left out: why)."""
    row: Row = {
        'name': run.name,
        'algorithm': run.algorithm,
        'sequence': run.sequence,
        'trial': run.trial,
    }
    left_out = rig['rig']['left_out']
    if doc:
        row.update(row_of(doc))
        row['status'], row['reason'] = Status.OK, ''
    else:
        row['status'], row['reason'] = Status.FAILED, left_out.get(run.name, '')
    from .rig_file import part_of

    row['rig'] = {
        'used': 'used',
        'follows': "follows (takes the rig's T_HE)",
        'left out': f'left out: {left_out.get(run.name, "")}',
    }[part_of(rig['rig'], run.name)]
    return row


def _rss_mb() -> float | None:
    """This process's resident memory now (MB; Linux), to see a worker's memory stay flat."""
    try:
        pages = int(Path('/proc/self/statm').read_text().split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return round(pages * os.sysconf('SC_PAGE_SIZE') / 2**20, 1)


def read_cached(cache: Path, key: str) -> Row | None:
    """The row cached under ``key``, or None."""
    try:
        return json.loads((cache / f'{key}.json').read_text())
    except (OSError, ValueError):
        return None


def write_cached(cache: Path, key: str, row: Row) -> None:
    """Cache a row atomically (a killed writer leaves no half file to be read back)."""
    cache.mkdir(parents=True, exist_ok=True)
    tmp = cache / f'.{key}.{os.getpid()}.tmp'
    tmp.write_text(json.dumps(row))
    os.replace(tmp, cache / f'{key}.json')
