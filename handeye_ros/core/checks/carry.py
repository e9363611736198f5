"""The readiness a calibration's result carries: READY only when that result is ``good``.

:mod:`.readiness` predicts the 1-sigmas a calibration would report from the consecutive eye
pairs, which see neither the errors a real VIO correlates over minutes nor its scale (on real
recordings the predictions are 0.1-0.6 of the reported sigmas). Once a result exists, its
reported over its own predicted sigmas on the same data (:func:`predictor_factors`) carry those
terms into every later prediction, and its reasons hold READY back until a result is ``good``
(:func:`carry_over`). The node's status carries its last result's (``ros/auto_mode.py``); a
result carries its own (:func:`carried`), so that its ``readiness`` section never says READY
beside a ``doubtful`` verdict and its sigmas are the reported ones.
"""

from __future__ import annotations

import numpy as np

from ..document import ReadinessDoc, ResultDoc
from .verdict import Code, sigmas_of

#: The readiness's sigma keys (ms, mm, deg), in the order of :func:`sigmas_of`.
SIGMA_KEYS = ('time_offset_ms', 'translation_mm', 'rotation_deg')


def predictor_factors(document: ResultDoc) -> dict[str, float]:
    """A result's reported 1-sigmas over the ones its own ``readiness`` predicted on the same
    data (``readiness.predicted``), per sigma key: how far the predictions fall short of the
    result's covariance on this recording, or exceed it. Empty without both."""
    std, readiness = document.get('std'), document.get('readiness')
    predicted = readiness['predicted'] if readiness else {}
    if not std or not predicted:
        return {}
    reported = sigmas_of(np.r_[std['time_offset'], std['translation'], std['rotation']])
    out = {}
    for key, value, k in zip(SIGMA_KEYS, reported, (1e3, 1e3, 1.0), strict=True):
        p = predicted.get(key)
        if p and np.isfinite(value) and value > 0.0:
            out[key] = value * k / p
    return out


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


def recording_remedies(doc: ResultDoc) -> bool:
    """Whether more of the same recording is the remedy for all that holds ``doc`` back
    (:func:`held_reasons`): its precision, and sigmas that lack the blocks' term."""
    return all(r['code'] == Code.IMPRECISE.value for r in doc['quality']['reasons'])


def held_words(first: str) -> str:
    """What holds READY back, said after a result's name, from the first of
    :func:`held_reasons`."""
    return first if first == LACKS_BLOCKS else f'is doubtful: {first}'


def carry_over(
    last: ReadinessDoc,
    factors: dict[str, float],
    held: list[str],
    whose: str = 'the last calibration',
    margin: float = 1.0,
    sigmas_decide: bool = True,
) -> ReadinessDoc:
    """The readiness ``last`` with its predicted sigmas (``predicted``) times a result's
    :func:`predictor_factors` as its ``sigma`` (the same covariance model as the result's),
    READY only if they still meet the targets (each times ``margin``: BLOCKS_MARGIN when they
    are carried to more data than the result's) and the result was ``good`` (``held``: the
    messages of its reasons, :func:`held_reasons`, the first said first); ``whose`` names the
    result in what is said; ``sigmas_decide`` False (purpose evaluation): the carried sigmas
    are shown and the result's verdict alone decides."""
    if not factors and not held:
        return last
    sigma = {
        k: (v * factors.get(k, 1.0) if v is not None else v) for k, v in last['predicted'].items()
    }
    target = last['target']
    meets = not sigmas_decide or all(
        v is not None and v <= margin * target[k] for k, v in sigma.items()
    )
    missing = list(last['missing'])
    if last['ready'] and not meets and not held:
        said = ', '.join(
            f'{k.rsplit("_", 1)[0].replace("_", " ")} x{f:.2g}' for k, f in factors.items()
        )
        inside = '' if margin == 1.0 else f' (READY within {margin:.0%} of the targets)'
        missing.insert(
            0,
            f"keep recording: {whose}'s sigmas were its predictions times {said} (errors of "
            f'the eye that consecutive poses do not show), and so are these{inside}',
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
    return carry_over(
        last,
        predictor_factors(document),
        held_reasons(document),
        'this calibration',
        sigmas_decide=document['quality']['purpose'] == 'extrinsic',
    )
