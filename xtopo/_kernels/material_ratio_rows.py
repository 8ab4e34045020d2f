"""The material ratio (Abbott–Firestone) curve and its functional parameters of many rows at once, pure numpy.

For the profile set (ISO 21920-2 / ISO 13565-2: Rk, Rpk, Rvk, Rmr1, Rmr2, Rmr(c)) of every
line of a map: each row is sorted and the whole batch of rows is evaluated without a Python
loop. (The areal set classes the heights of one surface in a single pass instead, which is
faster for one large array; the construction of the equivalent straight line is the same.)

The curve: the ``n`` valid heights sorted in descending order, the ``i``-th (from 0) at material
ratio ``100 i / (n - 1)`` %, linear in between (the highest point at 0 %, the lowest at 100 %;
the empirical quantile function, as ``numpy.quantile``'s default). All functions reduce the last
axis, ignore NaN and broadcast over the leading axes without a Python loop.

Equivalent straight line (ISO 13565-2 §4.1, ISO 25178-2 Annex B): the 40 % wide secant of
least gradient locates the central region; the line is the least-squares fit of the curve's
points in that region (heights as ordinates). Its heights at 0 % and 100 % bound the core:
``Rk`` is their difference, ``Rmr1``/``Rmr2`` the material ratios where the curve meets them,
``Rpk = 2 A1 / Rmr1`` and ``Rvk = 2 A2 / (100 - Rmr2)`` with ``A1``/``A2`` the areas of the peaks above
and the dales below the core (in % × height).
"""

from __future__ import annotations

import warnings

import numpy as np

__all__ = ["FUNCTIONAL", "descending", "material_ratio_at", "functional_of_sorted", "equivalent_line", "WINDOW"]

#: width (in % material ratio) of the central region of the equivalent straight line
WINDOW = 40.0
#: names and order of the outputs of :func:`functional_of_sorted`
FUNCTIONAL = ("k", "pk", "vk", "mr1", "mr2")


