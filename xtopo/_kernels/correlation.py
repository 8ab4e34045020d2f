"""Height-difference autocorrelation functions (paper eq. 11-12) via FFT.

``A(ℓ) = (1/2) ⟨(h(r) - h(r+ℓ))²⟩`` averaged over all pairs inside the data.
Periodic data wrap around; nonperiodic data are zero padded and every lag is
normalised by its own number of pairs, so the FFT result equals the direct sum.
A ≥ 0 by definition: FFT round-off below zero (at and near ``ℓ = 0``) is clipped,
and ``A(0) = 0`` exactly.
"""

from __future__ import annotations

import numpy as np
from .fft import sfft  # imported on first use (startup time)

from . import fft as _fft
from .spectra import BACKEND as _BACKEND
from .spectra import check_finite, power

__all__ = ["acf_profiles", "acf_offsets", "acf_map"]


def acf_profiles(h: np.ndarray, dx: float, *, periodic: bool, rows: int) -> np.ndarray:
    """A(k Δx) of the profiles along the last axis, averaged over ``rows`` leading axes.

    Returns ``k = 0..n//2`` for periodic and ``k = 0..n-1`` for nonperiodic data.
    ``dx`` is accepted for a uniform kernel signature; A does not depend on it.
    """
    check_finite(h, "acf")
    n = h.shape[-1]
    raxes = tuple(range(-1 - rows, -1))
    nrows = int(np.prod([h.shape[a] for a in raxes]))
    d = h - h.mean(axis=-1, keepdims=True)
    size = n if periodic else sfft.next_fast_len(2 * n - 1, real=True)
    p = power(_fft.rfftn(d, s=(size,), axes=(-1,), backend=_BACKEND)).sum(axis=raxes)  # raxes=(): unchanged
    c = _fft.irfftn(p, s=(size,), axes=(-1,), backend=_BACKEND)
    sq = (d * d).sum(axis=raxes)
    if periodic:
        k = n // 2 + 1
        a = (sq.sum(axis=-1, keepdims=True) - c[..., :k]) / (n * nrows)
        a[..., 0] = 0.0
        return np.maximum(a, 0, out=a)
    cs = np.zeros(sq.shape[:-1] + (n + 1,))
    np.cumsum(sq, axis=-1, out=cs[..., 1:])
    k = np.arange(n)
    head = cs[..., n - k]              # Σ_{m < n-k} h_m²
    tail = cs[..., -1:] - cs[..., k]   # Σ_{m >= k} h_m²
    a = (head + tail - 2 * c[..., :n]) / (2 * (n - k) * nrows)
    a[..., 0] = 0.0
    return np.maximum(a, 0, out=a)


def acf_offsets(ny: int, nx: int, dy: float, dx: float, *, periodic: bool) -> np.ndarray:
    """Lengths |Δr| of the lateral offsets returned by :func:`acf_map` (same shape)."""
    if periodic:
        iy = np.fft.fftfreq(ny, d=1.0 / ny)
        ix = np.fft.fftfreq(nx, d=1.0 / nx)
    else:
        iy = np.arange(ny, dtype=float)
        ix = np.arange(-(nx - 1), nx, dtype=float)
    return np.sqrt((iy[:, None] * dy) ** 2 + (ix[None, :] * dx) ** 2)


def acf_weights(ny: int, nx: int, *, periodic: bool) -> np.ndarray:
    """Weights of the offsets of :func:`acf_map` in a full-plane average (drops duplicate ±Δr)."""
    if periodic:
        return np.ones((ny, nx))
    w = np.ones((ny, 2 * nx - 1))
    w[0, : nx - 1] = 0.0  # Δy = 0, Δx < 0 duplicates Δx > 0
    return w


def acf_map(h: np.ndarray, *, periodic: bool) -> np.ndarray:
    """A(Δr) of an area scan ``h[..., ny, nx]`` for every lateral offset.

    Periodic: all ``(ny, nx)`` offsets in FFT order. Nonperiodic: the half plane
    ``Δy = 0..ny-1``, ``Δx = -(nx-1)..nx-1`` (shape ``(ny, 2nx-1)``); A(-Δr) = A(Δr).
    """
    check_finite(h, "acf")
    ny, nx = h.shape[-2:]
    d = h - h.mean(axis=(-2, -1), keepdims=True)
    sq = d * d
    # circular (periodic) or, zero padded, linear correlation Σ d(r) d(r + Δr)
    shape = (ny, nx) if periodic else tuple(sfft.next_fast_len(2 * n - 1, real=True) for n in (ny, nx))
    c = _fft.irfftn(power(_fft.rfftn(d, s=shape, axes=(-2, -1), backend=_BACKEND)), s=shape, axes=(-2, -1),
                    backend=_BACKEND)
    if periodic:
        a = sq.mean(axis=(-2, -1), keepdims=True) - c / (nx * ny)
        a[..., 0, 0] = 0.0
        return np.maximum(a, 0, out=a)
    px = shape[1]
    c = np.concatenate([c[..., :ny, px - (nx - 1):], c[..., :ny, :nx]], axis=-1)
    # Σ of h² over the rows a pair's first point (rows < ny-Δy) or second point (rows ≥ Δy) can take,
    # then prefix sums over columns: every rectangle sum below is a difference of two column views.
    head = np.cumsum(sq[..., ::-1, :], axis=-2)[..., ::-1, :]  # head[i] = Σ_{rows ≥ i}
    tail = np.cumsum(sq, axis=-2)[..., ::-1, :]                # tail[i] = Σ_{rows ≤ ny-1-i}
    p1 = np.zeros(sq.shape[:-1] + (nx + 1,))
    p2 = np.zeros_like(p1)
    np.cumsum(tail, axis=-1, out=p1[..., 1:])   # first point: rows [0, ny-Δy)
    np.cumsum(head, axis=-1, out=p2[..., 1:])   # second point: rows [Δy, ny)
    # Δx < 0 (|Δx| = nx-1..1): first point cols [|Δx|, nx), second [0, nx-|Δx|)
    neg = (p1[..., nx:] - p1[..., nx - 1:0:-1]) + p2[..., 1:nx]
    # Δx ≥ 0 (0..nx-1): first point cols [0, nx-Δx), second [Δx, nx)
    pos = p1[..., nx:0:-1] + (p2[..., nx:] - p2[..., :nx])
    t = np.concatenate([neg, pos], axis=-1)
    jx = np.arange(-(nx - 1), nx)
    npairs = (ny - np.arange(ny))[:, None] * (nx - np.abs(jx))[None, :]
    t -= 2 * c
    t /= 2 * npairs
    t[..., 0, nx - 1] = 0.0
    return np.maximum(t, 0, out=t)
