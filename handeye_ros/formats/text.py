"""Trajectory text files: TUM and EuRoC CSV.

- TUM: ``t x y z qx qy qz qw`` separated by spaces, ``t`` in seconds (decimal), optional ``#``
  comment lines. A first column of plain integers above 1e14 is read as nanoseconds, as some
  tools write it.
- EuRoC: CSV ``t[ns], x, y, z, qw, qx, qy, qz[, extra columns ignored]`` with a ``#`` header.
  The quaternion is stored ``w x y z`` in the file and converted to ``x y z w`` here, at the
  reader, so that nothing past this module sees the EuRoC order.

Stamps are parsed exactly into int64 nanoseconds: a TUM stamp such as ``1403636579.758555555``
is split at the decimal point rather than going through float64, which would round it to
~0.2 microseconds.
"""

from __future__ import annotations

import io
from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.trajectory import Trajectory

FORMATS = ('auto', 'tum', 'euroc')
#: Integer TUM stamps above this are nanoseconds (1e14 s would be three million years).
NANOSECOND_STAMP_THRESHOLD = 10 ** 14


def detect_format(path: str | Path) -> str:
    """'tum' or 'euroc' from the first data line of a file (commas mean EuRoC CSV)."""
    _, rows = _data_lines(Path(path))
    return _detect(Path(path), rows)


def read_trajectory(path: str | Path, fmt: str = 'auto') -> Trajectory:
    """Read and validate a TUM or EuRoC trajectory file.

    Raises
    ------
    InputError
        Naming the file (and line) for: a missing or unreadable file, an unknown format, a line
        with the wrong number of columns or a non-numeric value, and every problem
        :meth:`Trajectory.from_arrays` checks (too few poses, unsorted stamps, NaN, quaternions).
    """
    path = Path(path)
    if fmt not in FORMATS:
        msg = f'{path}: unknown format {fmt!r}; use one of {", ".join(FORMATS)}'
        raise InputError(msg)
    numbers, rows = _data_lines(path)
    if not rows:
        msg = f'{path}: holds no poses (the file is empty or has only comments)'
        raise InputError(msg)
    fmt = _detect(path, rows) if fmt == 'auto' else fmt
    sep = ',' if fmt == 'euroc' else None
    _check_columns(path, numbers[:1], rows[:1], sep, fmt)
    text = '\n'.join(rows)
    try:  # numpy's C parser; the slow line-by-line diagnosis runs only when it fails
        values = np.loadtxt(io.StringIO(text), delimiter=sep, usecols=range(1, 8), ndmin=2)
        stamps = np.char.strip(np.loadtxt(io.StringIO(text), delimiter=sep, usecols=0,
                                          dtype=str, ndmin=1))
    except ValueError as err:
        _diagnose(path, numbers, rows, sep, fmt)
        raise InputError(f'{path}: cannot be parsed as {fmt.upper()}: {err}') from None
    if fmt == 'euroc':
        t_ns = _integer_stamps(path, numbers, stamps)
        q_xyzw = values[:, [4, 5, 6, 3]]
    else:
        t_ns = _decimal_seconds_to_ns(path, numbers, stamps)
        q_xyzw = values[:, 3:7]
    return Trajectory.from_arrays(t_ns, values[:, :3], q_xyzw, name=str(path))


def write_tum(path: str | Path, traj: Trajectory) -> None:
    """Write a TUM file with exact nanosecond stamps (``seconds.nanoseconds``)."""
    sec, nsec = np.divmod(traj.t_ns, 1_000_000_000)
    with Path(path).open('w') as f:
        f.write('# timestamp[s] tx ty tz qx qy qz qw\n')
        for s, ns, p, q in zip(sec, nsec, traj.p_xyz, traj.q_xyzw, strict=True):
            f.write(f'{s}.{ns:09d} {p[0]:.9f} {p[1]:.9f} {p[2]:.9f} '
                    f'{q[0]:.12f} {q[1]:.12f} {q[2]:.12f} {q[3]:.12f}\n')


def write_euroc(path: str | Path, traj: Trajectory) -> None:
    """Write a EuRoC ground-truth style CSV (quaternion ``w x y z``)."""
    with Path(path).open('w') as f:
        f.write('#timestamp [ns],p_x [m],p_y [m],p_z [m],q_w [],q_x [],q_y [],q_z []\n')
        for t, p, q in zip(traj.t_ns, traj.p_xyz, traj.q_xyzw, strict=True):
            f.write(f'{t},{p[0]:.9f},{p[1]:.9f},{p[2]:.9f},'
                    f'{q[3]:.12f},{q[0]:.12f},{q[1]:.12f},{q[2]:.12f}\n')


