"""Conventions checked, not assumed: stamp units, clock epochs, and how orientations were read.

Each check compares readings of the data and keeps the one that a physical motion explains; a
reading other than the one given is either applied, with a :class:`Correction` that names what
was assumed and the option that says so explicitly (the verdict is then not ``good``: the files
still hold the mistake, and other tools will read them wrong), or, when two readings explain
the data equally, refused with a message naming both.

**Stamp units** (before stage 1). A pose stream runs at 0.5 Hz to 10 kHz. Stamps in
milliseconds read as seconds make a 20 Hz stream look like 0.02 Hz; microseconds written where
nanoseconds belong make a 200 Hz MoCap look like 200 kHz. Every reading of each stream scaled by
a power of 1000 is tried; a reading is plausible when both rates are, and the two streams then
cover spans within a factor 100 of each other (a unit mistake is a factor 1000). The stamps as
given are kept whenever they are plausible.

**Clock epochs.** Stamps above 1e8 s (1973) are read as an absolute epoch (Unix, GPS), stamps
below 1e7 s (116 days) as time since boot or since the recording started. Streams on different
epochs are legitimate (two clocks are why this tool exists); stage 1 searches every lag the
recordings allow, so the offset is found either way; the epochs are named in a warning.

How orientations were read is checked after stage 1 (:mod:`.orientations`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from datetime import UTC, datetime

import numpy as np

from ..errors import InputError
from ..trajectory import Trajectory

#: Rates a pose stream can have, Hz (a keyframe-only estimate down to one pose in 10 s).
PLAUSIBLE_RATE_HZ = (0.1, 10_000.0)
#: Two streams of one recording cover spans within this factor of each other (a MoCap may run
#: longer than the VIO; a unit mistake is a factor 1000).
SPAN_RATIO_MAX = 100.0
#: Scale factors tried on the stamps (true = as given * factor), with the unit they imply.
UNIT_FACTORS = {
    1e-9: 'nanoseconds (where seconds were expected)',
    1e-6: 'microseconds (where seconds were expected)',
    1e-3: 'milliseconds (where seconds were expected)',
    1.0: 'the unit expected',
    1e3: 'microseconds (where nanoseconds were expected)',
    1e6: 'milliseconds (where nanoseconds were expected)',
    1e9: 'seconds (where nanoseconds were expected)',
}
#: Stamps above this (s) are an absolute epoch; below EPOCH_RELATIVE_S, time since boot.
EPOCH_ABSOLUTE_S = 1e8
EPOCH_RELATIVE_S = 1e7
INT64_MAX = np.iinfo(np.int64).max
#: The two streams, in the order the checks take them.
STREAMS = ('hand', 'eye')


@dataclass(frozen=True)
class Correction:
    """A convention the data contradicted, and the reading that was applied instead.

    stream: 'hand' or 'eye'; what: 'stamp_unit', 'quaternion_order' or 'inverse'; assumed: the
    reading applied, in words; option: the option that states it explicitly ('' where none
    does: quaternions of a message); message: a warning for the user.
    """

    stream: str
    what: str
    assumed: str
    option: str
    message: str


# --------------------------------------------------------------------------------- stamps


def _scaled(traj: Trajectory, factor: float) -> Trajectory:
    """Stamps multiplied by a power of 1000 (exact integer arithmetic)."""
    if factor == 1.0:
        return traj
    if factor > 1.0:
        k = round(factor)
        if max(abs(int(traj.t_ns[0])), abs(int(traj.t_ns[-1]))) > INT64_MAX // k:
            raise OverflowError  # checked first: int64 products wrap silently
        t_ns = traj.t_ns * np.int64(k)
    else:
        k = round(1.0 / factor)
        t_ns = traj.t_ns // np.int64(k)
    if np.any(np.diff(t_ns) <= 0):  # a scale that merges stamps is no reading
        raise OverflowError
    return replace(traj, t_ns=t_ns)


def _plausible_rate(traj: Trajectory, factor: float) -> bool:
    rate = traj.rate_hz / factor
    return PLAUSIBLE_RATE_HZ[0] <= rate <= PLAUSIBLE_RATE_HZ[1]


def check_stamp_units(
    hand: Trajectory, eye: Trajectory
) -> tuple[Trajectory, Trajectory, list[Correction]]:
    """Both streams with plausible stamp units (see the module docstring). A unit stated to
    the reader is already applied; one that makes a plausible reading is kept.

    Raises
    ------
    InputError
        When no reading is plausible, or two are equally so.
    """
    options = [[f for f in UNIT_FACTORS if _plausible_rate(traj, f)] for traj in (hand, eye)]
    spans = (hand.duration_s, eye.duration_s)

    def compatible(fh: float, fe: float) -> bool:
        a, b = spans[0] * fh, spans[1] * fe
        return min(a, b) > 0 and max(a, b) / min(a, b) <= SPAN_RATIO_MAX

    readings = [(fh, fe) for fh in options[0] for fe in options[1] if compatible(fh, fe)]
    if (1.0, 1.0) in readings:
        return hand, eye, []
    if not readings:
        if (1.0 in options[0]) and (1.0 in options[1]):
            return hand, eye, []  # plausible rates, unusual spans: nothing better to offer
        msg = (
            'no reading of the stamps gives both streams a plausible rate (0.5 Hz to 10 kHz): '
            f'{hand.name} at {hand.rate_hz:.4g} Hz over {hand.duration_s:.4g} s, {eye.name} '
            f'at {eye.rate_hz:.4g} Hz over {eye.duration_s:.4g} s as read. Check the stamp '
            'units (set --hand-stamp-unit / --eye-stamp-unit)'
        )
        raise InputError(msg)
    # fewest changed streams first; among equals, the closest spans
    readings.sort(
        key=lambda r: (
            (r[0] != 1.0) + (r[1] != 1.0),
            abs(np.log10(spans[0] * r[0] / (spans[1] * r[1]))),
        )
    )
    best = readings[0]
    rivals = [
        r
        for r in readings[1:]
        if (r[0] != 1.0) + (r[1] != 1.0) == (best[0] != 1.0) + (best[1] != 1.0)
    ]
    if rivals:
        msg = (
            'the stamps of one stream are in an unexpected unit, and the data do not say '
            f'which: {hand.name} at {hand.rate_hz:.4g} Hz over {hand.duration_s:.4g} s, '
            f'{eye.name} at {eye.rate_hz:.4g} Hz over {eye.duration_s:.4g} s as read. Set '
            '--hand-stamp-unit / --eye-stamp-unit'
        )
        raise InputError(msg)
    out = [
        _reread(traj, stream, f)
        for traj, stream, f in zip((hand, eye), STREAMS, best, strict=True)
    ]
    corrections = [c for _, c in out if c is not None]
    return out[0][0], out[1][0], corrections


def _reread(traj: Trajectory, stream: str, factor: float) -> tuple[Trajectory, Correction | None]:
    """The stream with its stamps times ``factor`` (:data:`UNIT_FACTORS`), and the correction
    that says so (None for a factor of 1)."""
    if factor == 1.0:
        return traj, None
    try:
        scaled = _scaled(traj, factor)
    except OverflowError:
        msg = (
            f'{traj.name}: the stamps look like {UNIT_FACTORS[factor]} but cannot be '
            f'converted; set --{stream}-stamp-unit'
        )
        raise InputError(msg) from None
    unit = UNIT_FACTORS[factor]
    return scaled, Correction(
        stream,
        'stamp_unit',
        unit,
        f'{stream}_stamp_unit',
        f'{traj.name}: the stamps were taken as {unit}: as given they make a '
        f'{traj.rate_hz:.4g} Hz stream over {traj.duration_s:.4g} s, as {unit} a '
        f'{scaled.rate_hz:.4g} Hz stream over {scaled.duration_s:.4g} s like the other '
        f'stream. If that is right, say so with --{stream}-stamp-unit (the file still '
        'holds the mistake for other tools)',
    )


def epoch_note(hand: Trajectory, eye: Trajectory) -> str | None:
    """A warning when the two streams' stamps are on different clock epochs, else None."""

    def kind(t_ns: int) -> str | None:
        s = t_ns * 1e-9
        if s > EPOCH_ABSOLUTE_S:
            day = datetime.fromtimestamp(s, tz=UTC).strftime('%Y-%m-%d')
            return f'an absolute epoch (as Unix time: {day})'
        if 0 <= s < EPOCH_RELATIVE_S:
            return f'time since boot or since the start ({s:.1f} s)'
        return None

    kh, ke = kind(int(hand.t_ns[0])), kind(int(eye.t_ns[0]))
    if kh is None or ke is None or kh.split(' (')[0] == ke.split(' (')[0]:
        return None
    return (
        f'the streams are on different clock epochs: {hand.name} starts at {kh}, '
        f'{eye.name} at {ke}; the time offset includes the epoch difference'
    )


# --------------------------------------------------------------------------------- orientations
