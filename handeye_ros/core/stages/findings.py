"""What a calibration learns on the way: warnings, the verdict's reasons, notes, the readings it
corrected and the candidate offsets it scored. Every stage adds to one :class:`Findings`, and the
result is made from it (:mod:`.pipeline`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..checks.conventions import Correction
from ..checks.selfcheck import Candidate
from ..checks.verdict import Reason, convention_corrected


@dataclass
class Findings:
    """What the pipeline learns on the way, for the result and the verdict. Its reasons are
    made by the rules of :mod:`.checks.verdict` only (test_layout checks it)."""

    warnings: list[str] = field(default_factory=list)
    reasons: list[Reason] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    corrections: list[Correction] = field(default_factory=list)
    candidates: list[Candidate] = field(default_factory=list)
    #: stage 2 named the eye's scale (a reason or a note): the batch stage does not again
    scale_named: bool = False

    def corrected(self, found: list[Correction]) -> None:
        """Readings of the input that were corrected: each a warning and a reason."""
        for c in found:
            self.corrections.append(c)
            self.warnings.append(c.message)
            self.reasons.append(convention_corrected(c.message))
