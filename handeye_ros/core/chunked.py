"""Element-wise work on long streams, a chunk of rows at a time.

numpy's element-wise operations on arrays of millions of rows are bound by memory traffic: each
one writes a full-length temporary. Taken in chunks of some 65 000 rows, the temporaries stay
in cache, and the same computation runs about three times faster here (slerp of 3.6 million
quaternion pairs: 1.4 s whole, 0.5 s in chunks), with the same result to the bit.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar, cast

import numpy as np

from .arrays import Floats

#: What the function returns: an array, or a tuple of arrays.
Rows = TypeVar('Rows', bound='Floats | tuple[Floats, ...]')

#: Rows per chunk.
CHUNK_ROWS = 1 << 16


def chunked(fn: Callable[[slice], Rows], n: int, size: int = CHUNK_ROWS) -> Rows:
    """``fn(slice)`` over consecutive slices of ``range(n)``, its outputs (an array or a tuple
    of arrays, rows first) concatenated as one call on ``slice(0, n)`` would return them."""
    if n <= size:
        return fn(slice(0, n))
    parts = [fn(slice(k, min(k + size, n))) for k in range(0, n, size)]
    if isinstance(parts[0], tuple):
        return cast(Rows, tuple(np.concatenate(p) for p in zip(*parts, strict=True)))
    return cast(Rows, np.concatenate(parts))
