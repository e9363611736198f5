"""A trajectory file's stamp column to exact int64 nanoseconds, and the unit it is in.

The stamps come split into whole and fractional digits (:class:`.bulk.SplitStamps`: from the
bytes in bulk, or from the strings of the line-by-line reader here), never through float64,
which would round a stamp of 1.4e9 s to ~0.2 microseconds. The unit is the format's unless the
values say otherwise (see :func:`parse_stamps`).
"""

from __future__ import annotations

from decimal import Decimal, InvalidOperation
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..core.arrays import Indices, Mask, Stamps
from ..core.errors import InputError
from .bulk import SplitStamps

#: A column of a file as text (a stamp per row); digit strings, or Decimal's as objects.
Text = npt.NDArray[np.str_]

#: Stamp units a file may use: nanoseconds per unit. 'Gs' is 1e9 s: Unix seconds divided by
#: 1e9, as some comparisons publish them (TUM-VI room1 estimates: ``1.520530308199e+00``).
STAMP_UNITS = {'Gs': 10**18, 's': 10**9, 'ms': 10**6, 'us': 10**3, 'ns': 1}
#: A TUM stream read in seconds with stamps closer than this (s) cannot be a pose stream (a
#: MHz rate); when its stamps read as 1e9 s are Unix times of these years, that is the unit.
DENSEST_PERIOD_S = 1e-6
UNIX_YEARS_S = (9.46e8, 4.1e9)  # 2000 to 2099
#: Integer TUM stamps above this are nanoseconds (1e14 s would be three million years).
NANOSECOND_STAMP_THRESHOLD = 10**14
INT64_MAX = np.iinfo(np.int64).max


def parse_stamps(
    path: Path, numbers: Indices, split: SplitStamps, fmt: str, unit: str
) -> tuple[Stamps, list[str], Mask]:
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


def too_large(path: Path, numbers: Indices, whole: Stamps, unit: str = 'ns') -> None:
    k = int(np.argmax(whole))
    msg = (
        f'{path}, line {numbers[k]}: a stamp ({unit}) is beyond what int64 nanoseconds can '
        'hold (2^63 ns, the year 2262); check the stamp column and its unit '
        '(--hand-stamp-unit / --eye-stamp-unit)'
    )
    raise InputError(msg)


def _split_of(whole: Stamps, frac: Text | npt.NDArray[np.object_], neg: Mask) -> SplitStamps:
    """SplitStamps of whole parts, fractional digit strings and signs."""
    digits = np.char.ljust(frac.astype(str), 18, '0')
    nine = digits.astype('U9')  # billionths of the unit
    rest = np.array([f[9:18] for f in digits.tolist()], dtype='U9')
    return SplitStamps(
        whole,
        nine.astype(np.int64),
        np.char.str_len(np.char.rstrip(digits, '0')) > 0,
        neg,
        rest.astype(np.int64),
    )


def split_decimal(path: Path, numbers: list[int], col: Text) -> SplitStamps:
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
    long = (n > 19) | ((n == 19) & np.char.greater(digits, str(INT64_MAX)))
    if long.any():
        k = int(np.flatnonzero(long)[0])
        msg = (
            f'{path}, line {numbers[k]}: stamp {col[k]!r} is beyond what int64 nanoseconds '
            'can hold (2^63 ns, the year 2262); check the stamp column and its unit'
        )
        raise InputError(msg)
    return _split_of(whole_txt.astype(np.int64), parts[:, 2], neg)


def _split_decimal_fallback(path: Path, numbers: list[int], col: Text) -> SplitStamps:
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
