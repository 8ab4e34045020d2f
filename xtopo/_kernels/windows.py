"""Window functions for spectral analysis of nonperiodic data (paper §4.3).

Windows are normalised so that their mean square is one, ``(1/A) ∫ w² dA = 1``
(i.e. ``∫ w² dA = 1`` per unit area), which leaves the PSD of a stationary
surface unbiased and keeps Parseval's theorem true on average.
"""

from __future__ import annotations

import functools

import numpy as np

__all__ = ["hann", "radial_hann"]


@functools.lru_cache(maxsize=8)
def hann(n: int) -> np.ndarray:
    """Symmetric 1D Hann window of ``n`` samples with ``mean(w²) = 1`` (read-only)."""
    if n < 3:
        w = np.ones(n)
    else:
        w = np.sin(np.pi * np.arange(n) / (n - 1)) ** 2
        w /= np.sqrt(np.mean(w**2))
    w.flags.writeable = False
    return w


@functools.lru_cache(maxsize=4)
def radial_hann(ny: int, nx: int, dy: float, dx: float) -> np.ndarray:
    """Spherically symmetric 2D Hann window with ``mean(w²) = 1`` (read-only).

    ``w(r) = cos²(π r / (2 r₀))`` for ``r < r₀`` and 0 outside, with ``r`` the
    physical distance from the centre of the map and ``r₀`` half the shorter side.
    Maps with no pixel inside ``r₀`` (a single row/column, or two rows/columns whose
    pixels all lie on the circle) get no window, like :func:`hann` for ``n < 3``.
    """
    y = (np.arange(ny) - (ny - 1) / 2) * dy
    x = (np.arange(nx) - (nx - 1) / 2) * dx
    r0 = min((ny - 1) * dy, (nx - 1) * dx) / 2
    if r0 <= 0:
        w = np.ones((ny, nx))
    else:
        r = np.sqrt(y[:, None] ** 2 + x[None, :] ** 2)
        w = np.where(r < r0, np.cos(np.pi * np.minimum(r, r0) / (2 * r0)) ** 2, 0.0)
        w = w / np.sqrt(np.mean(w**2)) if w.any() else np.ones((ny, nx))
    w.flags.writeable = False
    return w