def _data_lines(path: Path) -> tuple[list[int], list[str]]:
    """(1-based line numbers, contents) of the non-blank, non-comment lines."""
    try:
        text = path.read_text(encoding='utf-8', errors='replace')
    except FileNotFoundError:
        raise InputError(f'{path}: no such file') from None
    except IsADirectoryError:
        raise InputError(f'{path}: is a directory, expected a trajectory file') from None
    except OSError as err:
        raise InputError(f'{path}: cannot be read ({err.strerror})') from None
    numbers, rows = [], []
    for k, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if s and not s.startswith('#'):
            numbers.append(k)
            rows.append(s)
    return numbers, rows


def _detect(path: Path, rows: list[str]) -> str:
    if not rows:
        msg = f'{path}: holds no poses (the file is empty or has only comments)'
        raise InputError(msg)
    first = rows[0]
    if ',' in first and len(first.split(',')) >= 8:
        return 'euroc'
    if ',' not in first and len(first.split()) == 8:
        return 'tum'
    msg = (f'{path}: unknown trajectory format (first data line: {first[:80]!r}); expected TUM '
           '"t x y z qx qy qz qw" separated by spaces or EuRoC CSV "t[ns],x,y,z,qw,qx,qy,qz,..."')
    raise InputError(msg)


def _check_columns(path: Path, numbers: list[int], rows: list[str], sep: str | None,
                   fmt: str) -> None:
    """Refuse the first line with too few columns (or, for TUM, a count other than 8)."""
    want = 8
    for number, row in zip(numbers, rows, strict=True):
        n = len(row.split(sep))
        if n < want or (fmt == 'tum' and n != want):
            msg = (f'{path}, line {number}: {n} columns; a {fmt.upper()} line has '
                   f'{"exactly" if fmt == "tum" else "at least"} {want} '
                   f'({"t x y z qx qy qz qw" if fmt == "tum" else "t[ns],x,y,z,qw,qx,qy,qz"})')
            raise InputError(msg)


def _diagnose(path: Path, numbers: list[int], rows: list[str], sep: str | None,
              fmt: str) -> None:
    """Find the first malformed line and raise an InputError naming it."""
    _check_columns(path, numbers, rows, sep, fmt)
    first = len(rows[0].split(sep))
    for number, row in zip(numbers, rows, strict=True):
        tokens = [t.strip() for t in row.split(sep)]
        if len(tokens) != first:
            msg = (f'{path}, line {number}: {len(tokens)} columns where the first data line '
                   f'has {first}')
            raise InputError(msg)
        for token in tokens[:8]:
            try:
                float(token)
            except ValueError:
                msg = f'{path}, line {number}: {token!r} is not a number'
                raise InputError(msg) from None


def _integer_stamps(path: Path, numbers: list[int], col: np.ndarray) -> np.ndarray:
    ok = np.char.isdigit(np.char.lstrip(col, '-'))
    if not ok.all():
        k = int(np.flatnonzero(~ok)[0])
        msg = (f'{path}, line {numbers[k]}: stamp {col[k]!r} is not an integer number of '
               'nanoseconds, as EuRoC CSV requires')
        raise InputError(msg)
    return col.astype(np.int64)


def _decimal_seconds_to_ns(path: Path, numbers: list[int], col: np.ndarray) -> np.ndarray:
    """Exact decimal seconds -> int64 ns (vectorised; a Decimal fallback for exponents)."""
    plain = np.char.isdigit(np.char.replace(np.char.lstrip(col, '-+'), '.', '', count=1))
    if not plain.all():
        return _decimal_fallback(path, numbers, col)
    if '.' not in ''.join(col[:1000]) and np.all(np.char.find(col, '.') < 0):
        ints = col.astype(np.int64)
        if ints.size and np.abs(ints).min() > NANOSECOND_STAMP_THRESHOLD:
            return ints
    neg = np.char.startswith(col, '-')
    parts = np.char.partition(np.char.lstrip(col, '-+'), '.')
    whole = np.where(parts[:, 0] == '', '0', parts[:, 0]).astype(np.int64)
    frac = np.char.ljust(parts[:, 2], 9, '0').astype('U9')
    frac = np.where(frac == '', '0', frac).astype(np.int64)
    ns = whole * 1_000_000_000 + frac
    return np.where(neg, -ns, ns)


def _decimal_fallback(path: Path, numbers: list[int], col: np.ndarray) -> np.ndarray:
    out = np.empty(col.size, dtype=np.int64)
    for k, token in enumerate(col):
        try:
            value = Decimal(str(token)) * 1_000_000_000
            if not value.is_finite():
                raise InvalidOperation
        except InvalidOperation:
            msg = f'{path}, line {numbers[k]}: stamp {token!r} is not a number of seconds'
            raise InputError(msg) from None
        out[k] = int(value.to_integral_value())
    return out
