"""Scale-dependent finite differences (paper eq. 9 and its second-order analogue).

``D^(η) h(x) = (h(x+ηΔx) - h(x)) / (ηΔx)`` and
``D²^(η) h(x) = (h(x+ηΔx) - 2h(x) + h(x-ηΔx)) / (ηΔx)²`` along the last axis.
Fractional scale factors ``η`` interpolate the heights linearly between samples.
Periodic data wrap around; nonperiodic data keep only the points whose stencil
lies inside the data.
"""

from __future__ import annotations

import numpy as np

from .spectra import check_finite

__all__ = ["scaled_difference", "sdrp_rms", "max_negative_curvature"]


def _shifted(h: np.ndarray, eta: float, start: int, count: int, sign: int) -> np.ndarray:
    """Linear interpolant of ``h`` at ``m + sign·η`` for ``m = start..start+count-1`` (no wrap)."""
    k = int(np.floor(eta + 1e-12))
    f = eta - k
    if f < 1e-12:
        f = 0.0
    a = start + sign * k
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
    reach = int(np.ceil(eta - 1e-12))
    if periodic:
        pad = reach + 1
        h = np.concatenate([h[..., n - pad:], h, h[..., :pad]], axis=-1) if pad <= n else np.pad(
            h, [(0, 0)] * (h.ndim - 1) + [(pad, pad)], mode="wrap")
        start, count = pad, n
    else:
        start = reach if order == 2 else 0
        count = n - reach - start
        if count <= 0:
            return np.empty(h.shape[:-1] + (0,))
    centre = h[..., start:start + count]
    fwd = _shifted(h, eta, start, count, +1)
    if order == 1:
        return (fwd - centre) / eta
    if order == 2:
        bwd = _shifted(h, eta, start, count, -1)
        return (fwd - 2 * centre + bwd) / eta**2
    raise ValueError(f"order must be 1 or 2, got {order}")


def sdrp_rms(h: np.ndarray, dx: float, etas, *, order: int, periodic: bool, rows: int) -> np.ndarray:
    """RMS of the scaled derivative at each ``η`` in ``etas``, over profiles and ``rows`` leading axes.

    Returns shape ``(..., len(etas))`` in units of 1/Δx^order; NaN where no stencil fits.
    """
    check_finite(h, "sdrp")
    h = np.asarray(h, dtype=float)
    lead = h.shape[: h.ndim - 1 - rows]
    out = np.full(lead + (len(etas),), np.nan)
    for i, eta in enumerate(etas):  # loop over scales; each step is vectorised over all pixels
        d = scaled_difference(h, float(eta), order=order, periodic=periodic)
        if d.shape[-1] == 0:
            continue
        flat = d.reshape(lead + (-1,))
        out[..., i] = np.sqrt(np.einsum("...i,...i->...", flat, flat) / flat.shape[-1])
    return out / dx**order


def max_negative_curvature(h: np.ndarray, dx: float, etas, *, periodic: bool, rows: int) -> np.ndarray:
    """``max_x[-D²^(η) h]`` at each ``η`` (paper eq. 13), shape ``(..., len(etas))``, units 1/length."""
    check_finite(h, "reliability")
    lead = h.shape[: h.ndim - 1 - rows]
    out = np.full(lead + (len(etas),), -np.inf)
    for i, eta in enumerate(etas):
        d = scaled_difference(h, float(eta), order=2, periodic=periodic)
        if d.shape[-1] == 0:
            continue
        out[..., i] = -d.reshape(lead + (-1,)).min(axis=-1)
    return out / dx**2
