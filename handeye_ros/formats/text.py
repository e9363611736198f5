"""Trajectory text files: TUM and EuRoC CSV.

- TUM: ``t x y z qx qy qz qw`` separated by spaces, ``t`` in seconds (decimal), optional ``#``
  comment lines. A first column of plain integers above 1e14 is read as nanoseconds, as some
  tools write it.
- EuRoC: CSV ``t[ns], x, y, z, qw, qx, qy, qz[, extra columns ignored]`` with a ``#`` header.
  The quaternion is stored ``w x y z`` in the file and converted to ``x y z w`` here, at the
  reader, so that nothing past this module sees the EuRoC order.

Stamps are parsed exactly into int64 nanoseconds (:mod:`.stamps`): a TUM stamp such as ``1403636579.758555555``
is split at the decimal point rather than going through float64, which would round it to
~0.2 microseconds. ``stamp_unit`` says what the numbers count (default: the format's unit);
when the format's unit cannot hold the values in int64 nanoseconds (Unix milliseconds in a TUM
file, 1.4e12, would be year 45 000), the first of ms, us, ns that can is taken, and the
trajectory's notes say so; the pipeline then checks the rates (see
:mod:`handeye_ros.core.checks.conventions`). ``quaternion_order`` says in which order the
file's four quaternion columns are (default: the format's).

A stamp written twice keeps its *last* row (estimators that correct a pose, e.g. after a loop
closure, write the corrected one after the first), counted in the notes; a file in which a tenth
of the rows repeat a stamp is refused (stamps with too few digits). Up to 1 % of rows no
pose stream can hold (a stamp that does not fit or is out of order with both neighbours, a
non-finite value, a non-unit quaternion) are dropped and named in the notes; a file with more
is refused, naming the first; an unsorted file is refused.
"""

from __future__ import annotations

import codecs
import io
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..core.arrays import Floats, Indices, Mask, Stamps
from ..core.errors import InputError
from ..core.geometry import row_norms
from ..core.trajectory import QUATERNION_NORM_TOLERANCE, Trajectory, quaternion_columns
from .bulk import SplitStamps, read_bulk
from .stamps import STAMP_UNITS, parse_stamps, split_decimal, too_large

FORMATS = ('auto', 'tum', 'euroc')
#: The orders of a file's four quaternion numbers read: TUM's, EuRoC's, and the two others of
#: the same cycle (``yzwx``: what Eigen's ``Quaterniond(x, y, z, w)``, whose constructor takes w
#: first, writes through ``coeffs()``).
QUATERNION_ORDERS = ('auto', 'xyzw', 'wxyz', 'yzwx', 'zwxy')
#: A file may hold up to this fraction of rows no pose stream can hold (a corrupt row, one
#: written with every value scaled): they are dropped, and the notes name them; more, and the
#: file is refused, naming the first.
MAX_BAD_ROW_FRACTION = 0.01
#: A file in which more than this fraction of rows repeat the stamp of the row before is refused:
#: a correction rewrites a few poses, while stamps that cannot tell a tenth of the poses apart
#: were written with too few digits (``1.7e+09`` from a 6-digit default, float32 seconds).
MAX_REPEATED_FRACTION = 0.1


def detect_format(path: str | Path) -> str:
    """'tum' or 'euroc' from the first data line of a file (commas mean EuRoC CSV)."""
    _, rows = _data_lines(Path(path))
    return _detect(Path(path), rows)


