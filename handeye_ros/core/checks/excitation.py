"""How far a body has turned about each of its axes, how fast, how far it travelled, and how
many of its recent poses are missing: the readiness's excitation and stream health, in pieces
that add up as a recording grows (:class:`Motion`: what the node's status reads of the poses new
since its last look, so that a look costs the same at 10 s and at 30 min of buffers).

A rotation about an axis a says nothing of T_HE's rotation about a, nor of its translation
along a (eq. 2); so the turn about each of the device's axes tells which one the user still
has to turn it about, and the spread of the turns' axes (:attr:`Turned.axis_spread_deg`) how
far the data observe T_HE at all: about one axis only (a ground robot), 0 whichever device
axes that one fills.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from ..arrays import Floats
from ..geometry import consecutive_rotvecs
from ..trajectory import Trajectory

#: The turn about each axis is summed over steps this long (s): summed over every pose's step,
#: it summed each pose's noise too (a noisy planar recording 'turned' 859 deg about an axis
#: it never turned about, and the advice then thought that axis done).
TURN_STEP_S = 0.2
#: The stream health looks at this much of the latest data (s).
RECENT_S = 10.0
#: New steps are merged into the newest piece until it spans this much (s): a buffer drops its
#: oldest poses piece by piece, and half an hour is 180 pieces.
PIECE_S = 10.0


@dataclass(frozen=True)
class Turned:
    """A body's motion over the steps between stamps t0_ns and t1_ns: ``deg`` (3,) the sum of
    |rotation| about each of its axes [deg], ``rate_sq`` the sum over steps of the squared
    angular speed [(rad/s)^2], ``steps`` how many, ``travel_m`` its path length [m],
    ``scatter`` (3, 3) the steps' axes' scatter, each weighted by its angle (``sum r r^T /
    |r|`` of the rotation vectors r [rad])."""

    t0_ns: int
    t1_ns: int
    deg: Floats
    rate_sq: float
    steps: int
    travel_m: float
    scatter: Floats

    def __add__(self, other: Turned) -> Turned:
        return Turned(
            min(self.t0_ns, other.t0_ns),
            max(self.t1_ns, other.t1_ns),
            self.deg + other.deg,
            self.rate_sq + other.rate_sq,
            self.steps + other.steps,
            self.travel_m + other.travel_m,
            self.scatter + other.scatter,
        )

    @property
    def axis_spread_deg(self) -> float:
        """How far apart the turns' axes are [deg]: ``2 atan(sqrt(l2 / l1))`` of the scatter's
        two largest eigenvalues, as stage 2 measures its motions' (:func:`.linear.refits.
        axis_spreads_deg`): 0 about one axis, 90 about two or more equally."""
        lam = np.linalg.eigvalsh(0.5 * (self.scatter + self.scatter.T))
        if not lam[2] > 0.0:
            return 0.0
        return float(np.degrees(2.0 * np.arctan(np.sqrt(max(lam[1], 0.0) / lam[2]))))

    @property
    def rms_dps(self) -> float:
        """RMS angular speed [deg/s] (0 without a step)."""
        return float(np.degrees(np.sqrt(self.rate_sq / self.steps))) if self.steps else 0.0


def turned(traj: Trajectory, from_ns: int | None = None) -> tuple[Turned | None, int | None]:
    """The motion of ``traj`` from its pose at ``from_ns`` (its first when None; the end of the
    last step taken before) over steps of about TURN_STEP_S that span no gap, and the stamp the
    next steps start at (None: the same). None for no whole step yet."""
    first = 0 if from_ns is None else int(np.searchsorted(traj.t_ns, from_ns))
    if len(traj) - first < 2:
        return None, from_ns
    t = traj.t_ns[first:]
    period = float(np.median(np.diff(t))) * 1e-9
    idx = first + np.arange(0, t.size, max(1, round(TURN_STEP_S / max(period, 1e-9))))
    if idx.size < 2:
        return None, from_ns
    gaps = np.concatenate(([0], np.cumsum(~traj.interval_ok())))
    whole = gaps[idx[1:]] == gaps[idx[:-1]]  # no gap or break inside the step
    turn = consecutive_rotvecs(traj.q_xyzw[idx])[whole]  # rad, body frame
    seconds = np.diff(traj.t_ns[idx])[whole] * 1e-9
    rate = turn / seconds[:, None]  # rad/s
    travel = float(np.sum(np.linalg.norm(np.diff(traj.p_xyz[idx], axis=0), axis=1)))
    angle = np.maximum(np.linalg.norm(turn, axis=1), 1e-12)
    scatter = (turn / angle[:, None]).T @ turn
    piece = Turned(
        int(traj.t_ns[idx[0]]),
        int(traj.t_ns[idx[-1]]),
        np.degrees(np.sum(np.abs(turn), axis=0)),
        float(np.sum(rate**2)),
        int(np.sum(whole)),
        travel,
        scatter,
    )
    return piece, int(traj.t_ns[idx[-1]])


def dropout(traj: Trajectory) -> float:
    """The fraction of the stream's samples missing over its last RECENT_S (0 for a keyframe
    stream, whose rate is its own)."""
    if traj.keyframes or len(traj) < 3:
        return 0.0
    period = float(np.median(np.diff(traj.t_ns))) * 1e-9
    t = traj.seconds(int(traj.t_ns[-1]))
    span = min(RECENT_S, -float(t[0]))
    if span <= 10 * period:
        return 0.0
    got = int(np.sum(t > -span))
    return float(np.clip(1.0 - got * period / span, 0.0, 1.0))


def _grown(pieces: tuple[Turned, ...], new: Turned | None) -> tuple[Turned, ...]:
    """``new`` added to the last piece while that spans less than PIECE_S, else appended."""
    if new is None:
        return pieces
    if pieces and (pieces[-1].t1_ns - pieces[-1].t0_ns) * 1e-9 < PIECE_S:
        return (*pieces[:-1], pieces[-1] + new)
    return (*pieces, new)


@dataclass(frozen=True)
class Motion:
    """What each stream ('hand', 'eye') did so far: its :class:`Turned` pieces (oldest first),
    the stamp its next steps start at (ns; None: its first pose), and the fraction of its last
    RECENT_S it misses."""

    pieces: Mapping[str, tuple[Turned, ...]] = field(
        default_factory=lambda: {'hand': (), 'eye': ()}
    )
    next_ns: Mapping[str, int | None] = field(default_factory=lambda: {'hand': None, 'eye': None})
    dropout: Mapping[str, float] = field(default_factory=dict)

    def wants(self, newest_ns: Mapping[str, int]) -> dict[str, int]:
        """From which stamp (ns) :meth:`grown` needs each stream's poses: where its steps go on,
        and its last RECENT_S."""
        recent = int(RECENT_S * 1e9)
        out = {}
        for s, newest in newest_ns.items():
            at = self.next_ns[s]
            out[s] = newest - recent if at is None else min(at, newest - recent)
        return out

    def grown(self, tails: Mapping[str, Trajectory]) -> Motion:
        """With the steps of each stream's poses from :meth:`wants` on."""
        pieces, next_ns = dict(self.pieces), dict(self.next_ns)
        for s, tail in tails.items():
            piece, next_ns[s] = turned(tail, self.next_ns[s])
            pieces[s] = _grown(pieces[s], piece)
        return Motion(pieces, next_ns, {s: dropout(t) for s, t in tails.items()})

    def since(self, oldest_ns: Mapping[str, int]) -> Motion:
        """Without the pieces of poses the buffers no longer hold (a piece goes whole once it
        begins before them)."""
        kept = {
            s: tuple(p for p in ps if p.t0_ns >= oldest_ns[s]) for s, ps in self.pieces.items()
        }
        return replace(self, pieces=kept)

    def turned(self, stream: str) -> Turned | None:
        """The stream's pieces added up (None: no whole step yet)."""
        pieces = self.pieces[stream]
        return sum(pieces[1:], pieces[0]) if pieces else None
