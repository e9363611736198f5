"""The readiness a calibration's result carries: READY only when that result is ``good``.

:mod:`.readiness` predicts the 1-sigmas a calibration would report from the consecutive eye
pairs, which see neither the errors a real VIO correlates over minutes nor its scale (on real
recordings the predictions are 0.1-0.6 of the reported sigmas). Once a result exists, its
covariance's terms carry into every later prediction (:class:`Carried`, :func:`carried_terms`):
the white and scale terms shrink as the predictions do, the correlated term is carried as it
is; and its reasons hold READY back until a result is ``good`` (:func:`carry_over`). The
node's status carries its last result's (``ros/auto_mode.py``); a result carries its own
(:func:`carried`), so that its ``readiness`` section never says READY beside a ``doubtful``
verdict and its sigmas are the reported ones.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..batch.correlated import BLOCKS
from ..document import ReadinessDoc, ResultDoc
from .verdict import Code

#: The readiness's sigma keys (ms, mm, deg), in the order of :func:`~.verdict.sigmas_of`; the
#: uncertainty's group of each, and its unit per SI unit.
SIGMA_KEYS = ('time_offset_ms', 'translation_mm', 'rotation_deg')
_GROUPS = {
    'time_offset_ms': ('time_offset', 1e3),
    'translation_mm': ('translation', 1e3),
    'rotation_deg': ('rotation', float(np.degrees(1.0))),
}
#: Predictions carried from a result to more data are READY only this far inside the targets: a
#: calibration of more data reports sigmas that the blocks' spread measures again, a 1-sigma
#: of three axes with BLOCKS - 1 degrees of freedom each, uncertain by 1 / sqrt(2 dof) of
#: itself (0.24: READY at most 0.81 of each target). Without it, a READY carried from a
#: `good` result at 9.5 mm said so of data whose own calibration reported 10.4 mm.
CARRIED_MARGIN = 1.0 / (1.0 + 1.0 / np.sqrt(2.0 * 3 * (BLOCKS - 1)))


@dataclass(frozen=True)
class Carried:
    """What a result's covariance says of the 1-sigmas of more data, per sigma key (SIGMA_KEYS,
    in the keys' units).

    scaled: the result's white and scale terms over what its own readiness predicted on the
    same data: those terms shrink with more data as the consecutive pairs' predictions do;
    held: its correlated term (what the long-run and the blocks add to the white one), errors
    the eye correlates over seconds to minutes that the pairs do not see and more of the same
    recording does not average down at their pace: carried as it is.
    """

    scaled: dict[str, float] = field(default_factory=dict)
    held: dict[str, float] = field(default_factory=dict)

    def sigma(self, key: str, predicted: float) -> float:
        """The 1-sigma of ``key`` for data whose pairs predict ``predicted``."""
        return float(np.hypot(predicted * self.scaled.get(key, 1.0), self.held.get(key, 0.0)))

    def said(self) -> str:
        """The carried terms in words: 'time offset x1.1, translation x1.2 with 8.1 mm held'."""
        parts = []
        for key in SIGMA_KEYS:
            if key not in self.scaled:
                continue
            name, unit = key.rsplit('_', 1)
            held = self.held.get(key, 0.0)
            parts.append(
                f'{name.replace("_", " ")} x{self.scaled[key]:.2g}'
                + (f' with {held:.2g} {unit} held' if held > 0.0 else '')
            )
        return ', '.join(parts)


def carried_terms(document: ResultDoc) -> Carried:
    """A result's :class:`Carried`: its reported 1-sigmas' terms (``std.terms``) against the
    1-sigmas its own ``readiness`` predicted on the same data (``readiness.predicted``). Empty
    without both; a result without terms carries its whole reported sigmas as ``scaled``."""
    std, readiness = document.get('std'), document.get('readiness')
    predicted = readiness['predicted'] if readiness else {}
    if not std or not predicted:
        return Carried()
    terms = std.get('terms')
    axes = {
        'time_offset': [std['time_offset']],
        'translation': std['translation'],
        'rotation': std['rotation'],
    }
    scaled, held = {}, {}
    for key, (group, k) in _GROUPS.items():
        p = predicted.get(key)
        if terms:
            t = terms[group]
            moving, correlated = np.hypot(t['white'], t['scale']) * k, t['correlated'] * k
        else:
            moving, correlated = float(np.linalg.norm(axes[group])) * k, 0.0
        if p and np.isfinite(moving) and moving > 0.0:
            scaled[key], held[key] = float(moving / p), float(correlated)
    return Carried(scaled, held)


#: Why a result whose sigmas lack the blocks' term holds READY back.
LACKS_BLOCKS = (
    'lacks in its sigmas the errors a VIO correlates over minutes (too few eye poses for the '
    'four blocks that measure them yet): more recording adds them'
)


def held_reasons(doc: ResultDoc) -> list[str]:
    """The messages of a result's reasons, its precision's last (more recording is the remedy
    for that one alone), and last of all LACKS_BLOCKS when its covariance could not gain the
    blocks' term: a result that is not ``good`` holds READY back until a calibration of more
    data is, since READY says that a calibration now would be ``good``, and predictions carried
    from a result that was not, or whose sigmas miss the term that dominates them on a real
    VIO, are a coin toss near the targets."""
    reasons = sorted(doc['quality']['reasons'], key=lambda r: r['code'] == Code.IMPRECISE.value)
    std = doc.get('std')
    lacking = std is not None and 'block_factors' in std and std['block_factors'] is None
    return [r['message'] for r in reasons] + [LACKS_BLOCKS] * lacking


def held_words(first: str) -> str:
    """What holds READY back, said after a result's name, from the first of
    :func:`held_reasons`."""
    return first if first == LACKS_BLOCKS else f'is doubtful: {first}'


def carry_over(
    last: ReadinessDoc,
    terms: Carried,
    held: list[str],
    whose: str = 'the last calibration',
    margin: float = 1.0,
) -> ReadinessDoc:
    """The readiness ``last`` with its predicted sigmas (``predicted``) carried through a
    result's :class:`Carried` ``terms`` as its ``sigma`` (the same covariance model as the
    result's), READY only if they still meet the targets (each times ``margin``: CARRIED_MARGIN
    when they are carried to more data than the result's) and the result was ``good``
    (``held``: the messages of its reasons, :func:`held_reasons`, the first said first);
    ``whose`` names the result in what is said."""
    if not terms.scaled and not held:
        return last
    sigma = {k: (terms.sigma(k, v) if v is not None else v) for k, v in last['predicted'].items()}
    target = last['target']
    meets = all(v is not None and v <= margin * target[k] for k, v in sigma.items())
    missing = list(last['missing'])
    if last['ready'] and not meets and not held:
        inside = '' if margin == 1.0 else f' (READY within {margin:.0%} of the targets)'
        missing.insert(
            0,
            f"keep recording: {whose}'s sigmas were its predictions times {terms.said()} "
            '(errors of the eye that consecutive poses do not show; the held ones are correlated '
            f'over the recording, and more of it does not average them down), and so are '
            f'these{inside}',
        )
    if held:
        missing.insert(0, f'{whose} {held_words(held[0])}')
    ready = bool(last['ready'] and meets and not held)
    return {**last, 'sigma': sigma, 'ready': ready, 'missing': missing}


def carried(document: ResultDoc) -> ReadinessDoc | None:
    """A result's ``readiness`` carried over with the result itself: its sigmas the reported
    ones, READY only when the result is ``good`` and the predictions were READY."""
    last = document.get('readiness')
    if last is None:
        return None
    return carry_over(last, carried_terms(document), held_reasons(document), 'this calibration')
