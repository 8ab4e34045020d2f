"""Power spectral densities with the paper's DFT convention (eq. 1, §4.6).

``h̃ = Δx Δy Σ h e^{-iq·r}``, ``C1D = |h̃|²/L`` and ``C2D = |h̃|²/(Lx Ly)``.
Heights are taken about their mean (per profile for C1D, per map for C2D), so
that Parseval's theorem reads ``Σ_q C1D Δq/(2π) = Rq²`` and
``Σ_q C2D Δq_x Δq_y/(2π)² = Sq²`` exactly for unwindowed data.
Arrays carry the lateral dims last; leading dims are a batch.
"""

from __future__ import annotations

import numpy as np
from ._lazy import LazyJit

from ..errors import MissingDataError
from . import fft as _fft
from .derivatives import wavevectors
from .windows import hann, radial_hann

njit = LazyJit(globals())  # numba imported, the kernels wrapped, on first use (startup time, issue 26)

#: FFT backend of the analysis kernels. pyFFTW through its scipy interface re-plans on
#: every call (no interface cache), which measured slower than scipy.fft at 2048²-8192²
#: on the 2-core development machine.
BACKEND = "scipy"

__all__ = ["BACKEND", "psd_profiles", "prewhitening", "psd_map", "psd_iso", "rfft_abs_q", "rfft_multiplicity", "check_finite",
           "power"]


def check_finite(h: np.ndarray, what: str) -> None:
    """Raise :class:`~xtopo.errors.MissingDataError` if ``h`` holds NaN or inf."""
    if not np.isfinite(h).all():
        raise MissingDataError(f"{what}: the heights contain missing data (NaN)")


def power(f: np.ndarray) -> np.ndarray:
    """``|f|²`` of a complex array (one temporary, no complex multiply)."""
    p = f.real * f.real
    p += f.imag * f.imag
    return p


@njit(nogil=True, cache=True)
def _centred_profiles(h, window, out):
    """``out[r] = (h[r] - mean(h[r])) · window`` for the rows of ``h`` (2D) in one pass each."""
    rows, n = h.shape
    for r in range(rows):
        s = 0.0
        for i in range(n):
            s += h[r, i]
        m = s / n
        for i in range(n):
            out[r, i] = (h[r, i] - m) * window[i]


@njit(nogil=True, cache=True)
def _mean_power(f, scale):
    """``scale · mean_r |f[l, r, k]|²`` over the middle axis of a complex ``(L, R, K)`` array, in one pass."""
    n_lead, rows, k = f.shape
    out = np.zeros((n_lead, k))
    for lead in range(n_lead):
        acc = out[lead]
        for r in range(rows):
            for j in range(k):
                v = f[lead, r, j]
                acc[j] += v.real * v.real + v.imag * v.imag
        for j in range(k):
            acc[j] *= scale / rows
    return out


def psd_profiles(h: np.ndarray, dx: float, *, window: bool, rows: int, prewhiten: bool = False) -> np.ndarray:
    """C1D of the profiles along the last axis at ``q = 2π k/L``, ``k = 0..n//2``.

    Parameters
    ----------
    h : ndarray, shape (..., [ny,] n)
        Heights; profiles along the last axis.
    dx : float
        Sample spacing.
    window : bool
        Multiply each (mean-free) profile by a Hann window with ``mean(w²) = 1``.
    rows : int
        Number of axes in front of the last one to average over (0 or 1).
    prewhiten : bool
        Transform the slopes instead of the heights (:func:`prewhitening`).

    Notes
    -----
    Centring and windowing are one compiled pass, the power and its mean over the rows another:
    the transform is the only full-size temporary.
    """
    check_finite(h, "psd")
    n = h.shape[-1]
    h2 = np.ascontiguousarray(h, dtype=float).reshape(-1, n)
    if prewhiten and n > 1:
        h2 = np.diff(h2, axis=-1) / dx  # the slope (D_x h): n - 1 values, transformed on the heights' n points
    m = h2.shape[-1]
    d = np.empty_like(h2)
    _centred_profiles(h2, hann(m) if window else np.ones(m), d)
    f = _fft.rfftn(d.reshape(h.shape[:-1] + (m,)), s=(n,), axes=(-1,), backend=BACKEND)
    del d
    lead = h.shape[: h.ndim - 1 - rows]
    c = _mean_power(f.reshape(int(np.prod(lead, dtype=int)), -1, f.shape[-1]), dx / m)  # Δx² |Σ h e^{-iqx}|² / L
    c = c.reshape(lead + (f.shape[-1],))
    if prewhiten and n > 1:
        c = c * prewhitening(n, dx)
    return c


