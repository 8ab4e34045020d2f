"""Variable bandwidth method (paper §4.8): tilt-corrected RMS height in blocks.

The map is cut into ``ζ × ζ`` blocks (``ζ`` segments for profiles) with block
boundaries ``floor(i N/ζ)``; for ``ζ = 2^k`` the blocks of level ``k`` are
unions of blocks of level ``k+1``. Block sums are therefore computed once on the
finest level and merged upwards, with moments about each block's centre so the
plane fit stays well conditioned.
"""

from __future__ import annotations

import functools
import operator

import numpy as np
from ._lazy import LazyJit

from .spectra import check_finite

njit = LazyJit(globals())  # numba imported, the kernels wrapped, on first use (startup time, issue 26)

__all__ = ["vbm_levels", "vbm"]


def vbm_levels(sizes, min_pixels: int = 4) -> np.ndarray:
    """Magnifications ``ζ = 1, 2, 4, …`` whose blocks keep at least ``min_pixels`` along every axis."""
    k = max((int(min(sizes)) // int(min_pixels)).bit_length() - 1, 0)  # the largest k with n // 2**k >= min_pixels
    return 2 ** np.arange(k + 1)


@njit(nogil=True, cache=True)
def _row_blocks(h, starts, xl):
    """Σh, Σx̂h and Σh² over the blocks of each row of ``h`` (2D, rows × n) in one pass, summed in order."""
    rows, n = h.shape
    zeta = starts.size
    s0 = np.empty((rows, zeta))
    s1 = np.empty((rows, zeta))
    s2 = np.empty((rows, zeta))
    for r in range(rows):
        for j in range(zeta):
            lo = starts[j]
            hi = starts[j + 1] if j + 1 < zeta else n
            a = 0.0
            b = 0.0
            c = 0.0
            for i in range(lo, hi):
                v = h[r, i]
                a += v
                b += v * xl[i]
                c += v * v
            s0[r, j] = a
            s1[r, j] = b
            s2[r, j] = c
    return s0, s1, s2


def _geometry(n, zeta):
    """Block starts, widths, centres and each pixel's offset x̂ from its block's centre (pixels)."""
    b = (np.arange(zeta) * n) // zeta
    w = np.diff(np.append(b, n))
    centre = b + (w - 1) / 2
    return b, w, centre, np.arange(n) - np.repeat(centre, w)


def _merge(arrs, w, centre, axis):
    """Merge pairs of neighbouring blocks along ``axis``: moments about the parent centre.

    ``arrs`` maps moment name to arrays: ``"s0"`` Σh, ``"s2"`` Σh², an axis number its first
    moments Σx̂h along that axis (these get the shift term).
    """
    wp = w[0::2] + w[1::2]
    start = centre[0::2] - (w[0::2] - 1) / 2
    cp = start + (wp - 1) / 2
    shape = [1] * arrs["s0"].ndim
    shape[axis] = len(centre)
    shift = (centre - np.repeat(cp, 2)).reshape(shape)
    even, odd = ((slice(None),) * axis + (slice(k, None, 2),) for k in (0, 1))
    out = {}
    for name, a in arrs.items():
        a = a + shift * arrs["s0"] if name == axis else a
        out[name] = a[even] + a[odd]
    return out, (wp, cp)


def vbm(h: np.ndarray, levels, *, ndim: int, quadratic: bool = False) -> np.ndarray:
    """Mean tilt-corrected RMS height ⟨h_rms⟩ at each magnification ``ζ`` in ``levels``.

    The plane is fitted in pixel units: its residuals, and so the result, do not depend on the
    spacings (a plane in ``x/Δx``, ``y/Δy`` is a plane in ``x``, ``y``), square pixels or not.

    Parameters
    ----------
    h : ndarray, shape (..., [ny,] nx)
    levels : sequence of int
        Powers of two, ascending (see :func:`vbm_levels`).
    ndim : int
        1 for profiles, 2 for maps.
    quadratic : bool
        Square root of the mean square over all pixels of the blocks (SurfaceTopography)
        instead of the arithmetic mean of the blocks' RMS heights (paper §4.8).

    Returns
    -------
    ndarray, shape (..., len(levels))
    """
    check_finite(h, "vbm")
    h = np.asarray(h, dtype=float)
    axes = tuple(range(h.ndim - ndim, h.ndim))
    h = h - h.mean(axis=axes, keepdims=True)
    levels = [int(z) for z in levels]
    zmax = levels[-1]
    # reduce along the last axis first (the expensive pass: one compiled sweep), then along y
    ax = h.ndim - 1
    bx, wx, cx, xl = _geometry(h.shape[-1], zmax)
    s0, s1x, s2 = (s.reshape(h.shape[:-1] + (zmax,))
                   for s in _row_blocks(h.reshape(-1, h.shape[-1]), bx.astype(np.int64), xl))
    m = {"s0": s0, ax: s1x, "s2": s2}
    geo = {ax: (wx.astype(float), cx)}
    if ndim == 2:
        by, wy, cy, yl = _geometry(h.shape[-2], zmax)
        m = {"s0": s0, ax - 1: s0 * yl[:, None], ax: s1x, "s2": s2}
        m = {name: np.add.reduceat(a, by, axis=ax - 1) for name, a in m.items()}
        geo[ax - 1] = (wy.astype(float), cy)
    results = {}
    zeta = zmax
    while True:
        # block widths along each axis, broadcastable against the block sums
        widths = {a: w.reshape([-1 if b == a else 1 for b in range(h.ndim)]) for a, (w, _) in geo.items()}
        count = functools.reduce(operator.mul, widths.values(), 1.0)
        ss = m["s2"] - m["s0"] ** 2 / count
        for a, w in widths.items():
            sxx = (w**3 - w) / 12.0 * (count / w)  # Σ (x - centre)² over the block, pixels²
            with np.errstate(invalid="ignore", divide="ignore"):
                ss = ss - np.where(sxx > 0, m[a] ** 2 / np.where(sxx > 0, sxx, 1.0), 0.0)
        if quadratic:
            pixels = np.broadcast_to(count, ss.shape).sum(axis=axes)
            results[zeta] = np.sqrt(np.maximum(ss, 0.0).sum(axis=axes) / pixels)
        else:
            results[zeta] = np.sqrt(np.maximum(ss, 0.0) / count).mean(axis=axes)
        if zeta == 1:
            break
        for a in list(geo):
            m, geo[a] = _merge(m, *geo[a], a)
        zeta //= 2
    return np.stack([results[z] for z in levels], axis=-1)