def read_trajectory(
    path: str | Path, fmt: str = 'auto', stamp_unit: str = 'auto', quaternion_order: str = 'auto'
) -> Trajectory:
    """Read and validate a TUM or EuRoC trajectory file.

    ``stamp_unit``: 'auto' (the format's: s for TUM, ns for EuRoC) or one of
    :data:`STAMP_UNITS`; ``quaternion_order``: 'auto' (the format's: x y z w for TUM, w x y z
    for EuRoC) or the order of the file's quaternion columns.

    Raises
    ------
    InputError
        Naming the file (and line) for: a missing or unreadable file, an unknown format, a line
        with the wrong number of columns or a non-numeric value, a stamp no int64 nanosecond
        count can hold, and every problem :meth:`Trajectory.from_arrays` checks (too few poses,
        unsorted stamps, NaN, quaternions).
    """
    path = Path(path)
    _check_choices(path, fmt, stamp_unit, quaternion_order)
    data = _read_bytes(path)

    def format_of(number: int, first_row: str) -> tuple[str, str | None]:
        chosen = _detect(path, [first_row]) if fmt == 'auto' else fmt
        sep = ',' if chosen == 'euroc' else None
        _check_columns(path, [number], [first_row], sep, chosen)
        return chosen, sep

    bulk = read_bulk(path, data, format_of)
    if bulk is not None:
        fmt, table = bulk
        numbers, values, split = table.numbers, table.values, table.stamps
    else:
        lines, values, split, fmt = _read_lines(path, data, fmt)
        numbers = np.asarray(lines)
    del data
    t_ns, notes, fits = parse_stamps(path, numbers, split, fmt, stamp_unit)
    order = _quaternion_order(path, fmt, stamp_unit, quaternion_order, split, notes)
    # the file's four quaternion columns, in file order, to x y z w (a view when they are;
    # from_arrays makes the normalised copy)
    q_xyzw = values[:, 3:7] if order == 'xyzw' else values[:, 3:7][:, quaternion_columns(order)]
    (t_ns, values, q_xyzw), dropped = _drop_bad_rows(path, numbers, (t_ns, values, q_xyzw), fits)
    notes += [dropped] if dropped else []
    keep = _last_of_repeated(t_ns)
    _check_repeated(path, keep, t_ns)
    if not keep.all():  # (no copies of millions of rows when every stamp is once)
        notes.append(
            f'{path}: {int((~keep).sum())} stamp(s) written twice; the last row of each was kept'
        )
        t_ns, values, q_xyzw = t_ns[keep], values[keep], q_xyzw[keep]
    traj = Trajectory.from_arrays(
        t_ns, np.ascontiguousarray(values[:, :3]), q_xyzw, name=str(path), notes=tuple(notes)
    )
    return replace(traj, quaternion_order=order)


def _drop_bad_rows(
    path: Path,
    numbers: Indices,
    rows: tuple[Stamps, Floats, Floats],
    fits: Mask,
) -> tuple[tuple[Stamps, Floats, Floats], str]:
    """The rows (stamps ns, values, x y z w quaternions) without those no pose stream holds
    (:func:`_bad_rows`), and a note naming them (line ``numbers``), when they are at most
    MAX_BAD_ROW_FRACTION; with more, all rows (the validation refuses them), except that a
    stamp int64 ns cannot hold is refused here with its own message."""
    t_ns, values, q_xyzw = rows
    bad = _bad_rows(t_ns, values, q_xyzw, fits)
    if not bad.any():
        return rows, ''
    if bad.sum() > MAX_BAD_ROW_FRACTION * bad.size:
        if not fits.all():
            too_large(path, numbers, np.where(fits, 0, np.abs(t_ns)), 'as read')
        return rows, ''
    lines = ', '.join(str(numbers[k]) for k in np.flatnonzero(bad)[:5])
    note = (
        f'{path}: dropped {int(bad.sum())} row(s) no pose stream can hold '
        f'(a stamp out of range or order, a non-finite value or a non-unit '
        f'quaternion; line(s) {lines}{", ..." if bad.sum() > 5 else ""})'
    )
    keep = ~bad
    return (t_ns[keep], values[keep], q_xyzw[keep]), note


def _check_choices(path: Path, fmt: str, stamp_unit: str, quaternion_order: str) -> None:
    """InputError naming the file for a format, stamp unit or quaternion order we do not know."""
    if fmt not in FORMATS:
        msg = f'{path}: unknown format {fmt!r}; use one of {", ".join(FORMATS)}'
        raise InputError(msg)
    if stamp_unit != 'auto' and stamp_unit not in STAMP_UNITS:
        msg = f'{path}: unknown stamp unit {stamp_unit!r}; use auto, {", ".join(STAMP_UNITS)}'
        raise InputError(msg)
    if quaternion_order not in QUATERNION_ORDERS:
        msg = (
            f'{path}: unknown quaternion order {quaternion_order!r}; use '
            f'{", ".join(QUATERNION_ORDERS)}'
        )
        raise InputError(msg)


def _quaternion_order(
    path: Path, fmt: str, stamp_unit: str, given: str, split: SplitStamps, notes: list[str]
) -> str:
    """The order of the file's quaternion columns: the one given, else the format's; a
    comma-separated file stamped in seconds is read in TUM's order, with a note."""
    if given != 'auto':
        return given
    if fmt == 'euroc' and stamp_unit == 'auto' and split.fractional.mean() > 0.5:
        # EuRoC's own files stamp in integer ns; a CSV in seconds comes from scripts and tools
        # (the ETH hand-eye tools' t, x, y, z, qx, qy, qz, qw) that keep TUM's order
        notes.append(
            f'{path}: a comma-separated file stamped in seconds (EuRoC stamps in integer '
            'nanoseconds): read as t, x, y, z, qx, qy, qz, qw (TUM order); if its '
            'quaternion is w x y z, say so with --hand/eye-quaternion-order wxyz'
        )
        return 'xyzw'
    return 'wxyz' if fmt == 'euroc' else 'xyzw'


