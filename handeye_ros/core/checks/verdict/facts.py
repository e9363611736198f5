"""What the stages found, as facts for the verdict: each stage records what it measured or met,
and only the verdict says what that means (:func:`read`: a reason, a note, or nothing).

The stages' findings keep the facts among their notes, in the order they were found
(:class:`~.findings.Findings`), so that the reasons and the notes read from them keep that
order. A :class:`~.codes.Reason` the rules make on the way (a tie of the
self-check) is kept there too, and reads as itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, get_args

from ...arrays import Floats

if TYPE_CHECKING:  # the records of the stages' math, for the facts' fields only
    from ...linear.scale import ScaleFit
    from ...time.clock import DriftFit
    from ..selfcheck import Candidate


@dataclass(frozen=True)
class ConventionCorrected:
    """A reading of the input other than the one given was applied (``message`` says which)."""

    message: str


@dataclass(frozen=True)
class FixedOffsetDisagrees:
    """The time offset the user fixed (``fixed_s``) is not where the angular-speed correlation
    peaks (``measured_s``, with its peak ``correlation``)."""

    fixed_s: float
    measured_s: float
    correlation: float


@dataclass(frozen=True)
class ScaleMeasured:
    """Without estimate_scale: the scale that would fit the eye's translations to the hand's
    (stage 2's motions)."""

    fit: ScaleFit


@dataclass(frozen=True)
class DriftMeasured:
    """Without clock_drift: the offset measured in windows along the recording (every run)."""

    fit: DriftFit


@dataclass(frozen=True)
class DriftUnobservable:
    """With clock_drift: the drift could not be measured (``why``; None: the eye has keyframes
    only, and the windows need angular velocities)."""

    why: str | None


@dataclass(frozen=True)
class SeedFailed:
    """Stage 2 with the next RANSAC seed found no answer (``error``)."""

    seed: int
    error: str


@dataclass(frozen=True)
class SeedCompared:
    """Stage 2 with the next RANSAC seed landed this far (deg, m) from the answer, on the
    directions the batch stage determines; the batch stage's sigmas (dt, p, theta) when it
    ran."""

    seed: int
    rotation_deg: float
    translation_m: float
    batch_std: Floats | None


@dataclass(frozen=True)
class StagesDisagree:
    """The batch stage moved the answer (``what``) beyond its sigmas and the self-check did not
    support it: stage 2 ``failed`` at its offset, the scores could not be compared (``scored``
    None), or they sided with the linear result (``scored``: the candidates)."""

    what: str
    failed: str | None = None
    scored: tuple[Candidate, ...] | None = None


#: Every fact a stage records: a closed union, which the verdict reads case by case
#: (:func:`.during.read`, checked exhaustive by the type checker).
Fact = (
    ConventionCorrected
    | FixedOffsetDisagrees
    | ScaleMeasured
    | DriftMeasured
    | DriftUnobservable
    | SeedFailed
    | SeedCompared
    | StagesDisagree
)
FACTS = get_args(Fact)
