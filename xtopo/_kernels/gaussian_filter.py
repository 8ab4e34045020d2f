"""Gaussian filters of ISO 16610-21 (profiles) and ISO 16610-61 (areas), pure numpy/scipy.

The weighting function of the Gaussian filter with cut-off (nesting index) ``λc`` is

    s(x) = 1/(α λc) · exp(-π (x / (α λc))²),   α = sqrt(ln 2 / π),

whose amplitude transmission ``exp(-π (α λc / λ)²)`` is 50 % at ``λ = λc``. The areal filter
is the product of one such function per axis (ISO 16610-61), which makes it separable.

End effects: the filter keeps the full length. Near an end (and around missing data) the
weights that fall outside the data are left out and the remaining ones renormalised to a sum
of 1 — the zero-order (moment-retaining) end correction of ISO 16610-28, the same as a
Gaussian regression filter of order 0 (ISO 16610-31). In the interior this is the plain
Gaussian filter. Periodic data are filtered circularly with the exact transfer function
(no ends, no truncation).

Heights arrive with the filtered axes last; NaN marks missing data, which stays NaN.
"""

from __future__ import annotations

import functools

import numpy as np
import scipy.fft as sfft
from scipy import ndimage

__all__ = ["ALPHA", "TRUNCATION", "weights", "transmission", "gaussian_lowpass"]

#: constant of the Gaussian weighting function, ISO 16610-21 eq. (1)
ALPHA = float(np.sqrt(np.log(2) / np.pi))
#: the weighting function is truncated at ``|x| <= TRUNCATION · λc`` (its relative weight there is 6.5e-7)
TRUNCATION = 1.0
#: kernels up to this many points are applied by direct convolution, longer ones through the FFT
_DIRECT = 63


def weights(cutoff: float, dx: float) -> np.ndarray:
    """The sampled Gaussian weighting function for ``cutoff`` on spacing ``dx``, summing to 1 (odd length)."""
    half = int(np.floor(TRUNCATION * cutoff / dx))
    x = np.arange(-half, half + 1) * dx
    w = np.exp(-np.pi * (x / (ALPHA * cutoff)) ** 2)
    return w / w.sum()


def transmission(wavelength, cutoff: float):
    """Amplitude transmission of the (continuous) Gaussian low-pass at ``wavelength``: 0.5 at the cut-off."""
    with np.errstate(divide="ignore", over="ignore"):
        return np.exp(-np.pi * (ALPHA * cutoff / np.asarray(wavelength, dtype=float)) ** 2)


def _convolve(a: np.ndarray, w: np.ndarray, axis: int) -> np.ndarray:
    """``a`` convolved with the symmetric ``w`` along ``axis``, zero outside the data (same length)."""
    if w.size <= _DIRECT:
        return ndimage.correlate1d(a, w, axis=axis, mode="constant", cval=0.0)
    n, half = a.shape[axis], w.size // 2
    m = sfft.next_fast_len(n + w.size - 1, real=True)
    fa = sfft.rfft(a, m, axis=axis)
    shape = [1] * a.ndim
    shape[axis] = -1
    fa *= sfft.rfft(w, m).reshape(shape)
    out = sfft.irfft(fa, m, axis=axis)
    return np.take(out, np.arange(half, half + n), axis=axis)


def _periodic(a: np.ndarray, cutoff: float, dx: float, axis: int) -> np.ndarray:
    """Circular Gaussian low-pass along ``axis`` with the exact transfer function."""
    n = a.shape[axis]
    f = sfft.rfftfreq(n, dx)  # cycles per length
    shape = [1] * a.ndim
    shape[axis] = -1
    return sfft.irfft(sfft.rfft(a, axis=axis) * np.exp(-np.pi * (ALPHA * cutoff * f) ** 2).reshape(shape), n,
                      axis=axis)


def gaussian_lowpass(h: np.ndarray, cutoffs, spacings, periodic: bool = False) -> np.ndarray:
    """The Gaussian mean line (profiles) or mean surface (areas) of ``h``.

    Parameters
    ----------
    h : numpy.ndarray
        Heights; the last ``len(cutoffs)`` axes are filtered, NaN marks missing data.
    cutoffs : sequence of float or None
        Cut-off wavelength per filtered axis (in the unit of ``spacings``); None leaves that
        axis unfiltered.
    spacings : sequence of float
        Sampling distance per filtered axis.
    periodic : bool
        Filter circularly (periodic data); otherwise with the renormalised end correction.

    Returns
    -------
    numpy.ndarray
        The low-pass (float64, same shape); NaN where ``h`` is NaN.
    """
    h = np.asarray(h, dtype=float)
    missing = np.isnan(h)
    axes = [(h.ndim - len(cutoffs) + i, c, d) for i, (c, d) in enumerate(zip(cutoffs, spacings)) if c is not None]
    if periodic and not missing.any():
        out = h
        for axis, c, d in axes:
            out = _periodic(out, c, d, axis)
        return out
    num = np.where(missing, 0.0, h)
    # the weights present: the same for every line when nothing is missing, so one line of them is enough
    den = (~missing).astype(float) if missing.any() else None
    den_axes = []
    for axis, c, d in axes:
        w = weights(c, d)
        num = _convolve(num, w, axis)
        if den is not None:
            den = _convolve(den, w, axis)
        else:
            ones = np.ones(h.shape[axis])
            shape = [1] * h.ndim
            shape[axis] = -1
            den_axes.append(_convolve(ones, w, 0).reshape(shape))
    if den is None:
        den = functools.reduce(np.multiply, den_axes, 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = num / den
    out[missing] = np.nan
    return out
