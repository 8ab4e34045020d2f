"""Scale-dependent finite differences (paper eq. 9 and its second-order analogue).

``D^(η) h(x) = (h(x+ηΔx) - h(x)) / (ηΔx)`` and
``D²^(η) h(x) = (h(x+ηΔx) - 2h(x) + h(x-ηΔx)) / (ηΔx)²`` along the last axis.
Fractional scale factors ``η`` interpolate the heights linearly between samples.
Periodic data wrap around; nonperiodic data keep only the points whose stencil
lies inside the data.
"""

from __future__ import annotations

import numpy as np
from ._lazy import LazyJit

from .spectra import check_finite

njit = LazyJit(globals())  # numba imported, the kernels wrapped, on first use (startup time, issue 26)

__all__ = ["scaled_difference", "sdrp_rms", "max_negative_curvature"]


def _stencil(eta, order: int, periodic: bool, n: int, pad: int):
    """``(k, f, start, count)`` of scale factor(s) ``eta``: ``η = k + f`` (``f`` in [0, 1)) and the stencil
    positions ``m = start..start+count-1`` of a profile of ``n`` points (wrapped by ``pad`` values each side when
    periodic; ``count ≤ 0``: no stencil fits)."""
    k = np.floor(eta + 1e-12).astype(np.int64)
    f = np.where(eta - k < 1e-12, 0.0, eta - k)
    if periodic:
        return k, f, np.full_like(k, pad), np.full_like(k, n)
    reach = np.ceil(eta - 1e-12).astype(np.int64)
    start = reach if order == 2 else np.zeros_like(k)
    return k, f, start, n - reach - start


def _shifted(h: np.ndarray, a: int, f: float, count: int, sign: int) -> np.ndarray:
    """Linear interpolant of ``h`` at ``m + sign·f`` for ``m = a..a+count-1`` (no wrap)."""
    out = h[..., a:a + count]
    if f:
        b = a + sign
        out = (1 - f) * out + f * h[..., b:b + count]
    return out


def scaled_difference(h: np.ndarray, eta: float, *, order: int, periodic: bool) -> np.ndarray:
    """The scaled derivative field ``D^(η) h`` (order 1) or ``D²^(η) h`` (order 2), in units of 1/Δx^order.

    Multiply by ``1/Δx`` (order 1) or ``1/Δx²`` (order 2) for physical units.
    """
    n = h.shape[-1]
    pad = int(np.ceil(eta - 1e-12)) + 1
    if periodic:
        h = np.concatenate([h[..., n - pad:], h, h[..., :pad]], axis=-1) if pad <= n else np.pad(
            h, [(0, 0)] * (h.ndim - 1) + [(pad, pad)], mode="wrap")
    k, f, start, count = (v.item() for v in _stencil(np.float64(eta), order, periodic, n, pad))
    if count <= 0:
        return np.empty(h.shape[:-1] + (0,))
    centre = h[..., start:start + count]
    fwd = _shifted(h, start + k, f, count, +1)
    if order == 1:
        return (fwd - centre) / eta
    bwd = _shifted(h, start - k, f, count, -1)
    return (fwd - 2 * centre + bwd) / eta**2


_SUM = dict(nogil=True, cache=True, fastmath={"reassoc", "nsz"})   # sums may be vectorised (reordered)


@njit(**_SUM)
def _diff(row, start, a, b, count, g, f, squares, second):
    """``Σ d²`` or ``min d`` of ``d = h(m+η) - h(m)``, or with ``second`` ``h(m+η) - 2h(m) + h(m-η)``, over
    ``m = start..start+count-1``: ``h(m+η) = g·h[a+m] + f·h[a+1+m]``, ``h(m-η) = g·h[b+m] + f·h[b-1+m]``.

    The loops run over contiguous slices (no index arithmetic in them), which vectorises them.
    """
    acc = 0.0 if squares else np.inf
    c = row[start:start + count]
    x = row[a:a + count]
    z = row[b:b + count]
    if f == 0.0:
        for m in range(count):
            d = x[m] - 2 * c[m] + z[m] if second else x[m] - c[m]
            acc = acc + d * d if squares else min(acc, d)
    else:
        y = row[a + 1:a + 1 + count]
        w = row[b - 1:b - 1 + count]
        for m in range(count):
            d = (g * x[m] + f * y[m]) - 2 * c[m] + (g * z[m] + f * w[m]) if second else (g * x[m] + f * y[m]) - c[m]
            acc = acc + d * d if squares else min(acc, d)
    return acc


