"""Discrete derivative operators of paper Table 1, in real and Fourier space.

The same operator is used in both spaces, so results agree to round-off.
Arrays have the derivative axis last (``axis=-1``) unless stated.
"""

from __future__ import annotations

import numpy as np

__all__ = ["forward_difference", "second_difference", "fourier_first", "fourier_second", "wavevectors"]


def forward_difference(h: np.ndarray, dx: float, *, periodic: bool, axis: int = -1, step: int = 1) -> np.ndarray:
    """``(h[m+step] - h[m]) / (step dx)`` along ``axis`` (paper eq. 3 and 9).

    Periodic data wrap around; nonperiodic data lose the last ``step`` samples.
    """
    h = np.asarray(h)
    if periodic:
        return (np.roll(h, -step, axis=axis) - h) / (step * dx)
    n = h.shape[axis]
    a = np.take(h, np.arange(step, n), axis=axis)
    b = np.take(h, np.arange(0, n - step), axis=axis)
    return (a - b) / (step * dx)


def second_difference(h: np.ndarray, dx: float, *, periodic: bool, axis: int = -1, step: int = 1) -> np.ndarray:
    """``(h[m+s] - 2h[m] + h[m-s]) / (s dx)^2`` along ``axis`` (paper eq. 4).

    Periodic data wrap around; nonperiodic data lose ``step`` samples at each end.
    """
    h = np.asarray(h)
    if periodic:
        return (np.roll(h, -step, axis=axis) - 2 * h + np.roll(h, step, axis=axis)) / (step * dx) ** 2
    n = h.shape[axis]
    c = np.take(h, np.arange(step, n - step), axis=axis)
    p = np.take(h, np.arange(2 * step, n), axis=axis)
    m = np.take(h, np.arange(0, n - 2 * step), axis=axis)
    return (p - 2 * c + m) / (step * dx) ** 2


def wavevectors(n: int, dx: float, *, real: bool = False) -> np.ndarray:
    """Angular wavevectors ``q_o = 2π o / L`` in FFT order (``rfft`` order if ``real``)."""
    f = np.fft.rfftfreq(n, d=dx) if real else np.fft.fftfreq(n, d=dx)
    return 2 * np.pi * f


def fourier_first(q: np.ndarray, dx: float) -> np.ndarray:
    """Fourier symbol of the forward difference, ``(e^{iqΔx} - 1)/Δx`` (paper eq. 6)."""
    return (np.exp(1j * q * dx) - 1) / dx


def fourier_second(q: np.ndarray, dx: float) -> np.ndarray:
    """Fourier symbol of the central second difference, ``(e^{iqΔx} - 2 + e^{-iqΔx})/Δx²``."""
    return (2 * np.cos(q * dx) - 2) / dx**2
