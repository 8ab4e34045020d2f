"""Putting curves of several measurements onto common log-spaced collocation points:
log-log interpolation (smooth, sparse curves) and log-bin averaging (dense, noisy curves)."""

from __future__ import annotations

import numpy as np

__all__ = ["interp_loglog", "collocation_points", "bin_mean", "bin_error", "select_for_mean", "fill_inside",
           "equal_weight_mean", "collocate", "collocate_error"]


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
    rows = int(np.prod(y.shape[:-1]))                  # explicit: a curve without samples is all NaN
    flat_y = y.reshape(rows, y.shape[-1])
    flat_o = out.reshape(rows, xnew.size)
    for i, row in enumerate(flat_y):
        ok = np.isfinite(row) & (row > 0) & np.isfinite(lx_all)
        if ok.sum() < 2:
            if ok.sum() == 1:
                j = np.flatnonzero(ok)[0]
                flat_o[i, np.isclose(xnew, x[j], rtol=1e-9)] = row[j]
            continue
        lx, ly = lx_all[ok], np.log(row[ok])
        order = np.argsort(lx, kind="stable")  # np.interp needs increasing abscissae (a curve may run downwards)
        lx, ly = lx[order], ly[order]
        inside = (lxn >= lx[0] - 1e-12) & (lxn <= lx[-1] + 1e-12)
        flat_o[i, inside] = np.exp(np.interp(lxn[inside], lx, ly))
    return out


def bin_mean(y: np.ndarray, x: np.ndarray, xnew: np.ndarray) -> np.ndarray:
    """Mean of ``y[..., n]`` (at abscissae ``x[n]``) over log bins, evaluated at the bin centres ``xnew``.

    Bin edges lie at the geometric midpoints between the points of ``xnew`` (and half a bin
    beyond the first and last). The mean of a bin belongs to the mean ``log x`` of its
    samples, not to its centre (a sparse bin, e.g. one sample near an edge, would otherwise
    shift a steep curve by up to half a bin): each non-empty bin's value is the log-log line
    through the neighbouring bin means, evaluated at its centre (at most half a bin away).
    NaN samples are ignored; empty bins are NaN.
    """
    y = np.asarray(y, dtype=float)
    x = np.asarray(x, dtype=float)
    centers = np.asarray(xnew, dtype=float)
    lc = np.log(centers)
    idx = _bin_index(x, centers)
    nb = centers.size
    lx = np.log(np.where(x > 0, x, 1.0))
    flat = y.reshape(-1, y.shape[-1])
    out = np.full((flat.shape[0], nb), np.nan)
    for i, row in enumerate(flat):
        ok = np.isfinite(row)
        counts = np.bincount(idx[ok], minlength=nb + 1)[:nb]
        full = counts > 0
        if not full.any():
            continue
        means = np.bincount(idx[ok], weights=row[ok], minlength=nb + 1)[:nb][full] / counts[full]
        at = np.bincount(idx[ok], weights=lx[ok], minlength=nb + 1)[:nb][full] / counts[full]
        out[i, full] = _loglog_line(at, means, lc[full])
    return out.reshape(y.shape[:-1] + (nb,))


def fill_inside(values: np.ndarray, y: np.ndarray, x: np.ndarray, xnew: np.ndarray) -> np.ndarray:
    """``values[..., len(xnew)]`` (e.g. bin means) with its NaN points inside the range of each row's
    finite samples ``y[..., n]`` (at ``x[n]``) filled by log-log interpolation between those samples.

    A curve sampled more sparsely than the collocation points (the long wavelengths of a
    spectrum, ``q = 2πk/L``) thus reaches every collocation point between its first and last
    sample instead of leaving empty bins between its samples.
    """
    values = np.asarray(values, dtype=float)
    gaps = np.isnan(values)
    if not gaps.any():
        return values
    return np.where(gaps, interp_loglog(y, x, xnew), values)


