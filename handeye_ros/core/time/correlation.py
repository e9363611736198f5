"""The correlation of stage 1 (eq. 1): a masked normalised cross-correlation by FFT, and the
shape of its curve: the sub-sample vertex of the peak (the paper's quadratic fit), the peak's
lobe, and how high the curve rises outside it.
"""

from __future__ import annotations

import numpy as np
from scipy import fft

from ..arrays import Floats, Indices, Mask
from ..geometry import row_sums


def masked_normalised_correlation(
    y: Floats, my: Mask, x: Floats, mx: Mask
) -> tuple[Indices, Floats, Floats]:
    """Pearson correlation of ``y[k + lag]`` with ``x[k]`` over the samples valid in both.

    For each lag the means and variances are those of the overlapping valid samples only
    (Padfield's masked normalised cross-correlation), all sums computed by FFT. Multichannel
    signals (shape (n, C)) are correlated as vectors: ``sum_c cov_c / sqrt(sum_c var_y,c *
    sum_c var_x,c)`` over the shared mask.

    Returns
    -------
    lags : ndarray of int, shape (len(y) + len(x) - 1,)
    ncc : ndarray, same shape, NaN where the overlap has no variance
    overlap : ndarray, same shape, number of samples valid in both
    """
    y2: Floats = y.reshape(y.shape[0], -1) * my[:, None]
    x2: Floats = x.reshape(x.shape[0], -1) * mx[:, None]
    fy, fx = my.astype(float), mx.astype(float)
    ny, nx = y2.shape[0], x2.shape[0]
    # One zero-padded FFT per signal, then every sum is a product of spectra. (scipy.fft
    # rather than scipy.signal, whose import alone takes a second.)
    nfft = fft.next_fast_len(ny + nx - 1, real=True)

    def fwd(v: Floats) -> Floats:
        out: Floats = fft.rfft(v, nfft, axis=0)
        return out

    def corr(A: Floats, B: Floats) -> Floats:
        c = fft.irfft(A * B, nfft, axis=0)  # c[L] = sum_m a[m + L] b[m], negative L wrapped
        return np.concatenate((c[nfft - (nx - 1) :], c[:ny]))

    FY, FX = fwd(fy), np.conj(fwd(fx))
    Y, X = fwd(y2), np.conj(fwd(x2))
    YY = fwd(row_sums(y2 * y2))
    XX = np.conj(fwd(row_sums(x2 * x2)))
    n = np.rint(corr(FY, FX))
    sy = corr(Y, FX[:, None])
    sx = corr(FY[:, None], X)
    syy, sxx = corr(YY, FX), corr(FY, XX)
    sxy = corr(row_sums(Y * X), np.ones(1))
    with np.errstate(divide='ignore', invalid='ignore'):
        cov = sxy - row_sums(sy * sx) / n
        var = (syy - row_sums(sy * sy) / n) * (sxx - row_sums(sx * sx) / n)
        ncc = np.where((n > 1) & (var > 0.0), cov / np.sqrt(np.abs(var)), np.nan)
    lags = np.arange(-(nx - 1), ny)
    return lags, ncc, n


def parabola_vertex(c_minus: float, c0: float, c_plus: float) -> float:
    """Sub-sample position, in (-0.5, 0.5), of the vertex of the parabola through 3 samples."""
    den = c_minus - 2.0 * c0 + c_plus
    if not den < 0.0:  # flat or not a maximum: keep the integer peak
        return 0.0
    return float(np.clip(0.5 * (c_minus - c_plus) / den, -0.5, 0.5))


def lobe(scores: Floats, k: int) -> tuple[int, int]:
    """First and last index of the peak's lobe (bounded by the nearest local minima)."""
    d = np.diff(np.where(np.isfinite(scores), scores, -2.0))  # ineligible lags: below any NCC
    left = np.flatnonzero(d[:k] < 0.0)  # a rise towards the left of the peak ends the lobe
    right = np.flatnonzero(d[k:] > 0.0)
    lo = left[-1] + 1 if left.size else 0
    hi = k + right[0] if right.size else scores.size - 1
    return int(lo), int(hi)


def second_peak_ratio(scores: Floats, k: int) -> float:
    """Best correlation outside the main lobe (bounded by the nearest local minima) over peak."""
    lo, hi = lobe(scores, k)
    outside = np.concatenate((scores[:lo], scores[hi + 1 :]))
    outside = outside[np.isfinite(outside)]
    if not outside.size or scores[k] <= 0.0:
        return 0.0
    return float(max(outside.max(), 0.0) / scores[k])
