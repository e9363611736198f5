"""Which pose pairs (i, j) become the relative motions A_ij, B_ij (paper Section III-B.1).

- ``rotation`` (the paper's choice): keyframes chosen so that each motion rotates by at least
  eta (eq. 6). Every motion then constrains the extrinsic (a pure translation would not, and a
  tiny rotation is drowned by noise), while staying short enough not to accumulate VIO drift.
- ``global``: every frame against the first; drift couples into every equation.
- ``interframe``: consecutive frames; short motions, low signal-to-noise.
"""

from __future__ import annotations

import numpy as np

from ..arrays import Floats, Indices
from ..trajectory import segment_spans


def motion_indices(
    R: Floats, strategy: str = 'rotation', eta_rad: float = np.deg2rad(5.0)
) -> tuple[Indices, Indices]:
    """Index pairs ``(i, j)``, i < j, of the relative motions, for rotations R of shape (N, 3, 3).

    ``eta_rad`` is used by the ``rotation`` strategy only.
    """
    if strategy not in STRATEGIES:
        msg = f'relative_poses must be one of {tuple(STRATEGIES)}, got {strategy!r}'
        raise ValueError(msg)
    if strategy == 'rotation':
        return rotation_keyframes(R, eta_rad)
    return WITHOUT_ETA[strategy](R)


def global_pairs(R: Floats) -> tuple[Indices, Indices]:
    """Every frame against the first."""
    j = np.arange(1, R.shape[0])
    return np.zeros_like(j), j


def interframe_pairs(R: Floats) -> tuple[Indices, Indices]:
    """Consecutive frames."""
    i = np.arange(R.shape[0] - 1)
    return i, i + 1


def rotation_keyframes(R: Floats, eta_rad: float) -> tuple[Indices, Indices]:
    """Chain of keyframes k_0 = 0, k_m+1 = first j > k_m with angle(R_k_m^T R_j) >= eta (eq. 6).

    The loop runs once per keyframe, not per pose: the rotation path length s (cumulative sum of
    inter-frame angles) bounds the angle from above, angle(i, j) <= s_j - s_i, so no j before
    ``s_j >= s_i + eta`` can qualify, and candidates after it are tested in vectorised blocks.
    """
    n = R.shape[0]
    # angle(R_i^T R_j) >= eta  <=>  trace(R_i^T R_j) = <R_i, R_j> (the matrices' inner product
    # as 9-vectors) <= 1 + 2 cos(eta): one dot product per candidate (an hour at 200 Hz has
    # some 20 000 keyframes)
    R9 = np.ascontiguousarray(R).reshape(n, 9)
    step = np.einsum('ij,ij->i', R9[:-1], R9[1:])
    s = np.concatenate(([0.0], np.cumsum(np.arccos(np.clip(0.5 * (step - 1.0), -1.0, 1.0)))))
    max_trace = 1.0 + 2.0 * np.cos(eta_rad)
    first, second = [], []
    i = 0
    while True:
        # never i itself: its angle to itself is float noise (~1e-8 rad), not zero
        start = max(int(np.searchsorted(s, s[i] + eta_rad * (1.0 - 1e-9))), i + 1)
        block = 32
        found = -1
        while start < n:
            stop = min(start + block, n)
            hit = np.flatnonzero(R9[start:stop] @ R9[i] <= max_trace)
            if hit.size:
                found = start + int(hit[0])
                break
            start = stop
            block *= 2
        if found < 0:
            break
        first.append(i)
        second.append(found)
        i = found
    return np.asarray(first, dtype=int), np.asarray(second, dtype=int)


def segment_motion_indices(
    R: Floats,
    segment: Indices,
    strategy: str = 'rotation',
    eta_rad: float = np.deg2rad(5.0),
) -> tuple[Indices, Indices]:
    """:func:`motion_indices` within each segment (``segment``: (N,) labels, non-decreasing),
    so that no motion joins two segments."""
    spans = segment_spans(segment)
    if len(spans) == 1:
        return motion_indices(R, strategy, eta_rad)
    firsts, seconds = [], []
    for a, b in spans:
        if b - a < 2:
            continue
        i, j = motion_indices(R[a:b], strategy, eta_rad)
        firsts.append(i + a)
        seconds.append(j + a)
    if not firsts:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    return np.concatenate(firsts), np.concatenate(seconds)


#: The relative-pose strategies by name (the option ``relative_poses``; its choices in
#: :mod:`.config` are these names, which test_config checks).
WITHOUT_ETA = {'global': global_pairs, 'interframe': interframe_pairs}
STRATEGIES = ('rotation', *WITHOUT_ETA)