def _bad_rows(t_ns: Stamps, values: Floats, q_xyzw: Floats, fits: Mask) -> Mask:
    """(N,) bool: rows no pose stream can hold: a stamp that does not fit int64 ns, a
    non-finite value, a quaternion whose norm is off by more than the tolerance, or a stamp
    out of order with both neighbours while they are in order (one wild stamp, not an unsorted
    file)."""
    each = np.isfinite(values)
    finite: Mask = np.ones(len(values), bool)
    if not each.all():  # (no per-row reduction of a clean file's millions of rows)
        finite = np.all(each, axis=1)
    with np.errstate(invalid='ignore', over='ignore'):
        norm = row_norms(np.where(finite[:, None], q_xyzw, 0.0))
    bad = ~fits | ~finite | (np.abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE)
    good = np.flatnonzero(~bad)
    if good.size >= 3:
        t = t_ns[good]
        prev = np.concatenate(([np.iinfo(np.int64).min], t[:-1]))
        nxt = np.concatenate((t[1:], [np.iinfo(np.int64).max]))
        prev2 = np.concatenate(([np.iinfo(np.int64).min] * 2, t[:-2]))
        nxt2 = np.concatenate((t[2:], [np.iinfo(np.int64).max] * 2))
        # k is out of order while k-1 and k+1 are in order with each other (or, at the ends,
        # with the next ones); an equal stamp is a repeat, kept-last below, not disorder
        out = ((t > nxt) | (t < prev)) & (prev < nxt)
        out[0] = t[0] > t[1] and t[1] < nxt2[0]
        out[-1] = t[-1] < t[-2] and prev2[-1] < t[-2]
        bad[good[out]] = True
    return bad


def _check_repeated(path: Path, keep: Mask, t_ns: Stamps) -> None:
    """Refuse a file whose rows repeat their stamps beyond MAX_REPEATED_FRACTION."""
    repeated = int(keep.size - keep.sum())
    if repeated > MAX_REPEATED_FRACTION * keep.size:
        sec, ns = divmod(int(t_ns[0]), 10**9)
        msg = (
            f'{path}: {repeated} of {keep.size} rows repeat the stamp of the row before '
            f'({keep.sum()} distinct, the first {sec}.{ns:09d} s): the stamps were written '
            'with too few digits (a default 6-digit format prints 1.7e+09; float32 seconds keep '
            '128 s at 1.7e9), or the file holds more than one pose an instant. Write them to '
            'the microsecond or finer'
        )
        raise InputError(msg)


def _last_of_repeated(t_ns: Stamps) -> Mask:
    """(N,) bool: every row but those followed by a row with the same stamp."""
    return np.concatenate((t_ns[1:] != t_ns[:-1], [True]))


def write_tum(path: str | Path, traj: Trajectory) -> None:
    """Write a TUM file with exact nanosecond stamps (``seconds.nanoseconds``)."""
    sec, nsec = np.divmod(traj.t_ns, 1_000_000_000)
    with Path(path).open('w') as f:
        f.write('# timestamp[s] tx ty tz qx qy qz qw\n')
        f.writelines(
            f'{s}.{ns:09d} {p[0]:.9f} {p[1]:.9f} {p[2]:.9f} '
            f'{q[0]:.12f} {q[1]:.12f} {q[2]:.12f} {q[3]:.12f}\n'
            for s, ns, p, q in zip(sec, nsec, traj.p_xyz, traj.q_xyzw, strict=True)
        )


def write_euroc(path: str | Path, traj: Trajectory) -> None:
    """Write a EuRoC ground-truth style CSV (quaternion ``w x y z``)."""
    with Path(path).open('w') as f:
        f.write('#timestamp [ns],p_x [m],p_y [m],p_z [m],q_w [],q_x [],q_y [],q_z []\n')
        f.writelines(
            f'{t},{p[0]:.9f},{p[1]:.9f},{p[2]:.9f},'
            f'{q[3]:.12f},{q[0]:.12f},{q[1]:.12f},{q[2]:.12f}\n'
            for t, p, q in zip(traj.t_ns, traj.p_xyz, traj.q_xyzw, strict=True)
        )


def _read_bytes(path: Path) -> bytes:
    """The file's bytes, less the byte-order mark some Windows tools start UTF-8 text with."""
    try:
        return path.read_bytes().removeprefix(codecs.BOM_UTF8)
    except FileNotFoundError:
        raise InputError(f'{path}: no such file') from None
    except IsADirectoryError:
        raise InputError(f'{path}: is a directory, expected a trajectory file') from None
    except OSError as err:
        raise InputError(f'{path}: cannot be read ({err.strerror})') from None


