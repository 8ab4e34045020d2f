"""Gaussian filters of ISO 16610-21 (profiles) and ISO 16610-61 (areas), pure numpy/scipy.

The weighting function of the Gaussian filter with cut-off (nesting index) ``λc`` is

    s(x) = 1/(α λc) · exp(-π (x / (α λc))²),   α = sqrt(ln 2 / π),

whose amplitude transmission ``exp(-π (α λc / λ)²)`` is 50 % at ``λ = λc``. The areal filter
is the product of one such function per axis (ISO 16610-61), which makes it separable.

End effects: the filter keeps the full length. Near an end (and around missing data) the
weights that fall outside the data are left out and the remaining ones renormalised to a sum
of 1 — the zero-order (moment-retaining) end correction of ISO 16610-28, the same as a
Gaussian regression filter of order 0 (ISO 16610-31). With ``order=1`` a line (plane) is fitted
by Gaussian-weighted least squares at every point instead (the regression filter of order 1),
which keeps a tilted line or plane up to the ends. In the interior both are the plain
Gaussian filter. Periodic data are filtered circularly with the exact transfer function
(no ends, no truncation).

Heights arrive with the filtered axes last; NaN marks missing data, which stays NaN.
"""

from __future__ import annotations

import numpy as np

from ._lazy import Lazy

sfft, ndimage = Lazy("scipy.fft"), Lazy("scipy.ndimage")  # imported on first use (startup time, issue 26)

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


def _along(axis: int, ndim: int) -> list:
    """The shape that lays a 1D array along ``axis`` (≥ 0) of ``ndim`` axes, broadcastable against them."""
    return [-1 if i == axis else 1 for i in range(ndim)]


def _correlate(a: np.ndarray, w: np.ndarray, axis: int) -> np.ndarray:
    """``sum_j w[j] a[i + j - half]`` along ``axis``, zero outside the data (same length; ``w`` of odd length)."""
    if w.size <= _DIRECT:
        return ndimage.correlate1d(a, w, axis=axis, mode="constant", cval=0.0)
    n, half = a.shape[axis], w.size // 2
    m = sfft.next_fast_len(n + w.size - 1, real=True)
    fa = sfft.rfft(a, m, axis=axis)
    fa *= sfft.rfft(w[::-1], m).reshape(_along(axis, a.ndim))  # a convolution with the reversed kernel
    out = sfft.irfft(fa, m, axis=axis)
    return np.take(out, np.arange(half, half + n), axis=axis)


def _periodic(a: np.ndarray, cutoff: float, dx: float, axis: int) -> np.ndarray:
    """Circular Gaussian low-pass along ``axis`` with the exact transfer function."""
    n = a.shape[axis]
    f = sfft.rfftfreq(n, dx)  # cycles per length
    return sfft.irfft(sfft.rfft(a, axis=axis) * np.exp(-np.pi * (ALPHA * cutoff * f) ** 2).reshape(
        _along(axis, a.ndim)), n, axis=axis)


def gaussian_lowpass(h: np.ndarray, cutoffs, spacings, periodic: bool = False, order: int = 0) -> np.ndarray:
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
        Filter circularly (periodic data); otherwise with an end correction.
    order : {0, 1}
        End correction: 0 renormalises the weights inside the data (the Gaussian regression
        filter of order 0); 1 fits a line (a plane for maps) by Gaussian-weighted least squares
        at every point (order 1), which keeps a straight line or plane exactly up to the ends.
        Both are the plain Gaussian filter where the whole kernel lies on data.

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
    kernels = []
    for axis, c, d in axes:
        w = weights(c, d)
        half = w.size // 2
        kernels.append((axis, w, np.arange(-half, half + 1) / max(half, 1)))  # offsets scaled to [-1, 1]
    data = np.where(missing, 0.0, h)
    present = (~missing).astype(float) if missing.any() else None
    k = len(kernels)
    unit = [tuple(int(i == j) for j in range(k)) for i in range(k)]  # the powers of x (and y)
    t = [_moment(data, kernels, (0,) * k)] + [_moment(data, kernels, p) for p in (unit if order else [])]
    s0 = _weights_moment(present, h.shape, kernels, (0,) * k)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = t[0] / s0
        if order and k:
            num, det, scale = _regression(t, lambda *p: _weights_moment(present, h.shape, kernels, p))
            solvable = np.abs(det) > 1e-9 * np.abs(scale)  # a lone point or a line of points: order 0 there
            out = np.where(solvable, num / np.where(solvable, det, 1.0), out)
    out[missing] = np.nan
    return out


def _regression(t, s):
    """Numerator and determinant (Cramer's rule) of the intercept of the local weighted least-squares line/plane.

    ``t``: the data moments (Σw·z, Σw·z·u, Σw·z·v); ``s(*powers)``: the weight moments. Also
    returns the product of the normal matrix's diagonal, the scale of its determinant.
    """
    if len(t) == 2:  # a line: [[s0, s1], [s1, s2]]
        s0, s1, s2 = s(0), s(1), s(2)
        return t[0] * s2 - s1 * t[1], s0 * s2 - s1 * s1, s0 * s2
    s00, s10, s01, s20, s11, s02 = s(0, 0), s(1, 0), s(0, 1), s(2, 0), s(1, 1), s(0, 2)
    minor = s20 * s02 - s11 * s11
    det = s00 * minor - s10 * (s10 * s02 - s11 * s01) + s01 * (s10 * s11 - s20 * s01)
    num = t[0] * minor - s10 * (t[1] * s02 - s11 * t[2]) + s01 * (t[1] * s11 - s20 * t[2])
    return num, det, s00 * s20 * s02


def _moment(a, kernels, powers):
    """``a`` correlated along each filtered axis with the weights times the scaled offsets to ``powers``."""
    for (axis, w, u), p in zip(kernels, powers):
        a = _correlate(a, w * u**p, axis)
    return a


def _weights_moment(present, shape, kernels, powers):
    """:func:`_moment` of the present points; without missing data a product of 1D vectors (broadcastable)."""
    if present is not None:
        return _moment(present, kernels, powers)
    out = 1.0
    for (axis, w, u), p in zip(kernels, powers):
        out = out * _correlate(np.ones(shape[axis]), w * u**p, 0).reshape(_along(axis, len(shape)))
    return out
