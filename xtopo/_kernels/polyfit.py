"""Least-squares polynomial backgrounds (pure numpy).

Heights arrive with the lateral core dims last; NaN marks missing data, which is ignored
by the fit and stays NaN. Positions are centred and scaled to [-1, 1] before building the
design matrix, so the fit is well conditioned for any physical unit.
"""

from __future__ import annotations

import numpy as np

__all__ = ["DEGREES", "subtract_polynomial_2d", "subtract_polynomial_1d"]

#: Polynomial degree of each detrend mode.
DEGREES = {"mean": 0, "plane": 1, "curvature": 2}


def _scaled(v):
    v = np.asarray(v, dtype=float)
    half = 0.5 * (v.max() - v.min()) if v.size > 1 else 1.0
    return (v - 0.5 * (v.max() + v.min())) / (half if half > 0 else 1.0)


def _design_1d(x, degree):
    u = _scaled(x)
    return np.stack([u ** k for k in range(degree + 1)], axis=-1)


def _design_2d(y, x, degree):
    v, u = np.meshgrid(_scaled(y), _scaled(x), indexing="ij")
    cols = [u ** (total - j) * v ** j for total in range(degree + 1) for j in range(total + 1)]
    return np.stack([c.ravel() for c in cols], axis=-1)


def _subtract(A, values):
    """``values`` (n_points, n_series) minus their least-squares fits on the columns of ``A``.

    Series without missing data share one solve; series with NaN are fitted on their finite points.
    """
    out = np.array(values, dtype=float, copy=True)
    finite = np.isfinite(out)
    full = finite.all(axis=0)
    if full.any():
        coef, *_ = np.linalg.lstsq(A, out[:, full], rcond=None)
        out[:, full] -= A @ coef
    for j in np.flatnonzero(~full):
        ok = finite[:, j]
        if ok.sum() >= A.shape[1]:
            coef, *_ = np.linalg.lstsq(A[ok], out[ok, j], rcond=None)
            out[ok, j] -= A[ok] @ coef
        elif ok.any():  # too few points for this degree: remove the mean only
            out[ok, j] -= out[ok, j].mean()
    return out


def subtract_polynomial_2d(h, y, x, degree: int, per_line: bool = False):
    """Remove a least-squares polynomial of ``degree`` from maps ``h[..., ny, nx]``.

    The polynomial has every monomial ``x^i y^j`` with ``i + j <= degree``.

    With ``per_line`` every row (profile along ``x``) gets its own 1D polynomial.
    """
    h = np.asarray(h, dtype=float)
    ny, nx = h.shape[-2:]
    batch = h.reshape(-1, ny, nx)
    if per_line:
        A = _design_1d(x, degree)
        cols = batch.transpose(2, 0, 1).reshape(nx, -1)  # (nx, batch * ny)
        res = _subtract(A, cols).reshape(nx, -1, ny).transpose(1, 2, 0)
    else:
        A = _design_2d(y, x, degree)
        res = _subtract(A, batch.reshape(-1, ny * nx).T).T.reshape(-1, ny, nx)
    return res.reshape(h.shape)


def subtract_polynomial_1d(h, x, degree: int):
    """Remove a least-squares polynomial of ``degree`` from line scans ``h[..., n]`` at positions ``x``."""
    h = np.asarray(h, dtype=float)
    n = h.shape[-1]
    A = _design_1d(x, degree)
    return _subtract(A, h.reshape(-1, n).T).T.reshape(h.shape)
