"""Trajectory text files: TUM and EuRoC CSV.

- TUM: ``t x y z qx qy qz qw`` separated by spaces, ``t`` in seconds (decimal), optional ``#``
  comment lines. A first column of plain integers above 1e14 is read as nanoseconds, as some
  tools write it.
- EuRoC: CSV ``t[ns], x, y, z, qw, qx, qy, qz[, extra columns ignored]`` with a ``#`` header.
  The quaternion is stored ``w x y z`` in the file and converted to ``x y z w`` here, at the
  reader, so that nothing past this module sees the EuRoC order.

Stamps are parsed exactly into int64 nanoseconds: a TUM stamp such as ``1403636579.758555555``
is split at the decimal point rather than going through float64, which would round it to
~0.2 microseconds. ``stamp_unit`` says what the numbers count (default: the format's unit);
when the format's unit cannot hold the values in int64 nanoseconds (Unix milliseconds in a TUM
file, 1.4e12, would be year 45 000), the first of ms, us, ns that can is taken, and the
trajectory's notes say so; the pipeline then checks the rates (see
:mod:`handeye_ros.core.checks.conventions`). ``quaternion_order`` says in which order the file's four
quaternion columns are (default: the format's).

A stamp written twice keeps its *last* row (estimators that correct a pose, e.g. after a loop
closure, write the corrected one after the first), counted in the notes. Up to 1 % of rows no
pose stream can hold (a stamp that does not fit or is out of order with both neighbours, a
non-finite value, a non-unit quaternion) are dropped and named in the notes; a file with more
is refused, naming the first; an unsorted file is refused.
"""

from __future__ import annotations

import io
from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.trajectory import QUATERNION_NORM_TOLERANCE, Trajectory
from .bulk import SplitStamps, read_bulk

FORMATS = ('auto', 'tum', 'euroc')
#: Stamp units a file may use: nanoseconds per unit. 'Gs' is 1e9 s: Unix seconds divided by
#: 1e9, as some comparisons publish them (TUM-VI room1 estimates: ``1.520530308199e+00``).
STAMP_UNITS = {'Gs': 10**18, 's': 10**9, 'ms': 10**6, 'us': 10**3, 'ns': 1}
#: A TUM stream read in seconds with stamps closer than this (s) cannot be a pose stream (a
#: MHz rate); when its stamps read as 1e9 s are Unix times of these years, that is the unit.
DENSEST_PERIOD_S = 1e-6
UNIX_YEARS_S = (9.46e8, 4.1e9)  # 2000 to 2099
QUATERNION_ORDERS = ('auto', 'xyzw', 'wxyz')
#: Integer TUM stamps above this are nanoseconds (1e14 s would be three million years).
NANOSECOND_STAMP_THRESHOLD = 10**14
INT64_MAX = np.iinfo(np.int64).max
#: A file may hold up to this fraction of rows no pose stream can hold (a corrupt row, one
#: written with every value scaled): they are dropped, and the notes name them; more, and the
#: file is refused, naming the first.
MAX_BAD_ROW_FRACTION = 0.01


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
        numbers, values, split, fmt = _read_lines(path, data, fmt)
    del data
    t_ns, notes, fits = parse_stamps(path, numbers, split, fmt, stamp_unit)
    order = _quaternion_order(path, fmt, stamp_unit, quaternion_order, split, notes)
    # the file's four quaternion columns, in file order, to x y z w
    q_xyzw = values[:, 3:7][:, [1, 2, 3, 0] if order == 'wxyz' else [0, 1, 2, 3]]
    bad = _bad_rows(t_ns, values, q_xyzw, fits)
    if bad.any():
        if bad.sum() > MAX_BAD_ROW_FRACTION * bad.size:
            if not fits.all():  # refused with the stamp's own message
                _too_large(path, numbers, np.where(fits, 0, np.abs(t_ns)), 'as read')
        else:  # a few rows no pose stream holds: dropped, named (validation below refuses more)
            lines = ', '.join(str(numbers[k]) for k in np.flatnonzero(bad)[:5])
            notes.append(
                f'{path}: dropped {int(bad.sum())} row(s) no pose stream can hold '
                f'(a stamp out of range or order, a non-finite value or a non-unit '
                f'quaternion; line(s) {lines}{", ..." if bad.sum() > 5 else ""})'
            )
            keep = ~bad
            t_ns, values, q_xyzw = t_ns[keep], values[keep], q_xyzw[keep]
            numbers = np.asarray(numbers)[keep]
    keep = _last_of_repeated(t_ns)
    if not keep.all():
        notes.append(
            f'{path}: {int((~keep).sum())} stamp(s) written twice; the last row of each was kept'
        )
    return Trajectory.from_arrays(
        t_ns[keep], values[keep, :3], q_xyzw[keep], name=str(path), notes=tuple(notes)
    )


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


