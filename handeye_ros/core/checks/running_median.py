"""The running median of the screening (:mod:`.screening`), the same on every scipy.

``scipy.ndimage.median_filter`` of a 1-D array selects the median of every window anew (work
n * w) before scipy 1.15, and keeps the window sorted since (n log w): on the ROS 2 Jazzy
platform's scipy 1.11.4 the screening's filters (windows of 401 residuals) made stage 1 of an
hour of 1 kHz take 72 s instead of 5 s, and of ten minutes of 200 Hz 3.7 s instead of 0.3 s
(bench/runtime.py). Where scipy has the fast filter it is used; elsewhere
:func:`_pairs_of_blocks` gives the same values (the median of an odd window is one of its
elements) in n log w and w steps of vectorised work: 4 times faster than the old filter on
22 401 residuals, 13 times on 720 000.

Its method: the padded signal cut into blocks of w; a window that starts j into block b holds
the block's elements from j on and the next block's before j. The two blocks sorted together,
the median is the (w // 2 + 1)-th element still in the window; moving the window by one
removes one element and adds one, so the median's place in the sorted pair moves by a few
places (past the elements no longer inside), for all pairs at once.
"""

from __future__ import annotations

import numpy as np
import scipy
from scipy.ndimage import median_filter

from ..arrays import Floats, Indices, Mask

#: The first scipy whose 1-D median_filter keeps its window sorted (scipy PR 20543).
FAST_SCIPY = (1, 15)
#: Shortest signal the pairs of blocks take on an older scipy: below it the old filter's
#: n * w selections cost less than the pairs' w vectorised steps (2277 residuals, windows of
#: 41: 1.4 ms against 2.8 ms; 22 401 and 401: 102 ms against 24 ms).
PAIRS_FROM = 8192


def _scipy_version() -> tuple[int, int]:
    major, minor = scipy.__version__.split('.')[:2]
    return int(major), int(minor)


#: Whether this scipy's median_filter keeps its window sorted.
SCIPY_SORTS = _scipy_version() >= FAST_SCIPY


def running_median(x: Floats, size: int) -> Floats:
    """The median of each window of ``size`` (odd, at most ``x.size``) centred on each
    element, the signal mirrored at its ends (d c b | a b c d | c b a): what
    ``median_filter(x, size=size, mode='mirror')`` gives."""
    if SCIPY_SORTS or x.size < PAIRS_FROM or size < 3:
        out: Floats = median_filter(x, size=size, mode='mirror')
        return out
    return _pairs_of_blocks(np.asarray(x, dtype=np.float64), size)


def _pairs_of_blocks(x: Floats, w: int) -> Floats:
    """The running median by sorted pairs of blocks (the module docstring)."""
    h, n = w // 2, x.size
    padded = np.pad(x, h, mode='reflect')  # numpy's reflect is scipy's mirror
    nb = (n - 1) // w + 1  # the blocks windows start in
    # the tail past the signal is never inside a window that gives an output
    tail = np.full((nb + 1) * w - padded.size, np.inf)
    blocks = np.concatenate((padded, tail)).reshape(nb + 1, w)
    pair = np.concatenate((blocks[:-1], blocks[1:]), axis=1)  # (nb, 2w): block b, then b + 1
    order = np.argsort(pair, axis=1, kind='stable')
    values = np.take_along_axis(pair, order, axis=1)
    place = np.empty_like(order)  # where each column of the pair sits in the sorted order
    np.put_along_axis(place, order, np.broadcast_to(np.arange(2 * w), order.shape), axis=1)
    # flat, row by row: one index per pair and step instead of two
    inside = (order < w).ravel()  # the window starting at block b: block b whole
    base = np.arange(nb) * (2 * w)
    flat_values = values.ravel()
    cum = np.cumsum(inside.reshape(nb, 2 * w), axis=1)
    k: Indices = base + np.argmax(cum > h, axis=1)  # the (h + 1)-th inside, flat
    place = place + base[:, None]
    out = np.empty((w, nb))
    out[0] = flat_values[k]
    for j in range(1, w):
        gone, come = place[:, j - 1], place[:, w + j - 1]
        inside[gone] = False
        inside[come] = True
        # elements inside up to k: h + 1 before the move, then one fewer and one more
        count = h + 1 - (gone <= k) + (come <= k)
        _walk(inside, k, count, h)
        out[j] = flat_values[k]
    median: Floats = out.T.reshape(-1)[:n]
    return median


def _walk(inside: Mask, k: Indices, count: Indices, h: int) -> None:
    """Move each pair's ``k`` (flat, in place) to the (h + 1)-th element inside its window,
    given ``count``, the elements inside up to ``k``: up while fewer, down while the one
    below would still have h + 1."""
    up = np.flatnonzero(count <= h)
    while up.size:
        k[up] = k[up] + 1
        count[up] = count[up] + inside[k[up]]
        up = up[count[up] <= h]
    down = np.flatnonzero(count - inside[k] > h)
    while down.size:
        count[down] = count[down] - inside[k[down]]
        k[down] = k[down] - 1
        down = down[count[down] - inside[k[down]] > h]
