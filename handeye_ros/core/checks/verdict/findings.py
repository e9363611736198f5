"""What a step of the calibration found, as a frozen record it returns (:class:`Findings`): its
warnings, its notes and facts in the order found, the readings it corrected and the candidate
offsets it scored. The pipeline adds the stages' records in their order and hands the sum to the
verdict once (:func:`.final.judged`): no step writes into another's."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .codes import Reason
from .facts import ConventionCorrected, Fact

#: What a log holds: a note (a sentence that does not lower the verdict), a fact a stage
#: recorded, or a reason a rule made on the way.
Entry = str | Fact | Reason

if TYPE_CHECKING:  # the records of the checks, for the fields only
    from ..conventions import Correction
    from ..selfcheck import Candidate


@dataclass(frozen=True)
class Findings:
    """What one step found, or the steps so far (``a + b``: a's, then b's).

    ``log`` holds the notes (``str``: sentences that do not lower the verdict), the facts the
    stages recorded (:mod:`.facts`) and the reasons the rules made, in the order found: the
    verdict reads each fact into a reason or a note (:func:`.final.judged`; test_layout checks
    that no stage makes a reason). ``warnings`` go to the result as they are."""

    warnings: tuple[str, ...] = ()
    log: tuple[Entry, ...] = ()
    corrections: tuple[Correction, ...] = ()
    candidates: tuple[Candidate, ...] = ()

    def __add__(self, later: Findings) -> Findings:
        return Findings(
            self.warnings + later.warnings,
            self.log + later.log,
            self.corrections + later.corrections,
            self.candidates + later.candidates,
        )

    @classmethod
    def of(cls, *entries: Entry) -> Findings:
        """Notes, facts or reasons for the verdict, in this order."""
        return cls(log=entries)

    @classmethod
    def warned(cls, *texts: str, noted: bool = False) -> Findings:
        """Warnings for the result; ``noted``: each also a note of the verdict."""
        return cls(warnings=texts, log=texts if noted else ())

    @classmethod
    def corrected(cls, found: Iterable[Correction]) -> Findings:
        """Readings of the input that were corrected: each a warning and a fact."""
        found = tuple(found)
        return cls(
            warnings=tuple(c.message for c in found),
            log=tuple(ConventionCorrected(c.message) for c in found),
            corrections=found,
        )