def _data_lines(path: Path, data: bytes | None = None) -> tuple[list[int], list[str]]:
    """(1-based line numbers, contents) of the non-blank, non-comment lines."""
    text = (_read_bytes(path) if data is None else data).decode('utf-8', errors='replace')
    numbers, rows = [], []
    for k, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if s and not s.startswith('#'):
            numbers.append(k)
            rows.append(s)
    return numbers, rows


def _read_lines(path: Path, data: bytes, fmt: str) -> tuple[list[int], Floats, SplitStamps, str]:
    """The file line by line (what :mod:`.bulk` leaves): (line numbers, the seven pose columns,
    the split stamps, the format), or an InputError naming the line at fault."""
    numbers, rows = _data_lines(path, data)
    if not rows:
        msg = f'{path}: holds no poses (the file is empty or has only comments)'
        raise InputError(msg)
    fmt = _detect(path, rows) if fmt == 'auto' else fmt
    sep = ',' if fmt == 'euroc' else None
    _check_columns(path, numbers[:1], rows[:1], sep, fmt)
    text = '\n'.join(rows)
    try:  # numpy's C parser; the slow line-by-line diagnosis runs only when it fails
        values = np.loadtxt(io.StringIO(text), delimiter=sep, usecols=range(1, 8), ndmin=2)
        stamps = np.char.strip(
            np.loadtxt(io.StringIO(text), delimiter=sep, usecols=0, dtype=str, ndmin=1)
        )
    except ValueError as err:
        _diagnose(path, numbers, rows, sep, fmt)
        raise InputError(f'{path}: cannot be parsed as {fmt.upper()}: {err}') from None
    return numbers, values, split_decimal(path, numbers, stamps), fmt


def _detect(path: Path, rows: list[str]) -> str:
    if not rows:
        msg = f'{path}: holds no poses (the file is empty or has only comments)'
        raise InputError(msg)
    first = rows[0]
    if ',' in first and len(first.split(',')) >= 8:
        return 'euroc'
    if ',' not in first and len(first.split()) == 8:
        return 'tum'
    packed = _compressed(path)
    if packed:
        raise InputError(f'{path}: a {packed} archive, not a trajectory file: unpack it first')
    msg = (
        f'{path}: unknown trajectory format (first data line: {first[:80]!r}); expected TUM '
        '"t x y z qx qy qz qw" separated by spaces or EuRoC CSV "t[ns],x,y,z,qw,qx,qy,qz,..."'
    )
    raise InputError(msg)


#: The first bytes of the archives a trajectory file is shipped in.
ARCHIVES = {
    b'\x1f\x8b': 'gzip',
    b'PK\x03\x04': 'zip',
    b'BZh': 'bzip2',
    b'\xfd7zXZ': 'xz',
    b'\x28\xb5\x2f\xfd': 'zstd',
}


def _compressed(path: Path) -> str:
    """The archive format ``path`` starts like ('' for none, or a file that cannot be read)."""
    try:
        with path.open('rb') as f:
            head = f.read(8)
    except OSError:
        return ''
    return next((name for magic, name in ARCHIVES.items() if head.startswith(magic)), '')


def _check_columns(
    path: Path, numbers: list[int], rows: list[str], sep: str | None, fmt: str
) -> None:
    """Refuse the first line with too few columns (or, for TUM, a count other than 8)."""
    want = 8
    for number, row in zip(numbers, rows, strict=True):
        n = len(row.split(sep))
        if n < want or (fmt == 'tum' and n != want):
            msg = (
                f'{path}, line {number}: {n} columns; a {fmt.upper()} line has '
                f'{"exactly" if fmt == "tum" else "at least"} {want} '
                f'({"t x y z qx qy qz qw" if fmt == "tum" else "t[ns],x,y,z,qw,qx,qy,qz"})'
            )
            raise InputError(msg)


def _number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _diagnose(path: Path, numbers: list[int], rows: list[str], sep: str | None, fmt: str) -> None:
    """Find the first malformed line and raise an InputError naming it."""
    _check_columns(path, numbers, rows, sep, fmt)
    first = len(rows[0].split(sep))
    for number, row in zip(numbers, rows, strict=True):
        tokens = [t.strip() for t in row.split(sep)]
        if len(tokens) != first:
            msg = (
                f'{path}, line {number}: {len(tokens)} columns where the first data line '
                f'has {first}'
            )
            raise InputError(msg)
        bad = next((t for t in tokens[:8] if not _number(t)), None)
        if bad is not None:
            # words on the first data line are a header row without its comment mark
            header = number == numbers[0] and not any(_number(t) for t in tokens)
            hint = ' (a header row? start it with #, as comments are)' if header else ''
            raise InputError(f'{path}, line {number}: {bad!r} is not a number{hint}')
