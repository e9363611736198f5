"""What the readiness has gathered of a recording, kept up to date as the recording grows.

:func:`start` reads a whole recording: stages 1 and 2 (unless a calibration is given), and
then, at their estimate, the consecutive eye pairs' information (eq. 16,
:mod:`.pair_information`) and the excitation (:mod:`.excitation`) in pieces of
about PIECE_S. :func:`measure` reads only the poses that came since, at the same estimate: the
older pieces are frozen, so a status costs the same at 10 s and at 30 min of buffers. A
:class:`Progress` adds the pieces up, drops those of poses a buffer has dropped, and says when
the pairs' optimum has moved beyond its own 1-sigma since (:meth:`Progress.moved`), or the
recording has grown by half (:meth:`Progress.due`): then :func:`start` reads it again.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Protocol, Self, TypeVar

import numpy as np

from ..arrays import Floats, Indices
from ..config import CalibrationConfig
from ..errors import HandeyeError, InputError
from ..geometry import matrix_from_quat
from ..linear.solve import solve_linear
from ..time.align import MIN_OVERLAP_S, align_time
from ..trajectory import Trajectory, is_keyframe_only
from . import pair_information as info
from .excitation import RECENT_S, Turned, dropout, turned
from .orientations import READINGS, check_orientations

#: Slower than this RMS angular speed (deg/s), the device is held still (and stages 1 and 2
#: are not tried).
STILL_DPS = 2.0
#: Shorter streams cannot be aligned in time: stage 1 wants MIN_OVERLAP_S of overlap at the
#: offsets it searches, some of which overlap only partly.
MIN_RECORDING_S = 2.0 * MIN_OVERLAP_S
#: :func:`start` uses at most this many consecutive eye pairs; a longer recording uses every
#: k-th pair and counts each k times (a cost cap: 100 s at 200 Hz; neighbouring pairs carry
#: nearly the same information, and an hour would otherwise cost seconds). :func:`measure`
#: uses every new pair.
MAX_PAIRS = 20_000
#: New pieces are merged into the newest one until it spans this much (s): a buffer drops its
#: oldest poses piece by piece, and half an hour is 180 pieces.
PIECE_S = 10.0
#: The whole recording is read again (:meth:`Progress.due`) each time its span has grown by
#: this factor: stage 1 looks again, at a cost that grows with the recording, as often as it
#: grows by half.
READ_AGAIN = 1.5


class _Piece(Protocol):
    """What :class:`Progress` gathers: sums over a span of stamps that add up."""

    @property
    def t0_ns(self) -> int: ...

    @property
    def t1_ns(self) -> int: ...

    def __add__(self, other: Self, /) -> Self: ...


Piece = TypeVar('Piece', bound=_Piece)


def _grow(pieces: list[Piece], new: Piece | None) -> None:
    """``new`` added to the last piece while that spans less than PIECE_S, else appended."""
    if new is None:
        return
    if pieces and (pieces[-1].t1_ns - pieces[-1].t0_ns) * 1e-9 < PIECE_S:
        pieces[-1] = pieces[-1] + new
    else:
        pieces.append(new)


@dataclass(frozen=True)
class Known:
    """A calibration already made on the same data (offline: the result's own), so that the
    prediction needs no stage 1 or 2 of its own."""

    time_offset_s: float
    R_HE: Floats
    p_HE: Floats
    motions: int
    peak_correlation: float = float('nan')
    second_peak_ratio: float = float('nan')

    @property
    def estimate(self) -> info.Estimate:
        return info.Estimate(self.time_offset_s, self.R_HE, self.p_HE)


@dataclass(frozen=True)
class Carry:
    """Where :func:`measure` goes on (eye or hand stamps, ns; None: from the first pose): the
    next eye pair starts at or after ``pairs_ns``, the next turn steps at ``eye_ns`` and
    ``hand_ns``."""

    pairs_ns: int | None = None
    eye_ns: int | None = None
    hand_ns: int | None = None


@dataclass(frozen=True)
class Cursor:
    """What :func:`measure` needs of a :class:`Progress`: its estimate (None when stages 1 and 2
    have not given one), the noise (rad, m) that sets the outliers, and where to go on."""

    known: Known | None
    noise: tuple[float, float]
    carry: Carry
    h: float


@dataclass(frozen=True)
class Measured:
    """The pieces of the poses new since a :class:`Cursor` (None: nothing whole yet)."""

    pairs: info.Chunk | None
    eye_turn: Turned | None
    hand_turn: Turned | None
    carry: Carry
    dropout: dict[str, float]


@dataclass
class Progress:
    """The pieces gathered so far of one recording (oldest first), at one estimate."""

    known: Known | None
    #: why stages 1 and 2 gave no estimate (their refusal, or too short a recording), or None
    refused: str | None
    h: float
    carry: Carry
    #: the span :func:`start` read (s, the shorter stream's)
    span_s: float = 0.0
    #: the Gauss-Newton step the pairs called for when :func:`start` read them (7,): from
    #: stage 2's linear estimate to where the batch stage would go; None without pairs
    first_step: Floats | None = None
    pairs: list[info.Chunk] = field(default_factory=list)
    eye_turn: list[Turned] = field(default_factory=list)
    hand_turn: list[Turned] = field(default_factory=list)
    dropout: dict[str, float] = field(default_factory=dict)

    def cursor(self) -> Cursor:
        return Cursor(self.known, self.noise(), self.carry, self.h)

    def wants(self, hand_newest_ns: int, eye_newest_ns: int) -> tuple[int, int]:
        """From which stamps (ns) :func:`measure` needs each stream's poses: where it goes on,
        the hand at the next pairs' stamps less dt and h, and the last RECENT_S of both."""
        c, recent = self.carry, int(RECENT_S * 1e9)
        hand, eye = [hand_newest_ns - recent], [eye_newest_ns - recent]
        if c.hand_ns is not None:
            hand.append(c.hand_ns)
        if c.eye_ns is not None:
            eye.append(c.eye_ns)
        if c.pairs_ns is not None and self.known is not None:
            eye.append(c.pairs_ns)
            hand.append(c.pairs_ns - round((self.known.time_offset_s + self.h) * 1e9))
        return min(hand), min(eye)

    def take(self, m: Measured) -> None:
        """Add the pieces :func:`measure` found."""
        _grow(self.pairs, m.pairs)
        _grow(self.eye_turn, m.eye_turn)
        _grow(self.hand_turn, m.hand_turn)
        self.carry, self.dropout = m.carry, m.dropout

    def drop_before(self, hand_oldest_ns: int, eye_oldest_ns: int) -> None:
        """Forget the pieces of poses the buffers no longer hold (a piece goes whole once it
        begins before them: what a calibration now could not use)."""
        self.eye_turn[:] = [p for p in self.eye_turn if p.t0_ns >= eye_oldest_ns]
        self.hand_turn[:] = [p for p in self.hand_turn if p.t0_ns >= hand_oldest_ns]
        if self.known is not None:
            shift = round((self.known.time_offset_s + self.h) * 1e9)
            first = max(eye_oldest_ns, hand_oldest_ns + shift)
            self.pairs[:] = [p for p in self.pairs if p.t0_ns >= first]

    def total(self) -> info.Chunk | None:
        """All the pairs' pieces added up."""
        return sum(self.pairs[1:], self.pairs[0]) if self.pairs else None

    def turned(self, stream: str) -> Turned | None:
        pieces = self.eye_turn if stream == 'eye' else self.hand_turn
        return sum(pieces[1:], pieces[0]) if pieces else None

    def noise(self) -> tuple[float, float]:
        total = self.total()
        return info.weights(total.hist) if total is not None else (np.inf, np.inf)

    def due(self, span_s: float) -> str | None:
        """Why the whole recording, now ``span_s`` long (the shorter stream's span, s), should
        be read again (:func:`start`), or None: stages 1 and 2 gave no estimate yet, the
        recording has grown by READ_AGAIN, or the pairs' optimum has moved beyond its 1-sigma
        (:meth:`moved`: a clock that jumped or drifts, a stage 1 peak that more data
        overturn)."""
        if self.known is None:
            return self.refused or 'no estimate yet'
        if span_s >= READ_AGAIN * self.span_s:
            return f'the recording has grown from {self.span_s:.0f} s to {span_s:.0f} s'
        return self.moved()

    def step_vector(self) -> Floats | None:
        """The Gauss-Newton step (7,) the pairs gathered call for from the estimate (the
        parameters of :mod:`.pair_information`); None without pairs."""
        total = self.total()
        if total is None:
            return None
        return info.step(*info.normal_equations(total))

    def step(self) -> tuple[tuple[float, float, float], tuple[float, float, float]] | None:
        """How far the pairs' optimum has moved since :func:`start` read them (the step now
        less the step then), and its 1-sigma now, each as dt [s], translation [m] and
        rotation [deg]; None without pairs."""
        total, now = self.total(), self.step_vector()
        if total is None or now is None or self.first_step is None:
            return None
        H, _ = info.normal_equations(total)
        return info.step_sizes(now - self.first_step), info.sigmas(info.covariance(H))

    def moved(self) -> str | None:
        """Whether the pairs' optimum has moved beyond its 1-sigma since :func:`start` read the
        recording (dt, the translation or the rotation), said with the numbers; None if not.
        Under white noise that comes as the pairs about double (the move then has the size of
        the 1-sigma of the first half); sooner, when a clock jumps or drifts. (The estimate
        itself, stage 2's linear one, stays where the pieces were linearised: the noise of the
        residuals at it is what the predictions were measured against, bench/readiness.py.)"""
        sizes = self.step()
        if sizes is None:
            return None
        names = ('time offset', 'translation', 'rotation')
        over = [
            f'{n} {s:.3g} (1-sigma {sg:.3g})'
            for n, s, sg in zip(names, *sizes, strict=True)
            if np.isfinite(s) and np.isfinite(sg) and s > sg
        ]
        return 'the estimate moved: ' + ', '.join(over) if over else None


def start(
    hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig, known: Known | None = None
) -> Progress:
    """Everything of a whole recording (both streams on their own clocks). Without ``known``,
    stages 1 and 2 give the estimate (unless the device is held still or the recording is too
    short). Never raises for data that cannot calibrate: ``refused`` says why."""
    h = cfg.knot_spacing / 2.0
    progress = Progress(None, None, h, Carry(), min(hand.duration_s, eye.duration_s))
    progress.take(measure(progress.cursor(), hand, eye, cfg))
    eye_turn = progress.turned('eye')
    if eye_turn is None or eye_turn.rms_dps < STILL_DPS:
        return progress
    if known is None:
        short = min(hand.duration_s, eye.duration_s)
        if is_keyframe_only(eye):
            progress.refused = _too_sparse(eye)
            return progress
        if short < MIN_RECORDING_S:
            progress.refused = (
                f'keep recording: {short:.0f} s of both streams so far, '
                f'{MIN_RECORDING_S:.0f} s needed'
            )
            return progress
        try:
            known = _calibrate(hand, eye, cfg)
        except HandeyeError as err:
            progress.refused = str(err)
            return progress
    progress.known = known
    progress.pairs, pairs_ns = _all_pairs(hand, eye, known.estimate, h)
    progress.carry = replace(progress.carry, pairs_ns=pairs_ns)
    progress.first_step = progress.step_vector()
    return progress


def measure(cursor: Cursor, hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig) -> Measured:
    """The pieces of ``hand`` and ``eye`` (each from :meth:`Progress.wants` on) that come after
    the cursor."""
    c = cursor.carry
    eye_turn, eye_ns = turned(eye, c.eye_ns)
    hand_turn, hand_ns = turned(hand, c.hand_ns)
    pairs, pairs_ns = None, c.pairs_ns
    if cursor.known is not None and c.pairs_ns is not None:
        est = cursor.known.estimate
        i, pairs_ns = _new_pairs(hand, eye, est, cursor.h, c.pairs_ns)
        if i.size:
            noise = cursor.noise
            if not np.all(np.isfinite(noise)):  # the first pairs: their own noise
                r, ok = info.residuals(hand, eye, i, est)
                noise = _noise(r[ok])
            pairs = next(iter(info.chunks(hand, eye, i, est, cursor.h, noise)), None)
    return Measured(
        pairs,
        eye_turn,
        hand_turn,
        Carry(pairs_ns, eye_ns, hand_ns),
        {'hand': dropout(hand), 'eye': dropout(eye)},
    )


def _calibrate(hand: Trajectory, eye: Trajectory, cfg: CalibrationConfig) -> Known:
    """Stages 1 and 2 on the data as they are (no screening, drift or scale)."""
    if cfg.time_offset is not None:
        dt, peak, second = cfg.time_offset, float('nan'), float('nan')
    else:
        ta = align_time(
            hand,
            eye,
            max_time_offset=cfg.max_time_offset,
            time_offset_guess=cfg.time_offset_guess,
            resample_rate_hz=cfg.resample_rate_hz,
        )
        dt, peak, second = ta.time_offset_s, ta.peak_correlation, ta.second_peak_ratio
    _misread(hand, eye, dt, cfg)
    lin, _ = solve_linear(hand, eye, dt, cfg)
    return Known(dt, matrix_from_quat(lin.q_HE), lin.p_HE, lin.n_motions, peak, second)


def _too_sparse(eye: Trajectory) -> str:
    """What the status says of a device stream too sparse for it (keyframes, or a VIO
    published at a rate of a few Hz)."""
    step = float(np.median(np.diff(eye.t_ns))) * 1e-9
    return (
        f"the device's poses come {step:.2f} s apart ({1.0 / step:.1f} Hz): too few for the "
        'status, which reads angular speeds; publish its odometry at its full rate (10 Hz or '
        'more). ~/calibrate still works: it calibrates sparse poses by their rotation angles'
    )


def _misread(hand: Trajectory, eye: Trajectory, dt: float, cfg: CalibrationConfig) -> None:
    """InputError, with the fix, when AX = XB fits the orientations of a stream read another
    way only (inverted poses, another quaternion order: :mod:`.orientations`): a status would
    otherwise predict the sigmas of a wrong model and ask for more motion."""
    found = check_orientations(hand, eye, dt, np.deg2rad(cfg.eta))[2]
    if found:
        c = found[0]
        source = {'hand': 'the MoCap', 'eye': 'the device'}[c.stream]
        words = READINGS[c.assumed][1]
        raise InputError(
            f'{source}: {words}, as AX = XB shows; the calibration corrects it and says so, '
            f'but tell the node: restart it with {c.option} set (calibrator --help)'
        )


def _all_pairs(
    hand: Trajectory, eye: Trajectory, est: info.Estimate, h: float
) -> tuple[list[info.Chunk], int | None]:
    """The pieces of every pair the hand can cover (at most MAX_PAIRS, see there), with the
    noise of them all, and the stamp the next pairs start at."""
    i, pairs_ns = _new_pairs(hand, eye, est, h, int(eye.t_ns[0]))
    scale = 1.0
    if i.size > MAX_PAIRS:
        every = i[:: -(-i.size // MAX_PAIRS)]
        scale, i = i.size / every.size, every
    if i.size == 0:
        return [], pairs_ns
    r, ok = info.residuals(hand, eye, i, est)
    return info.chunks(hand, eye, i, est, h, _noise(r[ok]), scale, PIECE_S), pairs_ns


def _new_pairs(
    hand: Trajectory, eye: Trajectory, est: info.Estimate, h: float, from_ns: int
) -> tuple[Indices, int]:
    """The eye pairs from ``from_ns`` on whose ends the hand reaches at dt - h (later ones wait
    for the hand), and the stamp the next ones start at."""
    limit = int(hand.t_ns[-1]) + round((est.time_offset_s - h) * 1e9)
    start = int(np.searchsorted(eye.t_ns, from_ns))
    stop = int(np.searchsorted(eye.t_ns, limit, side='right'))  # poses up to the limit
    if stop - start < 2:
        return np.zeros(0, int), from_ns
    i = info.pairs_of(eye, int(eye.t_ns[start]), int(eye.t_ns[stop - 1]))
    return i, int(eye.t_ns[stop - 1])


def _noise(r: Floats) -> tuple[float, float]:
    return info.weights(np.stack([info.histogram(r[:, :3]), info.histogram(r[:, 3:])]))
