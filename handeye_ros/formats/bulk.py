"""The common case of a trajectory text file, read in bulk from its bytes.

An hour of 1 kHz MoCap is 3.6 million lines (430 MB of TUM). Going line by line through Python
strings (a list of rows, a joined copy, a string array of stamps) took 31 s and 3.7 GB for it;
this reads the same file in about a third of the time and a fifth of the memory:

- the line index (where each line starts and ends, which are data) from the bytes with numpy;
- the stamp column split into whole and fractional digits straight from the bytes, exactly (no
  float64 round trip: a stamp of 1.4e9 s keeps its nanoseconds);
- the seven pose columns by numpy's C parser (``np.loadtxt``).

It takes only what it is sure of: lines that start with their first value, stamps of plain
decimal digits (an optional sign, at most one point, at most 18 whole digits). Anything else
(leading blanks, exponents, a stray byte, a row count the C parser disagrees with) returns None,
and :mod:`.text` reads the file line by line instead, which also names the line at fault.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.arrays import Bytes, Floats, Indices, Mask, Stamps

#: Longest stamp token (characters) read from the bytes; longer ones go line by line.
MAX_STAMP_CHARS = 40
#: Most whole digits read here: 18 always fit int64 (19 may not; the line-by-line path checks).
MAX_WHOLE_DIGITS = 18
_NL, _CR, _HASH, _DOT, _PLUS, _MINUS, _ZERO = 10, 13, 35, 46, 43, 45, 48
#: Bytes that end a stamp token: space, tab, comma, CR, and the end of the line (0 here).
_TOKEN_END = np.array([32, 9, 44, _CR, 0], dtype=np.uint8)
_BLANK_START = np.array([32, 9, 11, 12], dtype=np.uint8)


@dataclass(frozen=True)
class SplitStamps:
    """Decimal stamps split exactly: ``[-]whole.fraction`` in the file's unit.

    whole: (N,) int64; frac9: (N,) int64, the first nine fractional digits as billionths;
    fractional: (N,) bool, any non-zero fractional digit; neg: (N,) bool, a minus sign;
    frac18: (N,) int64, the next nine fractional digits (billionths of a billionth), which
    only a unit coarser than the second needs (stamps written in units of 1e9 s).
    """

    whole: Stamps
    frac9: Stamps
    fractional: Mask
    neg: Mask
    frac18: Stamps


@dataclass(frozen=True)
class BulkTable:
    """Data lines of a file: 1-based line numbers (N,), the first data line's text, the stamps
    and the seven pose columns (N, 7) as written (x y z and the four quaternion columns)."""

    numbers: Indices
    first_row: str
    stamps: SplitStamps
    values: Floats


def data_line_bounds(buf: Bytes) -> tuple[Indices, Indices, Indices] | None:
    """(1-based numbers, starts, ends) of the data lines of a file's bytes (not blank, not a
    ``#`` comment); None when a line starts with a blank (the line-by-line reader strips it)."""
    # newlines a block at a time: one comparison over 430 MB would make a 430 MB mask
    block = 1 << 24
    nl = np.concatenate(
        [np.flatnonzero(buf[k : k + block] == _NL) + k for k in range(0, buf.size, block)]
        or [np.zeros(0, np.intp)]
    )
    starts = np.concatenate(([0], nl + 1))
    ends = np.concatenate((nl, [buf.size]))
    first = np.where(starts < ends, buf[np.minimum(starts, buf.size - 1)], _NL)
    if np.isin(first, _BLANK_START).any():
        return None
    data = np.flatnonzero(~np.isin(first, (_HASH, _NL, _CR)))
    return data + 1, starts[data], ends[data]


def split_stamps(buf: Bytes, starts: Indices, ends: Indices) -> SplitStamps | None:
    """The first token of each line, split into whole and fractional digits; None when any is
    not a plain decimal (see the module docstring).

    A writer formats its stamps alike, so the tokens come in a few layouts (sign, point and
    length; a format that strips trailing zeros gives up to ten): each layout is read at once
    for all lines that have it, a column of digits at a time.
    """
    out = SplitStamps(
        np.zeros(starts.size, np.int64),
        np.zeros(starts.size, np.int64),
        np.zeros(starts.size, bool),
        np.zeros(starts.size, bool),
        np.zeros(starts.size, np.int64),
    )
    todo = np.arange(starts.size)
    for _ in range(MAX_LAYOUTS):
        if not todo.size:
            return out
        layout = _layout(buf, int(starts[todo[0]]), int(ends[todo[0]]))
        if layout is None:
            return None
        fits = _read_layout(buf, (starts[todo], ends[todo]), layout, out, todo)
        todo = todo[~fits]
    return None if todo.size else out


#: Lines whose stamp bytes are gathered at once.
CHUNK_LINES = 1 << 16
#: Most stamp layouts read in bulk; a file with more is read line by line.
MAX_LAYOUTS = 24
_POW10 = 10 ** np.arange(19, dtype=np.int64)


