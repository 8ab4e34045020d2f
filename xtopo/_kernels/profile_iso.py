"""ISO 21920-2 (and ISO 4287) profile parameters of an evaluation length, pure numpy.

Profiles arrive as ``z[..., n]``: the ordinates of the evaluation length about the reference
(mean) line, NaN for missing points, ``n`` divisible by the number of sections (sampling
lengths). Every function broadcasts over the leading axes without a Python loop.
"""

from __future__ import annotations

import functools
import warnings

import numpy as np

from .material_ratio_rows import descending, functional_of_sorted, material_ratio_at

__all__ = ["PARAMETERS", "CONVENTIONS", "profile_parameters", "seven_point", "slope_7point", "mean_width"]

#: names and order of the outputs of :func:`profile_parameters`
PARAMETERS = ("Ra", "Rq", "Rp", "Rv", "Rz", "Rt", "Rsk", "Rku", "Rdq", "RSm", "Rmr", "Rk", "Rpk", "Rvk", "Rmr1",
              "Rmr2")
#: ``"iso21920"``: Rp, Rv, Rz per section and averaged, the rest over the evaluation length (ISO 21920-2:2021);
#: ``"iso4287"``: every parameter but Rt, Rmr(c) and the Rk family per sampling length and averaged (ISO 4287:1997)
CONVENTIONS = ("iso21920", "iso4287")
#: height discrimination of the profile elements (RSm), a fraction of Rz (ISO 4287 §3.1.9, ISO 21920-2)
HEIGHT_DISCRIMINATION = 0.1
#: width discrimination of the profile elements, a fraction of the sampling length (ISO 4287 §3.1.9)
WIDTH_DISCRIMINATION = 0.01


def seven_point(m3, m2, m1, p1, p2, p3):
    """The 7-point slope × 60Δ from the samples at offsets -3, -2, -1, 1, 2, 3 (arrays; compiled for Sdq)."""
    return p3 - 9.0 * p2 + 45.0 * p1 - 45.0 * m1 + 9.0 * m2 - m3


def slope_7point(z: np.ndarray, dx: float) -> np.ndarray:
    """Local slope ``dz/dx`` by the 7-point formula of ISO 4287 (the differentiation it prescribes for RΔq).

    ``(z[i+3] - 9 z[i+2] + 45 z[i+1] - 45 z[i-1] + 9 z[i-2] - z[i-3]) / (60 dx)`` where a point has
    3 neighbours on each side; the 3 points at each end, which have not, take second-order
    differences (``numpy.gradient``, ``edge_order=2``), so that every point has a slope.
    """
    z = np.asarray(z, dtype=float)
    n = z.shape[-1]
    if n < 7:
        return np.gradient(z, dx, axis=-1, edge_order=2) if n >= 3 else np.full(z.shape, np.nan)
    out = np.empty_like(z)
    s = lambda k: z[..., 3 + k: n - 3 + k]  # noqa: E731
    out[..., 3:-3] = seven_point(*(s(k) for k in (-3, -2, -1, 1, 2, 3))) / (60.0 * dx)
    out[..., :3] = np.gradient(z[..., :6], dx, axis=-1, edge_order=2)[..., :3]
    out[..., -3:] = np.gradient(z[..., -6:], dx, axis=-1, edge_order=2)[..., -3:]
    return out


def mean_width(z: np.ndarray, dx: float, discrimination: np.ndarray, min_width: float = 0.0) -> np.ndarray:
    """Mean width of the profile elements (RSm) of rows ``z``, in the unit of ``dx``.

    A profile element is a peak (above the mean line) and the valley after it; peaks lower and
    valleys shallower than ``discrimination`` (one value per row) belong to their neighbours:
    the profile enters a peak when it rises above ``+discrimination`` and a valley when it falls
    below ``-discrimination`` (hysteresis). Elements are delimited by the upward crossings of
    the mean line (interpolated linearly) at which a valley turns into a peak; an element
    narrower than ``min_width`` (in points: the width discrimination) joins the next one. RSm is
    the mean distance between consecutive delimiters; NaN where a row has fewer than two.
    """
    z = np.asarray(z, dtype=float)
    hd = np.asarray(discrimination, dtype=float)[..., None]
    n = z.shape[-1]
    pos = np.arange(n)
    with np.errstate(invalid="ignore"):
        event = np.where(z > hd, 1, np.where(z < -hd, -1, 0))
    last = np.maximum.accumulate(np.where(event != 0, pos, -1), axis=-1)
    state = np.where(last >= 0, np.take_along_axis(event, np.clip(last, 0, None), -1), 0)
    zl, zr = z[..., :-1], z[..., 1:]
    with np.errstate(invalid="ignore", divide="ignore"):
        up = (zl <= 0) & (zr > 0)
        where = pos[:-1] + np.where(up, -zl / (zr - zl), 0.0)
    crossing = np.concatenate([np.full(z.shape[:-1] + (1,), -np.inf), np.where(up, where, -np.inf)], -1)
    crossing = np.maximum.accumulate(crossing, axis=-1)  # the last upward crossing at or before each point
    turn = np.zeros(z.shape, dtype=bool)
    turn[..., 1:] = (state[..., :-1] == -1) & (state[..., 1:] == 1)
    count = np.count_nonzero(turn, axis=-1)
    first = _nan(np.min, np.where(turn, crossing, np.inf), axis=-1)
    lastc = _nan(np.max, np.where(turn, crossing, -np.inf), axis=-1)
    if min_width > 0:
        count, first, lastc = _width_discrimination(turn, crossing, min_width, count, first, lastc)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count >= 2, (lastc - first) / (count - 1) * dx, np.nan)