def collocate(y: np.ndarray, x: np.ndarray, xnew: np.ndarray, method: str = "bin") -> np.ndarray:
    """Curves ``y[..., n]`` (at ``x[n]``) at the collocation points ``xnew``.

    ``"interp"``: log-log interpolation (smooth or sparse curves); ``"bin"``: mean of the
    samples in the log bin of each point (:func:`bin_mean`), and between samples sparser than
    the bins log-log interpolation (:func:`fill_inside`). Either way every point inside the
    range of a row's finite samples gets a value; points outside it are NaN. Samples that are not
    positive have no place on log-log axes (a degenerate window's zero RMS height) and are ignored.
    """
    y = np.asarray(y, dtype=float)
    y = np.where(y > 0, y, np.nan)
    if method == "interp":
        return interp_loglog(y, x, xnew)
    return fill_inside(bin_mean(y, x, xnew), y, x, xnew)


def collocate_error(err: np.ndarray, y: np.ndarray, x: np.ndarray, xnew: np.ndarray, method: str = "bin",
                    modes=None) -> np.ndarray:
    """Relative standard error of :func:`collocate` ``(y, x, xnew, method)`` from that of its samples.

    ``err[..., n]``: the samples' relative standard errors (ignored where ``y`` is NaN). With
    ``modes`` (independent Fourier modes of each sample of a spectrum) a bin holding ``N`` modes
    has ``1/√N`` (:func:`bin_error`); otherwise a bin has the mean error of its samples (neighbouring
    samples are correlated). Interpolated points have the interpolated error of their neighbours.
    """
    err = np.where(np.isfinite(y) & (np.asarray(y) > 0), np.broadcast_to(np.asarray(err, dtype=float), np.shape(y)), np.nan)
    if method == "interp":
        return interp_loglog(err, x, xnew)
    if modes is not None:
        binned = bin_error(np.where(np.asarray(y) > 0, y, np.nan), x, xnew, modes)
        binned = np.where(np.isfinite(binned), binned, np.nan)
    else:
        binned = bin_mean(err, x, xnew)
    return fill_inside(binned, err, x, xnew)


