"""Predicted statistical error of mean-square stencil estimators (ACF, scale-dependent slope/curvature).

For a Gaussian surface with variogram (height-difference ACF) ``γ(r) = ½⟨(h(r₀+r) - h(r₀))²⟩``,
the stencil ``D(x) = Σ_i w_i h(x + a_i)`` (``Σ w_i = 0``) has the covariance
``Cov(D(x), D(x')) = -Σ_ij w_i w_j γ(|x - x' + a_i - a_j|)`` (the constant of a
stationary covariance cancels because the weights sum to zero), and the mean of ``D²``
over ``M`` points of each of ``R`` rows a distance ``d`` apart has the variance
``Var = 2/(M R)² Σ_(s,j) (M - |s|)(R - |j|) Cov(s, j d)²`` (Isserlis). No power spectrum
beyond the scan is needed: the variogram holds all wavelengths, including those longer
than the window, which dominate the variance of self-affine surfaces with ``H > 3/4``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["variogram_from_samples", "mean_square_relative_error"]


def _log_slope(lr: np.ndarray, lg: np.ndarray, sel: np.ndarray, default: float) -> float:
    if sel.sum() < 2:
        return default
    return float(np.polyfit(lr[sel], lg[sel], 1)[0])


def variogram_from_samples(acf: np.ndarray, lags: np.ndarray):
    """A callable ``γ(r)`` for ``r ≥ 0`` from sampled values: log-log interpolation between samples,
    power laws beyond (exponent of the outer half decade at each end, clipped to ``[0, 2]``); ``γ(0) = 0``.

    Returns ``None`` when fewer than two samples are finite and positive.
    """
    acf = np.asarray(acf, dtype=float)
    lags = np.asarray(lags, dtype=float)
    ok = np.isfinite(acf) & (acf > 0) & (lags > 0)
    if ok.sum() < 2:
        return None
    lr, lg = np.log(lags[ok]), np.log(acf[ok])
    lo_slope = float(np.clip(_log_slope(lr, lg, lr <= lr[0] + np.log(3.0), 2.0), 0.0, 2.0))
    hi_slope = float(np.clip(_log_slope(lr, lg, lr >= lr[-1] - np.log(3.0), 0.0), 0.0, 2.0))

    def gamma(r):
        r = np.abs(np.asarray(r, dtype=float))
        with np.errstate(divide="ignore", invalid="ignore"):
            x = np.log(r)
            out = np.asarray(np.interp(x, lr, lg))  # an array also of one lag
            for side, end, slope in ((x < lr[0], 0, lo_slope), (x > lr[-1], -1, hi_slope)):
                out[side] = lg[end] + slope * (x[side] - lr[end])
        out = np.exp(out, out=out)
        out[r == 0] = 0.0
        return out

    return gamma


def _quadrature(count: int, dense: int, per_octave: int = 12):
    """Nodes ``0 ≤ s < count`` and weights approximating ``Σ_{s=0}^{count-1} f(s)`` for smooth ``f`` at large ``s``:
    every integer up to ``dense``, then log-spaced nodes each standing for the integers nearest to it."""
    if count <= dense:
        nodes = np.arange(count, dtype=float)
        return nodes, np.ones_like(nodes)
    octaves = np.log2(count / dense)
    far = np.unique(np.round(np.geomspace(dense, count - 1, max(2, int(np.ceil(octaves * per_octave))) + 1)))
    nodes = np.concatenate([np.arange(dense, dtype=float), far[far >= dense]])
    edges = np.concatenate([nodes[:dense] - 0.5, [dense - 0.5], (nodes[dense:-1] + nodes[dense + 1:]) / 2,
                            [count - 0.5]])
    weights = np.diff(edges)
    return nodes, weights


def mean_square_relative_error(gamma, lengths, *, offsets, weights, n: int, dx: float, rows: int = 1,
                               row_spacing: float = 0.0) -> np.ndarray:
    """Relative standard error of ``mean(D²)`` over a scan, for each stencil length in ``lengths``.

    Parameters
    ----------
    gamma : callable
        Variogram ``γ(r)`` (length² for r in length units).
    lengths : array_like
        Stencil lengths ``ℓ``.
    offsets, weights : array_like
        Stencil positions in units of ``ℓ`` (e.g. ``[0, 1]`` and ``[-1, 1]`` for a difference) and weights.
    n, dx : int, float
        Points per profile and their spacing; a stencil of span ``ℓ`` fits ``n - span/dx`` times.
    rows, row_spacing : int, float
        Parallel profiles averaged together and their distance.

    Returns
    -------
    numpy.ndarray
        ``std(mean D²) / E[D²]``; NaN where the stencil does not fit.
    """
    a = np.asarray(offsets, dtype=float)
    w = np.asarray(weights, dtype=float)
    diff = (a[:, None] - a[None, :]).ravel()
    pair_w = (w[:, None] * w[None, :]).ravel()
    pair_a, pair = np.unique(diff, return_inverse=True)  # pairs of one offset a_i - a_j share their γ
    offset_w = np.bincount(pair, weights=pair_w, minlength=pair_a.size)  # and enter Cov with their summed weight
    zero = pair_a == 0
    j_nodes, j_weights = _quadrature(max(int(rows), 1), 16)
    ds = j_nodes * row_spacing
    # γ at the lags of the zero offset (the pairs i = j) do not depend on ℓ: for every point of the profile at once
    at_zero = gamma(np.hypot(np.arange(n, dtype=float) * dx, ds[:, None]))
    out = np.full(np.size(lengths), np.nan)
    for i, ell in enumerate(np.atleast_1d(np.asarray(lengths, dtype=float))):
        span = (a.max() - a.min()) * ell
        m = int(np.floor(n - span / dx + 1e-9))
        if m < 1 or ell <= 0:
            continue
        dense = int(min(m, max(64, 8 * np.ceil(span / dx))))
        s_nodes, s_weights = _quadrature(m, dense)
        # Cov(s, d) = -Σ_ij w_i w_j γ(√((s + a_i - a_j)² + d²)), shape (rows nodes, s nodes), summed per offset
        # a_i - a_j; γ on (offsets, rows nodes, s nodes): its interpolation walks the samples in order along s (in
        # random order: 10x slower)
        g = np.empty((pair_a.size, ds.size, s_nodes.size))
        g[~zero] = gamma(np.hypot(s_nodes * dx + ell * pair_a[~zero, None, None], ds[:, None]))
        g[zero] = at_zero[:, s_nodes.astype(int)]
        cov = -np.tensordot(offset_w, g, axes=1)
        mult_s = s_weights * (m - s_nodes) * np.where(s_nodes > 0, 2.0, 1.0)
        mult_j = j_weights * (rows - j_nodes) * np.where(j_nodes > 0, 2.0, 1.0)
        var = 2.0 * np.sum(mult_j[:, None] * mult_s[None, :] * cov**2) / (m * rows) ** 2
        mean = -np.sum(pair_w * gamma(ell * np.abs(diff)))
        out[i] = np.sqrt(var) / mean if mean > 0 else np.nan
    return out