def prewhitening(n: int, dx: float) -> np.ndarray:
    """Factor ``1/|D̃_x(q)|²`` that turns the spectrum of the slopes into that of the heights, ``q = 2πk/(nΔx)``.

    Prewhitening (Blackman & Tukey 1958; Percival & Walden 1993, §6.5): the spectrum of the
    first differences ``D_x h`` (paper Table 1, ``D̃_x = (e^{iqΔx} - 1)/Δx``) is that of the heights
    times ``|D̃_x|² = (2 sin(qΔx/2)/Δx)²``, which flattens the steep spectrum of a rough surface
    (``C1D ∝ q^{-1-2H}``). A window's main lobe (Hann: ±2 bins) averages the spectrum over its
    width: for ``q^{-2.6}`` the heights' windowed spectrum is 1.7-2.7 times too high at ``k = 2``
    (mean of 18 example-twin AFM scans), the slopes' within 3-24 %. Differencing also removes
    the tilt (wavelengths longer than the scan) exactly, whose windowed remnant otherwise
    dominates ``k = 1``. ``q = 0`` (the mean, removed) gets 0.
    """
    q = 2 * np.pi * np.arange(n // 2 + 1) / (n * dx)
    d2 = (2 * np.sin(q * dx / 2) / dx) ** 2
    return np.divide(1.0, d2, out=np.zeros_like(d2), where=d2 > 0)


def _demeaned_map(h, dy, dx, window):
    """Heights of a map less their mean, radially Hann-windowed when asked (checked finite)."""
    check_finite(h, "psd")
    d = h - h.mean(axis=(-2, -1), keepdims=True)
    if window:
        d *= radial_hann(*h.shape[-2:], dy, dx)
    return d


def psd_map(h: np.ndarray, dy: float, dx: float, *, window: bool) -> np.ndarray:
    """C2D on the full (q_y, q_x) grid in ascending order (``fftshift``), shape ``(..., ny, nx)``."""
    ny, nx = h.shape[-2:]
    p = power(_fft.fftn(_demeaned_map(h, dy, dx, window), axes=(-2, -1), backend=BACKEND))
    return np.fft.fftshift(p * (dx * dy / (nx * ny)), axes=(-2, -1))


def rfft_abs_q(ny: int, nx: int, dy: float, dx: float) -> np.ndarray:
    """|q| of every mode of a 2D real FFT, shape ``(ny, nx//2+1)``."""
    qy, qx = wavevectors(ny, dy), wavevectors(nx, dx, real=True)
    return np.sqrt(qy[:, None] ** 2 + qx[None, :] ** 2)


def rfft_multiplicity(nx: int) -> np.ndarray:
    """How many modes of the full spectrum each rfft mode stands for (1 or 2), shape ``(nx//2+1,)``."""
    m = np.full(nx // 2 + 1, 2.0)
    m[0] = 1.0
    if nx % 2 == 0:
        m[-1] = 1.0
    return m


def psd_iso(h: np.ndarray, dy: float, dx: float, *, window: bool, plan) -> np.ndarray:
    """Radially averaged C2D over the bins of ``plan`` (a :class:`~.binning.BinPlan` on :func:`rfft_abs_q`)."""
    ny, nx = h.shape[-2:]
    p = power(_fft.rfftn(_demeaned_map(h, dy, dx, window), axes=(-2, -1), backend=BACKEND))
    return plan.mean(p) * (dx * dy / (nx * ny))