def _bad_rows(
    t_ns: np.ndarray, values: np.ndarray, q_xyzw: np.ndarray, fits: np.ndarray
) -> np.ndarray:
    """(N,) bool: rows no pose stream can hold: a stamp that does not fit int64 ns, a
    non-finite value, a quaternion whose norm is off by more than the tolerance, or a stamp
    out of order with both neighbours while they are in order (one wild stamp, not an unsorted
    file)."""
    finite = np.isfinite(values).all(axis=1)
    with np.errstate(invalid='ignore', over='ignore'):
        norm = np.linalg.norm(np.where(finite[:, None], q_xyzw, 0.0), axis=1)
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


def _last_of_repeated(t_ns: np.ndarray) -> np.ndarray:
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
    try:
        return path.read_bytes()
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


def _read_lines(
    path: Path, data: bytes, fmt: str
) -> tuple[list[int], np.ndarray, SplitStamps, str]:
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
    return numbers, values, _split_decimal(path, numbers, stamps), fmt


def _detect(path: Path, rows: list[str]) -> str:
    if not rows:
        msg = f'{path}: holds no poses (the file is empty or has only comments)'
        raise InputError(msg)
    first = rows[0]
    if ',' in first and len(first.split(',')) >= 8:
        return 'euroc'
    if ',' not in first and len(first.split()) == 8:
        return 'tum'
    msg = (
        f'{path}: unknown trajectory format (first data line: {first[:80]!r}); expected TUM '
        '"t x y z qx qy qz qw" separated by spaces or EuRoC CSV "t[ns],x,y,z,qw,qx,qy,qz,..."'
    )
    raise InputError(msg)


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
        for token in tokens[:8]:
            try:
                float(token)
            except ValueError:
                msg = f'{path}, line {number}: {token!r} is not a number'
                raise InputError(msg) from None


