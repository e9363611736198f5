"""What a calibration learns on the way: warnings, notes and the facts the verdict reads, the
readings it corrected and the candidate offsets it scored. Every stage adds to one
:class:`Findings`, and the result is made from it (:mod:`.pipeline`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..checks.conventions import Correction
from ..checks.selfcheck import Candidate
from ..checks.verdict import ConventionCorrected


@dataclass
class Findings:
    """What the pipeline learns on the way, for the result and the verdict.

    ``log`` holds the notes (sentences that do not lower the verdict) and the facts the stages
    recorded (:mod:`~handeye_ros.core.checks.verdict.facts`), in the order found: the verdict
    alone reads a fact into a reason or a note (:func:`~handeye_ros.core.checks.verdict.judged`;
    test_layout checks that no stage makes a reason)."""

    warnings: list[str] = field(default_factory=list)
    log: list[object] = field(default_factory=list)
    corrections: list[Correction] = field(default_factory=list)
    candidates: list[Candidate] = field(default_factory=list)
    #: stage 2 named the eye's scale (a reason or a note): the batch stage does not again
    scale_named: bool = False

    def note(self, text: str) -> None:
        """A sentence for the result's notes."""
        self.log.append(text)

    def record(self, fact: object) -> None:
        """A fact for the verdict to read."""
        self.log.append(fact)

    def corrected(self, found: list[Correction]) -> None:
        """Readings of the input that were corrected: each a warning and a fact."""
        for c in found:
            self.corrections.append(c)
            self.warnings.append(c.message)
            self.record(ConventionCorrected(c.message))
