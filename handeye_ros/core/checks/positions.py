"""What a failed stage 2 says of the input's positions, when they, not the motion, are why
no motion agrees: positions in millimetres or centimetres (:func:`units_said`) or at a scale
(:func:`scale_said`), by the scale the rotations alone fit (``stages.scale.rotations_scale``:
no threshold in metres, so it holds in any units), and positions that hardly move
(:func:`still_said`). Each says '' when it has nothing to say: the refusal being explained then
stands as it is."""

from __future__ import annotations

import numpy as np

from ..linear.scale import ScaleFit
from ..trajectory import Trajectory

#: A failed stage 2 names positions in millimetres (centimetres) when the eye's translations
#: fit the hand's at a scale within this factor of 1000 (100) or its inverse
#: (:func:`units_said`): halfway, in log, to the next unit, and far beyond what a metric VIO is
#: off by.
MM_FACTOR = 10**0.5
#: The units a failed stage 2 names, by the decades between the streams' translations.
UNITS = {3: 'millimetres', 2: 'centimetres'}
#: A failed stage 2 names a scale when the rotations alone fit one beyond this factor of 1, by
#: 3 sigmas (:func:`scale_said`): the eye's relative translations then differ from the hand's by
#: at least their own length, far beyond RANSAC's 2 cm on motions of decimetres.
FAR_SCALE = 2.0
#: A failed stage 2 names a stream whose positions hardly move: their extent (5-95 %, widest
#: axis) below this share of the other stream's (:func:`still_said`), where they carry under a
#: hundredth of the motion the other stream's positions show, while the other's extent is at
#: least STILL_OTHER_M: a recording under way, not the still start of a live one, whose
#: refusal would stop auto mode (an input error is no recording's to remedy).
STILL_SHARE = 0.01
STILL_OTHER_M = 0.1


def _three_sigmas(fit: ScaleFit | None) -> tuple[float, float] | None:
    """The scale's bounds at 3 sigmas; None without a finite sigma."""
    if fit is None or not np.isfinite(fit.scale_std):
        return None
    return fit.scale - 3.0 * fit.scale_std, fit.scale + 3.0 * fit.scale_std


def scale_said(fit: ScaleFit | None) -> str:
    """What a failed stage 2 says of an eye at a scale: the rotations alone fit the eye's
    translations to the hand's at s beyond FAR_SCALE (or below its inverse) by 3 sigmas.
    Empty otherwise."""
    bounds = _three_sigmas(fit)
    if fit is None or bounds is None:
        return ''
    lo, hi = bounds
    if not (lo > FAR_SCALE or 0.0 < hi < 1.0 / FAR_SCALE):
        return ''
    return (
        f"The eye's translations fit the hand's at a scale s = {fit.scale:.4g} +- "
        f'{fit.scale_std:.2g} (s * eye positions metric; from the rotations alone): a '
        'monocular VO, or positions in other units. Estimate it with --scale (node parameter '
        'estimate_scale)'
    )


def still_said(hand: Trajectory, eye: Trajectory) -> str:
    """What a failed stage 2 says of a stream whose positions hardly move: their extent below
    STILL_SHARE of the other stream's, itself at least STILL_OTHER_M. Empty otherwise."""
    extents = {'hand': _extent(hand), 'eye': _extent(eye)}
    (still, small), (other, large) = sorted(extents.items(), key=lambda kv: kv[1])
    if not (small < STILL_SHARE * large and large >= STILL_OTHER_M):
        return ''
    return (
        f"The {still}'s positions stay within {small * 1e3:.2g} mm while the {other}'s span "
        f"{large:.2f} m: the translation of T_HE needs positions that follow the device's "
        'motion (a stream of orientations only, or of positions left constant, cannot give it'
        + ('; a monocular VO at such a scale needs --scale)' if still == 'eye' else ')')
    )


def _extent(t: Trajectory) -> float:
    """How far a stream's positions spread [m]: 5-95 % along the widest axis of the world."""
    lo, hi = np.percentile(t.p_xyz, [5.0, 95.0], axis=0)
    return float(np.max(hi - lo))


def units_said(fit: ScaleFit | None) -> str:
    """What a failed stage 2 says of positions in millimetres or centimetres: the eye's
    translations fitted to the hand's by the rotations alone (:func:`.scale.rotations_scale`) a
    factor of 1000 or 100 apart (:data:`UNITS`), within MM_FACTOR and beyond 3 sigmas of doubt,
    where a metric VIO is off by per cents. Empty otherwise."""
    bounds = _three_sigmas(fit)
    if fit is None or bounds is None or not bounds[0] > 0.0:
        return ''
    apart = float(np.log10(fit.scale))
    decades = round(abs(apart))
    if decades not in UNITS or np.any(
        np.abs(np.abs(np.log10(bounds)) - decades) > np.log10(MM_FACTOR)
    ):
        return ''
    which, other = ('hand', 'eye') if apart > 0 else ('eye', 'hand')
    return (
        f"The {which}'s translations are {10 ** abs(apart):.0f} times the {other}'s: its "
        f'positions look like {UNITS[decades]}. Write them in metres (or, for a monocular eye '
        'of unknown scale, estimate_scale)'
    )