def parse_stamps(
    path: Path, numbers, split: SplitStamps, fmt: str, unit: str
) -> tuple[np.ndarray, list[str], np.ndarray]:
    """Exact int64 nanoseconds of a stamp column, notes on the unit assumed, and which rows'
    stamps fit int64 ns in that unit (the others are 0 here; the caller drops or refuses them).

    Each stamp is split into its whole and fractional digits (no float64 round trip). With
    ``unit`` 'auto': the format's unit (s for TUM, ns for EuRoC), plain TUM integers above
    NANOSECOND_STAMP_THRESHOLD as ns, EuRoC stamps with a fractional part as s; when that
    unit cannot hold the values in int64 ns, the first of ms, us, ns that can. The unit is
    chosen on the median stamp, so that one wild row cannot decide it for the file. Every
    unit other than the format's comes with a note.
    """
    whole, neg = split.whole, split.neg
    notes: list[str] = []
    if unit == 'auto':
        unit = 'ns' if fmt == 'euroc' else 's'
        fractional = split.fractional
        typical = int(np.median(whole)) if whole.size else 0
        if (
            fmt == 'tum'
            and not fractional.any()
            and whole.size
            and typical > NANOSECOND_STAMP_THRESHOLD
            and not neg.any()
        ):
            unit = 'ns'
        if fmt == 'tum' and _in_gigaseconds(split):
            unit = 'Gs'
            notes.append(
                f'{path}: the stamps ({typical}.{split.frac9[split.frac9.size // 2]:09d}...) '
                'are Unix seconds divided by 1e9 (as seconds they would be a pose every '
                'few picoseconds); read as units of 1e9 s'
            )
        if fmt == 'euroc' and fractional.mean() > 0.5:  # a fraction of a ns means nothing
            unit = 's'
            notes.append(
                f'{path}: the stamps have fractional parts, so they cannot be '
                'nanoseconds; read as seconds'
            )
        if typical > INT64_MAX // STAMP_UNITS[unit]:
            fits = [u for u in ('ms', 'us', 'ns') if typical <= INT64_MAX // STAMP_UNITS[u]]
            notes.append(
                f'{path}: stamps of {typical} cannot be '
                f'{"seconds" if unit == "s" else unit}; read as {fits[0]}'
            )
            unit = fits[0]
    scale = STAMP_UNITS[unit]
    ok = whole <= INT64_MAX // scale
    # billionths of the unit to ns (truncated below 1 ns); a unit above the second also takes
    # the next nine digits
    if scale > 10**9:
        frac_ns = split.frac9 * np.int64(scale // 10**9) + split.frac18 // (10**18 // scale)
    else:
        frac_ns = split.frac9 // np.int64(10**9 // scale)
    ns = np.where(ok, whole, 0) * np.int64(scale) + np.where(ok, frac_ns, 0)
    return np.where(neg, -ns, ns), notes, ok


def _in_gigaseconds(split: SplitStamps) -> bool:
    """Whether stamps read as seconds are a MHz stream that as units of 1e9 s are Unix times."""
    if split.whole.size < 3 or split.neg.any() or split.whole.max() > 9:
        return False
    as_s = split.whole * np.int64(10**9) + split.frac9
    step_s = float(np.median(np.diff(as_s))) * 1e-9
    typical_s = float(np.median(split.whole + split.frac9 * 1e-9)) * 1e9
    return 0.0 <= step_s < DENSEST_PERIOD_S and UNIX_YEARS_S[0] <= typical_s <= UNIX_YEARS_S[1]


def _too_large(path: Path, numbers: list[int], whole: np.ndarray, unit: str = 'ns') -> None:
    k = int(np.argmax(whole))
    msg = (
        f'{path}, line {numbers[k]}: a stamp ({unit}) is beyond what int64 nanoseconds can '
        'hold (2^63 ns, the year 2262); check the stamp column and its unit '
        '(--hand-stamp-unit / --eye-stamp-unit)'
    )
    raise InputError(msg)


def _split_of(whole: np.ndarray, frac: np.ndarray, neg: np.ndarray) -> SplitStamps:
    """SplitStamps of whole parts, fractional digit strings and signs."""
    frac = np.char.ljust(frac.astype(str), 18, '0')
    nine = frac.astype('U9')  # billionths of the unit
    rest = np.array([f[9:18] for f in frac.tolist()], dtype='U9')
    return SplitStamps(
        whole,
        nine.astype(np.int64),
        np.char.str_len(np.char.rstrip(frac, '0')) > 0,
        neg,
        rest.astype(np.int64),
    )


def _split_decimal(path: Path, numbers: list[int], col: np.ndarray) -> SplitStamps:
    """Decimal stamps (strings) split into whole parts, fractional digits and signs; exponent
    forms (1.4e9) go through Decimal."""
    body = np.char.lstrip(col, '-+')
    plain = np.char.isdigit(np.char.replace(body, '.', '', count=1)) & (np.char.str_len(body) > 0)
    if not plain.all():
        return _split_decimal_fallback(path, numbers, col)
    neg = np.char.startswith(col, '-')
    parts = np.char.partition(body, '.')
    whole_txt = np.where(parts[:, 0] == '', '0', parts[:, 0])
    digits = np.char.lstrip(whole_txt, '0')
    n = np.char.str_len(digits)
    # beyond int64: more than 19 digits, or 19 that compare above 2^63 - 1 (same length:
    # lexicographic order is numeric order)
    long = (n > 19) | ((n == 19) & (digits > str(INT64_MAX)))
    if long.any():
        k = int(np.flatnonzero(long)[0])
        msg = (
            f'{path}, line {numbers[k]}: stamp {col[k]!r} is beyond what int64 nanoseconds '
            'can hold (2^63 ns, the year 2262); check the stamp column and its unit'
        )
        raise InputError(msg)
    return _split_of(whole_txt.astype(np.int64), parts[:, 2], neg)


def _split_decimal_fallback(path: Path, numbers: list[int], col: np.ndarray) -> SplitStamps:
    whole = np.empty(col.size, dtype=np.int64)
    frac = np.empty(col.size, dtype=object)
    neg = np.zeros(col.size, dtype=bool)
    for k, token in enumerate(col):
        try:
            value = Decimal(str(token))
            if not value.is_finite():
                raise InvalidOperation
        except InvalidOperation:
            msg = f'{path}, line {numbers[k]}: stamp {token!r} is not a number'
            raise InputError(msg) from None
        neg[k] = value < 0
        whole_part = int(abs(value))
        if whole_part > INT64_MAX:
            msg = (
                f'{path}, line {numbers[k]}: stamp {token!r} is beyond what int64 '
                'nanoseconds can hold (2^63 ns, the year 2262); check the stamp column'
            )
            raise InputError(msg)
        whole[k] = whole_part
        text = format(abs(value) - whole_part, 'f')
        frac[k] = text.split('.', 1)[1].rstrip('0') if '.' in text else ''
    return _split_of(whole, frac, neg)