def equal_weight_mean(values: np.ndarray, errors: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Equal-weight mean over the last axis of the finite ``values[..., m]`` and its standard error.

    ``errors[..., m]`` are the relative standard errors of the values (NaN: unknown). The
    measurements are independent, so the standard error of the mean of ``n`` values is
    ``√(Σ (σ_i y_i)²) / n``; NaN where a used value's error is unknown.

    Returns
    -------
    mean, standard_error : numpy.ndarray, shape ``[...]``
        NaN where no value is finite.
    count : numpy.ndarray of int, shape ``[...]``
    """
    values = np.asarray(values, dtype=float)
    used = np.isfinite(values)
    count = used.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(used, values, 0.0).sum(axis=-1) / np.where(count > 0, count, np.nan)
        var = np.where(used, (np.asarray(errors, dtype=float) * values) ** 2, 0.0).sum(axis=-1)
        unknown = (used & ~np.isfinite(np.asarray(errors, dtype=float))).any(axis=-1)
        se = np.where(unknown | (count == 0), np.nan, np.sqrt(var) / np.where(count > 0, count, 1))
    return mean, se, count


def _bin_index(x: np.ndarray, centers: np.ndarray) -> np.ndarray:
    """Log bin of each ``x`` around ``centers`` (edges at the geometric midpoints, half a bin beyond
    the ends); ``len(centers)`` for samples outside every bin."""
    lc = np.log(centers)
    half = (lc[1] - lc[0]) / 2 if lc.size > 1 else 0.5
    edges = np.exp(np.concatenate([[lc[0] - half], (lc[1:] + lc[:-1]) / 2, [lc[-1] + half]]))
    idx = np.searchsorted(edges, x, side="right") - 1
    return np.where((idx >= 0) & (idx < centers.size) & (x > 0), idx, centers.size)


def bin_error(y: np.ndarray, x: np.ndarray, xnew: np.ndarray, weights) -> np.ndarray:
    """Relative standard error ``1/√N`` of the log bins of :func:`bin_mean`, where ``N`` sums the
    ``weights`` (independent samples) of the finite samples of ``y[..., n]`` in a bin (``inf`` if 0)."""
    y = np.asarray(y, dtype=float)
    centers = np.asarray(xnew, dtype=float)
    idx = _bin_index(np.asarray(x, dtype=float), centers)
    w = np.broadcast_to(np.asarray(weights, dtype=float), idx.shape)
    flat = y.reshape(-1, y.shape[-1])
    out = np.zeros((flat.shape[0], centers.size))
    for i, row in enumerate(flat):
        ok = np.isfinite(row)
        out[i] = np.bincount(idx[ok], weights=w[ok], minlength=centers.size + 1)[:centers.size]
    with np.errstate(divide="ignore"):
        return 1 / np.sqrt(out.reshape(y.shape[:-1] + (centers.size,)))


def select_for_mean(values: np.ndarray, errors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which of ``values[..., m]`` enter an equal-weight mean, and its predicted relative standard error.

    The finite values are taken in order of increasing predicted relative error
    ``errors[..., m]`` (NaN: unknown, treated as infinite) as long as the next one lowers the
    error of the mean of independent estimates, ``σ_mean = √(Σ σ_i²)/n``.

    Returns
    -------
    used : numpy.ndarray of bool, shape ``[..., m]``
    sigma : numpy.ndarray, shape ``[...]``
        ``σ_mean`` of the selection (``inf`` where no value is finite).
    """
    values = np.asarray(values, dtype=float)
    err = np.where(np.isfinite(values), np.nan_to_num(np.asarray(errors, dtype=float), nan=np.inf), np.inf)
    order = np.argsort(err, axis=-1, kind="stable")
    s = np.take_along_axis(err, order, axis=-1)
    n = np.arange(1, s.shape[-1] + 1)
    with np.errstate(invalid="ignore", over="ignore"):
        sigma = np.sqrt(np.cumsum(s**2, axis=-1)) / n
    finite = np.isfinite(values).any(axis=-1)
    # the prefix grows while each next value lowers sigma (NaN comparisons from inf - inf are False)
    lowers = np.concatenate([np.ones(s.shape[:-1] + (1,), bool), sigma[..., 1:] < sigma[..., :-1]], axis=-1)
    take = np.logical_and.accumulate(lowers, axis=-1) & np.isfinite(s)
    k = take.sum(axis=-1)
    best = np.where(k > 0, np.take_along_axis(sigma, np.maximum(k - 1, 0)[..., None], axis=-1)[..., 0], np.inf)
    used = np.zeros_like(take)
    np.put_along_axis(used, order, take, axis=-1)
    return used, np.where(finite, best, np.inf)


def _loglog_line(lx: np.ndarray, y: np.ndarray, lxnew: np.ndarray) -> np.ndarray:
    """Piecewise log-log linear through ``(lx, y)``; beyond an end, the line from the end point with
    the slope of the segment next to the end one (the end value's scatter is not levered out); ``y`` as is where
    a log is undefined (non-positive values or a single point)."""
    if lx.size < 2 or np.any(y <= 0):
        return y
    ly = np.log(y)
    j = np.clip(np.searchsorted(lx, lxnew) - 1, 0, lx.size - 2)
    dx = lx[j + 1] - lx[j]
    t = np.where(dx > 0, (lxnew - lx[j]) / np.where(dx > 0, dx, 1.0), 0.0)
    out = ly[j] + t * (ly[j + 1] - ly[j])
    if lx.size >= 3:  # beyond an end: from the end point with the slope of the next segment inward
        out = np.where(lxnew < lx[0], ly[0] + _slope(lx, ly, 1) * (lxnew - lx[0]), out)
        out = np.where(lxnew > lx[-1], ly[-1] + _slope(lx, ly, -3) * (lxnew - lx[-1]), out)
    return np.exp(out)


def _slope(lx: np.ndarray, ly: np.ndarray, j: int) -> float:
    dx = lx[j + 1] - lx[j]
    return float((ly[j + 1] - ly[j]) / dx) if dx > 0 else 0.0