@njit(nogil=True, cache=True)
def _scaled_stats(h, k, f, start, count, second, pad, squares):
    """Per leading index ``l`` of ``h`` (shape ``(L, R, n)``) and scale ``η`` (its :func:`_stencil` arrays
    ``k, f, start, count``): ``Σ d²`` over all ``R`` profiles (``squares``) or ``min d``, ``d`` the difference
    (``second``: of order 2) at ``η`` without its ``1/η^order``. Periodic profiles (``pad > 0``) are wrapped by
    ``pad`` values each side into one buffer, which stays in cache over all the scales."""
    n_lead, n_rows, n = h.shape
    out = np.zeros((n_lead, k.size)) if squares else np.full((n_lead, k.size), np.inf)
    row = np.empty(n + 2 * pad)
    for lead in range(n_lead):
        for r in range(n_rows):
            src = h[lead, r]
            if pad:
                for j in range(n + 2 * pad):
                    row[j] = src[(j - pad) % n]
                src = row
            for e in range(k.size):
                if count[e] <= 0:
                    continue
                acc = _diff(src, start[e], start[e] + k[e], start[e] - k[e], count[e], 1.0 - f[e], f[e], squares,
                            second)
                out[lead, e] = out[lead, e] + acc if squares else min(out[lead, e], acc)
    return out


def _stats(h, etas, order, periodic, rows, squares):
    """``h`` as float64 ``(L, R, n)`` profiles (leading, reduced ``rows`` and profile axes), its leading shape, the
    scale factors ``etas`` as an array, their stencil counts per profile and :func:`_scaled_stats` of them."""
    h = np.ascontiguousarray(h, dtype=float)
    lead = h.shape[: h.ndim - 1 - rows]
    h3 = h.reshape(int(np.prod(lead, dtype=int)), -1, h.shape[-1])
    etas = np.asarray(etas, dtype=float).reshape(-1)
    pad = int(np.ceil(etas.max() - 1e-12)) + 1 if periodic and etas.size else 0
    k, f, start, count = _stencil(etas, order, periodic, h3.shape[-1], pad)
    return h3, lead, etas, count, _scaled_stats(h3, k, f, start, count, order == 2, pad, squares)


def sdrp_rms(h: np.ndarray, dx: float, etas, *, order: int, periodic: bool, rows: int) -> np.ndarray:
    """RMS of the scaled derivative at each ``η`` in ``etas``, over profiles and ``rows`` leading axes.

    Returns shape ``(..., len(etas))`` in units of 1/Δx^order; NaN where no stencil fits.
    One compiled pass per profile covers all the scales (:func:`_scaled_stats`); the values are
    those of :func:`scaled_difference` (to rounding).
    """
    check_finite(h, "sdrp")
    h3, lead, etas, count, sums = _stats(h, etas, order, periodic, rows, True)
    count = count * h3.shape[1]
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.where(count > 0, np.sqrt(sums / np.maximum(count, 1)) / etas**order, np.nan)
    return rms.reshape(lead + (etas.size,)) / dx**order


def max_negative_curvature(h: np.ndarray, dx: float, etas, *, periodic: bool, rows: int) -> np.ndarray:
    """``max_x[-D²^(η) h]`` at each ``η`` (paper eq. 13), shape ``(..., len(etas))``, units 1/length.

    ``-inf`` where no stencil fits; one compiled pass as in :func:`sdrp_rms`.
    """
    check_finite(h, "reliability")
    _, lead, etas, _, low = _stats(h, etas, 2, periodic, rows, False)
    return (-low / etas**2).reshape(lead + (etas.size,)) / dx**2