def _width_discrimination(turn, crossing, min_width, count, first, last):
    """``(count, first, last)`` per row after dropping the delimiters closer than ``min_width`` to the previous one kept.

    Only rows with such a pair are walked through (a short loop over their few delimiters).
    """
    shape = np.shape(count)
    rows = turn.reshape(-1, turn.shape[-1])
    cross = crossing.reshape(rows.shape)
    count, first, last = (np.array(a, dtype=float).reshape(-1) for a in (count, first, last))
    r, c = np.nonzero(rows)
    b = cross[r, c]
    close = (np.diff(b) < min_width) & (r[1:] == r[:-1])
    for row in np.unique(r[1:][close]):
        kept = []
        for v in b[r == row]:
            if not kept or v - kept[-1] >= min_width:
                kept.append(v)
        count[row], first[row], last[row] = len(kept), kept[0], kept[-1]
    return count.reshape(shape), first.reshape(shape), last.reshape(shape)


def _nan(func, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return func(*args, **kwargs)


def _mean_of(a):
    """``np.mean``, or ``np.nanmean`` (quietly NaN for all-NaN slices) where ``a`` has NaN: nanmean copies the
    array; on NaN-free data both give the same sums."""
    return functools.partial(_nan, np.nanmean) if np.isnan(a).any() else np.mean


def _amplitude(z, dx, rz, sampling):
    """Ra, Rq, Rsk, Rku, Rdq, RSm of rows ``z`` (reduced over the last axis); ``sampling``: points per section."""
    mean = _mean_of(z)
    z2 = z * z
    ra = mean(np.abs(z), -1)
    rq = np.sqrt(mean(z2, -1))
    with np.errstate(invalid="ignore", divide="ignore"):
        rsk = np.where(rq > 0, mean(z2 * z, -1) / rq**3, np.nan)
        rku = np.where(rq > 0, mean(z2 * z2, -1) / rq**4, np.nan)
    rdq = np.sqrt(mean(slope_7point(z, dx) ** 2, -1))
    rsm = mean_width(z, dx, HEIGHT_DISCRIMINATION * rz, WIDTH_DISCRIMINATION * sampling)
    return ra, rq, rsk, rku, rdq, rsm


def profile_parameters(z: np.ndarray, dx: float, sections: int, c: float, convention: str,
                       center: bool) -> np.ndarray:
    """The ISO 21920-2 profile parameters of evaluation lengths ``z[..., n]``.

    Parameters
    ----------
    z : numpy.ndarray
        Ordinates (NaN: missing), ``n`` a multiple of ``sections``.
    dx : float
        Sampling distance.
    sections : int
        Number of sampling lengths (sections) of the evaluation length.
    c : float
        Height (about the mean line) of the material ratio Rmr(c).
    convention : {"iso21920", "iso4287"}
        Which parameters are averaged over sections (see :data:`CONVENTIONS`).
    center : bool
        Subtract the mean of the evaluation length first (no L-filter gave the mean line).

    Returns
    -------
    numpy.ndarray
        ``(..., len(PARAMETERS))`` in the order of :data:`PARAMETERS`.
    """
    z = np.asarray(z, dtype=float)
    if center:
        z = z - _nan(np.nanmean, z, -1)[..., None]
    sec = z.reshape(z.shape[:-1] + (sections, z.shape[-1] // sections))
    rp_i, rv_i = _nan(np.nanmax, sec, -1), -_nan(np.nanmin, sec, -1)
    rp, rv, rz = (_nan(np.nanmean, v, -1) for v in (rp_i, rv_i, rp_i + rv_i))
    rt = _nan(np.nanmax, z, -1) - _nan(np.nanmin, z, -1)
    if convention == "iso4287":
        parts = _amplitude(sec, dx, rz[..., None], sec.shape[-1])
        ra, rq, rsk, rku, rdq, rsm = (_nan(np.nanmean, p, -1) for p in parts)
    else:
        ra, rq, rsk, rku, rdq, rsm = _amplitude(z, dx, rz, sec.shape[-1])
    d, n = descending(z)
    rmr = material_ratio_at(d, n, c)
    k, pk, vk, mr1, mr2 = np.moveaxis(functional_of_sorted(d, n), -1, 0)
    return np.stack([ra, rq, rp, rv, rz, rt, rsk, rku, rdq, rsm, rmr, k, pk, vk, mr1, mr2], axis=-1)
