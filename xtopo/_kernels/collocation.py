"""Putting curves of several measurements onto common log-spaced collocation points:
log-log interpolation (smooth, sparse curves) and log-bin averaging (dense, noisy curves)."""

from __future__ import annotations

import numpy as np

__all__ = ["interp_loglog", "collocation_points", "bin_mean"]


def collocation_points(lo: float, hi: float, per_decade: int) -> np.ndarray:
    """Log-spaced points from ``lo`` to ``hi`` (inclusive), ``per_decade`` per decade."""
    if not (0 < lo < hi) or not np.isfinite(hi):
        return np.array([lo]) if lo > 0 else np.array([])
    n = max(2, int(np.ceil(per_decade * np.log10(hi / lo))) + 1)
    return np.geomspace(lo, hi, n)


def interp_loglog(y: np.ndarray, x: np.ndarray, xnew: np.ndarray) -> np.ndarray:
    """Interpolate ``y[..., n]`` given at ``x[n]`` onto ``xnew`` in log-log space.

    Per row, only finite, positive samples at positive ``x`` are used; points of
    ``xnew`` outside their range (or in a gap wider than one sample where the row is
    NaN) are NaN. Returns ``[..., len(xnew)]``.
    """
    y = np.asarray(y, dtype=float)
    x = np.asarray(x, dtype=float)
    xnew = np.asarray(xnew, dtype=float)
    out = np.full(y.shape[:-1] + (xnew.size,), np.nan)
    lx_all = np.log(np.where(x > 0, x, np.nan))
    lxn = np.log(xnew)
    flat_y = y.reshape(-1, y.shape[-1])
    flat_o = out.reshape(-1, xnew.size)
    for i in range(flat_y.shape[0]):
        row = flat_y[i]
        ok = np.isfinite(row) & (row > 0) & np.isfinite(lx_all)
        if ok.sum() < 2:
            if ok.sum() == 1:
                j = np.flatnonzero(ok)[0]
                flat_o[i, np.isclose(xnew, x[j], rtol=1e-9)] = row[j]
            continue
        lx, ly = lx_all[ok], np.log(row[ok])
        inside = (lxn >= lx[0] - 1e-12) & (lxn <= lx[-1] + 1e-12)
        flat_o[i, inside] = np.exp(np.interp(lxn[inside], lx, ly))
    return out


def bin_mean(y: np.ndarray, x: np.ndarray, xnew: np.ndarray, weights=None, min_weight: float = 0.0) -> np.ndarray:
    """Mean of ``y[..., n]`` (at abscissae ``x[n]``) over log bins, evaluated at the bin centres ``xnew``.

    Bin edges lie at the geometric midpoints between the points of ``xnew`` (and half a bin
    beyond the first and last). The mean of a bin belongs to the mean ``log x`` of its
    samples, not to its centre (a sparse bin, e.g. one sample near an edge, would otherwise
    shift a steep curve by up to half a bin): each non-empty bin's value is the log-log line
    through the neighbouring bin means, evaluated at its centre (at most half a bin away).
    NaN samples are ignored; empty bins, and bins whose summed ``weights`` (statistical
    weight of each sample, default 1) stay below ``min_weight``, are NaN.
    """
    y = np.asarray(y, dtype=float)
    x = np.asarray(x, dtype=float)
    centers = np.asarray(xnew, dtype=float)
    w = np.ones_like(x) if weights is None else np.asarray(weights, dtype=float)
    lc = np.log(centers)
    half = (lc[1] - lc[0]) / 2 if lc.size > 1 else 0.5
    edges = np.exp(np.concatenate([[lc[0] - half], (lc[1:] + lc[:-1]) / 2, [lc[-1] + half]]))
    idx = np.searchsorted(edges, x, side="right") - 1
    nb = centers.size
    idx = np.where((idx >= 0) & (idx < nb) & (x > 0), idx, nb)
    lx = np.log(np.where(x > 0, x, 1.0))
    flat = y.reshape(-1, y.shape[-1])
    out = np.full((flat.shape[0], nb), np.nan)
    for i, row in enumerate(flat):
        ok = np.isfinite(row)
        counts = np.bincount(idx[ok], minlength=nb + 1)[:nb]
        weight = np.bincount(idx[ok], weights=w[ok], minlength=nb + 1)[:nb]
        full = (counts > 0) & (weight >= min_weight)
        if not full.any():
            continue
        means = np.bincount(idx[ok], weights=row[ok], minlength=nb + 1)[:nb][full] / counts[full]
        at = np.bincount(idx[ok], weights=lx[ok], minlength=nb + 1)[:nb][full] / counts[full]
        out[i, full] = _loglog_line(at, means, lc[full])
    return out.reshape(y.shape[:-1] + (nb,))


def _loglog_line(lx: np.ndarray, y: np.ndarray, lxnew: np.ndarray) -> np.ndarray:
    """Piecewise log-log linear through ``(lx, y)``, extended by the end segments; ``y`` as is where
    a log is undefined (non-positive values or a single point)."""
    if lx.size < 2 or np.any(y <= 0):
        return y
    ly = np.log(y)
    j = np.clip(np.searchsorted(lx, lxnew) - 1, 0, lx.size - 2)
    dx = lx[j + 1] - lx[j]
    t = np.where(dx > 0, (lxnew - lx[j]) / np.where(dx > 0, dx, 1.0), 0.0)
    return np.exp(ly[j] + t * (ly[j + 1] - ly[j]))
