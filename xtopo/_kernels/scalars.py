"""Scalar roughness parameters (paper Table 2 plus the ISO amplitude set), numpy only.

All functions take heights with the lateral dims last — ``(..., nx)`` for line
scans, ``(..., ny, nx)`` for area scans — and ignore NaN (missing data).
S-parameters are about the global mean plane height, R-parameters about the
mean of each profile (ISO 4287 mean line) and averaged over profiles as
``sqrt(mean(r²))`` for RMS values and as plain means for Ra/Rz.
"""

from __future__ import annotations

import warnings

import numpy as np

from .derivatives import forward_difference, second_difference
from ..errors import UndefinedValueWarning
from .profile_iso import _mean_of, _nan  # nanmean of all-NaN slices: NaN without a warning

__all__ = ["AREA_PARAMETERS", "LINE_PARAMETERS", "area_parameters", "profile_parameters", "nonuniform_parameters"]

#: Names and order of the outputs of :func:`area_parameters`.
AREA_PARAMETERS = ("Sq", "Sdq", "Sddq", "Sa", "Sz", "Ssk", "Sku")
#: Names and order of the outputs of :func:`profile_parameters` (per direction).
LINE_PARAMETERS = ("Rq", "Rdq", "Rddq", "Ra", "Rz", "Rsk", "Rku")
#: how each parameter (both lists) scales with the heights: h¹, skewness and kurtosis h⁰
HEIGHT_POWERS = (1, 1, 1, 1, 1, 0, 0)


def _moments(d, axes):
    """RMS, mean absolute value, range (of each profile along the last axis, averaged over the other ``axes``),
    skewness and kurtosis of deviations ``d`` (NaN-aware) reduced over ``axes``. Skewness and kurtosis are NaN
    where the RMS is 0 (a flat surface, where they are undefined), with an
    :class:`~xtopo.errors.UndefinedValueWarning` saying so."""
    mean = _mean_of(d)
    d2 = d * d   # powers by products: d**3 and d**4 took 3/4 of a 1024² map's scalars
    q = np.sqrt(mean(d2, axis=axes))
    a = mean(np.abs(d), axis=axes)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)   # all-NaN profiles: NaN
        z = np.nanmax(d, -1) - np.nanmin(d, -1)
        if len(axes) > 1:
            z = np.nanmean(z, axis=tuple(range(1 - len(axes), 0)))
    with np.errstate(invalid="ignore", divide="ignore"):
        sk = np.where(q > 0, mean(d2 * d, axis=axes) / q**3, np.nan)
        ku = np.where(q > 0, mean(d2 * d2, axis=axes) / q**4, np.nan)
    if np.any(q == 0):
        warnings.warn("skewness and kurtosis of a flat surface (RMS height 0) are undefined: NaN",
                      UndefinedValueWarning, stacklevel=2)
    return q, a, z, sk, ku


def area_parameters(h: np.ndarray, dy: float, dx: float, periodic: bool) -> np.ndarray:
    """Sq, SΔq, SΔ²q, Sa, Sz, Ssk, Sku of ``h[..., ny, nx]``, stacked on the last axis.

    SΔq² = ⟨(D_x h)²⟩ + ⟨(D_y h)²⟩ and SΔ²q² = ⟨(D_xx h + D_yy h)²⟩/4 with Table 1
    operators. Periodic data wrap; nonperiodic differences drop the edge samples
    they cannot form (each mean is over the samples that exist).
    """
    h = np.asarray(h, dtype=float)
    flat = h.reshape(h.shape[:-2] + (-1,))
    d = flat - _nan(np.nanmean, flat, -1)[..., None]
    sq, sa, sz, ssk, sku = _moments(d, (-1,))
    gx = forward_difference(h, dx, periodic=periodic, axis=-1)
    gy = forward_difference(h, dy, periodic=periodic, axis=-2)
    sdq = np.sqrt(_nan(np.nanmean, gx.reshape(gx.shape[:-2] + (-1,)) ** 2, -1)
                  + _nan(np.nanmean, gy.reshape(gy.shape[:-2] + (-1,)) ** 2, -1))
    cx = second_difference(h, dx, periodic=periodic, axis=-1)
    cy = second_difference(h, dy, periodic=periodic, axis=-2)
    if not periodic:
        cx = cx[..., 1:-1, :]
        cy = cy[..., :, 1:-1]
    lap = cx + cy
    sddq = np.sqrt(_nan(np.nanmean, lap.reshape(lap.shape[:-2] + (-1,)) ** 2, -1) / 4)
    return np.stack([sq, sdq, sddq, sa, sz, ssk, sku], axis=-1)


def profile_parameters(h: np.ndarray, dx: float, periodic: bool, rows: int) -> np.ndarray:
    """R-parameters of the profiles along the last axis, averaged over ``rows`` preceding axes."""
    h = np.asarray(h, dtype=float)
    d = h - _nan(np.nanmean, h, -1)[..., None]
    axes = tuple(range(-1 - rows, 0))
    q, a, z, sk, ku = _moments(d, axes)
    g = forward_difference(h, dx, periodic=periodic, axis=-1)
    dq = np.sqrt(_nan(np.nanmean, g**2, axes))
    c = second_difference(h, dx, periodic=periodic, axis=-1)
    ddq = np.sqrt(_nan(np.nanmean, c**2, axes))
    return np.stack([q, dq, ddq, a, z, sk, ku], axis=-1)


def nonuniform_parameters(h: np.ndarray, x: np.ndarray) -> np.ndarray:
    """R-parameters of a piecewise-linear profile on nonuniform positions ``x``.

    Averages are integrals of the linear interpolant divided by its length;
    RΔq is exact for the interpolant, RΔ²q uses the three-point nonuniform
    second difference weighted by the control length of each node.
    """
    h = np.asarray(h, dtype=float)
    x = np.asarray(x, dtype=float)
    dxs = np.diff(x)
    length = x[-1] - x[0]
    a, b = h[..., :-1], h[..., 1:]
    mean = np.sum((a + b) / 2 * dxs, -1) / length
    da, db = a - mean[..., None], b - mean[..., None]
    q = np.sqrt(np.sum((da**2 + da * db + db**2) / 3 * dxs, -1) / length)
    # |.| and higher moments by trapezoid of the node deviations
    d = h - mean[..., None]
    w = np.pad(dxs / 2, (0, 1)) + np.pad(dxs / 2, (1, 0))  # trapezoid weight of each node
    ra = np.sum(np.abs(d) * w, -1) / length
    with np.errstate(invalid="ignore", divide="ignore"):
        sk = np.where(q > 0, np.sum(d**3 * w, -1) / length / q**3, np.nan)
        ku = np.where(q > 0, np.sum(d**4 * w, -1) / length / q**4, np.nan)
    z = d.max(-1) - d.min(-1)
    slope = (b - a) / dxs
    dq = np.sqrt(np.sum(slope**2 * dxs, -1) / length)
    if x.size >= 3:
        curv = 2 * (slope[..., 1:] - slope[..., :-1]) / (dxs[1:] + dxs[:-1])
        wc = (dxs[1:] + dxs[:-1]) / 2
        ddq = np.sqrt(np.sum(curv**2 * wc, -1) / np.sum(wc))
    else:
        ddq = np.full_like(q, np.nan)
    return np.stack([q, dq, ddq, ra, z, sk, ku], axis=-1)