def descending(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(d, n)``: the values of each row sorted in descending order (NaN after them) and the count of valid ones."""
    v = np.asarray(values, dtype=float)
    s = np.sort(v, axis=-1)  # ascending, NaN last
    n = np.count_nonzero(~np.isnan(v), axis=-1)
    idx = n[..., None] - 1 - np.arange(v.shape[-1])
    d = np.take_along_axis(s, np.clip(idx, 0, None), axis=-1)
    d[idx < 0] = np.nan
    return d, n


def _at(d, n, t):
    """The curve of rows ``d`` at fractional positions ``t`` (``0 <= t <= n - 1``), linear in between."""
    i0 = np.clip(np.floor(t).astype(int), 0, np.maximum(n - 1, 0)[..., None])
    i1 = np.minimum(i0 + 1, np.maximum(n - 1, 0)[..., None])
    f = t - i0
    a, b = np.take_along_axis(d, i0, -1), np.take_along_axis(d, i1, -1)
    return a + (b - a) * f


def material_ratio_at(d: np.ndarray, n: np.ndarray, c) -> np.ndarray:
    """Material ratio (%) of the sorted rows ``(d, n)`` at heights ``c`` (one per row, or a scalar)."""
    c = np.broadcast_to(np.asarray(c, dtype=float), n.shape)
    with np.errstate(invalid="ignore"):
        k = np.count_nonzero(d > c[..., None], axis=-1)  # points above c (NaN compares False)
    lo = np.take_along_axis(d, np.clip(k - 1, 0, None)[..., None], -1)[..., 0]
    hi = np.take_along_axis(d, np.clip(k, 0, np.maximum(n - 1, 0))[..., None], -1)[..., 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        frac = np.where(hi < lo, (lo - c) / (lo - hi), 0.0)
        t = np.where(k == 0, 0.0, np.where(k >= n, n - 1, k - 1 + frac))
        return np.where(n >= 2, 100.0 * t / (n - 1), np.nan)


def functional_of_sorted(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Core height, reduced peak height, reduced dale depth and the two material ratios of each row.

    Parameters
    ----------
    d, n : numpy.ndarray
        Rows ``(..., size)`` sorted by :func:`descending` and their counts of valid values.

    Returns
    -------
    numpy.ndarray
        ``(..., 5)``: ``k``, ``pk``, ``vk`` (height unit), ``mr1``, ``mr2`` (%) in the order of
        :data:`FUNCTIONAL` (Rk/Sk, Rpk/Spk, Rvk/Svk, Rmr1/Smr1, Rmr2/Smr2); NaN for rows with fewer
        than 3 valid values.
    """
    shape = n.shape
    d = d.reshape(-1, d.shape[-1])
    n = n.reshape(-1)
    out = np.full((n.size, len(FUNCTIONAL)), np.nan)
    ok = n >= 3
    if ok.any():
        out[ok] = _functional(d[ok], n[ok])
    return out.reshape(shape + (len(FUNCTIONAL),))


def equivalent_line(d: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Heights at 0 % and at 100 % of the equivalent straight line of sorted rows ``(d, n)`` (2D, ``n >= 3``).

    The areal set (:mod:`xtopo._kernels.material_ratio`) fits the same line to its curve sampled at
    equal material ratio steps, as one row.
    """
    rows, size = d.shape
    span = n - 1.0  # positions 0 .. n-1 ↔ 0 .. 100 %
    w = WINDOW / 100 * span  # window width in positions
    t = np.arange(size, dtype=float)[None, :]
    starts = int(np.floor((1 - WINDOW / 100) * span.max() + 1e-9)) + 1  # no window starts after 60 %
    end = t[:, :starts] + w[:, None]
    valid = end <= span[:, None] + 1e-9
    drop = d[:, :starts] - _at(d, n, np.minimum(end, span[:, None]))
    drop[~valid] = np.inf
    start = np.argmin(drop, axis=-1)  # first start of least gradient (ISO 13565-2: the first one)
    # least squares over the integer positions inside [start, start + w]
    a = start
    b = np.floor(start + w + 1e-9).astype(int)
    z = np.where(np.isnan(d), 0.0, d)
    csum = np.concatenate([np.zeros((rows, 1)), np.cumsum(z, -1)], -1)
    ctsum = np.concatenate([np.zeros((rows, 1)), np.cumsum(z * t, -1)], -1)
    r = np.arange(rows)
    m = (b - a + 1).astype(float)
    sh = csum[r, b + 1] - csum[r, a]
    sth = ctsum[r, b + 1] - ctsum[r, a]
    st = (a + b) * m / 2
    stt = (b * (b + 1) * (2 * b + 1) - (a - 1) * a * (2 * a - 1)) / 6.0
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (m * sth - st * sh) / (m * stt - st**2)
        intercept = (sh - slope * st) / m
    return intercept, intercept + slope * span


def _functional(d, n):
    span = n - 1.0
    t = np.arange(d.shape[-1], dtype=float)[None, :]
    upper, lower = equivalent_line(d, n)
    mr1 = material_ratio_at(d, n, upper)
    mr2 = material_ratio_at(d, n, lower)
    dmr = 100.0 / span
    valid_pts = t < n[:, None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        peaks = np.where(valid_pts, np.maximum(d - upper[:, None], 0.0), 0.0)
        dales = np.where(valid_pts, np.maximum(lower[:, None] - d, 0.0), 0.0)
    a1, a2 = _trapezoid(peaks, n) * dmr, _trapezoid(dales, n) * dmr
    with np.errstate(invalid="ignore", divide="ignore"):
        pk = np.where(mr1 > 0, 2 * a1 / mr1, 0.0)
        vk = np.where(mr2 < 100, 2 * a2 / (100 - mr2), 0.0)
    return np.stack([upper - lower, pk, vk, mr1, mr2], axis=-1)


def _trapezoid(g, n):
    """Trapezoid sums of the rows ``g`` over their first ``n`` points (unit spacing; zeros after them)."""
    last = np.take_along_axis(g, (n - 1)[:, None], -1)[:, 0]
    return g.sum(-1) - (g[:, 0] + last) / 2