def _layout(buf: Bytes, start: int, end: int) -> tuple[int, int, int] | None:
    """(sign characters 0/1, position of the point (= length without one), length) of the
    stamp token of one line; None unless it is a plain decimal."""
    line = bytes(buf[start : min(end, start + MAX_STAMP_CHARS + 1)])
    length = next((k for k, c in enumerate(line) if c in _TOKEN_END), len(line))
    token = line[:length]
    sign = int(token[:1] in (b'+', b'-'))
    body = token[sign:]
    dot = body.find(b'.')
    digits = body.replace(b'.', b'', 1)
    if (
        not digits
        or not digits.isdigit()
        or length > MAX_STAMP_CHARS
        or (dot if dot >= 0 else len(body)) > MAX_WHOLE_DIGITS
    ):
        return None
    return sign, sign + (dot if dot >= 0 else len(body)), length


def _read_layout(
    buf: Bytes,
    lines: tuple[Indices, Indices],
    layout: tuple[int, int, int],
    out: SplitStamps,
    rows: Indices,
) -> Mask:
    """Read the stamps of the lines (their (starts, ends) in ``buf``) that have this layout
    (sign, point, length: :func:`_layout`) into ``out`` (at ``rows``); returns which lines had
    it."""
    (starts, ends), (sign, dot, length) = lines, layout
    fits = ends - starts > length  # a stamp is followed by the other columns
    at = starts[fits]
    parts = [
        _layout_block(buf, at[k : k + CHUNK_LINES], sign, dot, length)
        for k in range(0, at.size, CHUNK_LINES)
    ]
    if not parts:
        return fits
    ok, whole, frac9, fractional, neg, frac18 = (
        np.concatenate(p) for p in zip(*parts, strict=True)
    )
    fits[fits] = ok
    mine = rows[fits]
    out.whole[mine], out.frac9[mine], out.fractional[mine] = whole[ok], frac9[ok], fractional[ok]
    out.neg[mine], out.frac18[mine] = neg[ok], frac18[ok]
    return fits


def _layout_block(
    buf: Bytes, at: Indices, sign: int, dot: int, length: int
) -> tuple[Mask, Stamps, Stamps, Mask, Mask, Stamps]:
    """(fits, whole, frac9, fractional, neg, frac18) of the stamps starting at ``at`` read with one
    layout: a block of lines at a time, so that every column is read from cache."""
    chars = buf[at[:, None] + np.arange(length + 1)]
    ok = np.isin(chars[:, length], _TOKEN_END)
    if sign:
        ok &= np.isin(chars[:, 0], (_PLUS, _MINUS))
    whole = np.zeros(at.size, np.int64)
    frac9 = np.zeros(at.size, np.int64)
    frac18 = np.zeros(at.size, np.int64)
    fractional = np.zeros(at.size, bool)
    for w in range(sign, length):
        c = chars[:, w]
        if w == dot:
            ok &= c == _DOT
            continue
        byte_digit = c - np.uint8(_ZERO)
        ok &= byte_digit <= 9  # the uint8 difference wraps above 9 for every other byte
        # int64 before any product: numpy 1.x casts by value, so uint8 * int64(100) stayed
        # uint8 there and wrapped at 256 (whole seconds 256, 512 or 768 s off)
        digit = byte_digit.astype(np.int64)
        if w < dot:
            whole += digit * _POW10[dot - 1 - w]
        else:
            k = w - dot - 1
            if k < 9:
                frac9 += digit * _POW10[8 - k]
            elif k < 18:
                frac18 += digit * _POW10[17 - k]
            fractional |= digit != 0
    neg = chars[:, 0] == _MINUS if sign else np.zeros(at.size, bool)
    return ok, whole, frac9, fractional, neg, frac18


def read_bulk(
    path: Path, data: bytes, fmt_of_first_row: Callable[[int, str], tuple[str, str | None]]
) -> tuple[str, BulkTable] | None:
    """(format, table) of a file's bytes, or None for the line-by-line reader.

    ``fmt_of_first_row(line number, first_row) -> (format, delimiter)`` decides the format (and
    checks the first row's columns) from the first data line, as the line-by-line reader does.
    """
    buf = np.frombuffer(data, np.uint8)
    bounds = data_line_bounds(buf) if buf.size else None
    if bounds is None or not bounds[0].size:
        return None
    numbers, starts, ends = bounds
    first_row = data[starts[0] : ends[0]].decode('utf-8', 'replace').strip()
    fmt, delimiter = fmt_of_first_row(int(numbers[0]), first_row)
    stamps = split_stamps(buf, starts, ends)
    if stamps is None:
        return None
    del buf
    try:
        with warnings.catch_warnings():
            warnings.simplefilter('ignore')  # an empty result is caught below
            values = np.loadtxt(
                path,
                delimiter=delimiter,
                usecols=range(1, 8),
                ndmin=2,
                comments='#',
                encoding='utf-8',
            )
    except (ValueError, UnicodeError):
        return None
    if values.shape[0] != numbers.size:
        return None
    return fmt, BulkTable(numbers, first_row, stamps, values)
