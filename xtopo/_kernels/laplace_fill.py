"""Harmonic (Laplace) filling of missing data (pure numpy/scipy; paper §3.2).

Every missing pixel ``p`` gets the value that makes the discrete Laplacian vanish,

    Σ_q w_pq (h_q − h_p) = 0,   w = 1/Δx² for x-neighbours, 1/Δy² for y-neighbours,

with the known pixels around each island of missing data as Dirichlet values. Periodic maps
wrap around; on a nonperiodic map a neighbour outside the map is simply absent (the natural,
zero-normal-slope condition: the fill still minimises the RMS slope). One sparse solve
covers all islands (they decouple). The result is exact for linear fields when the hole
does not touch a nonperiodic border, and it obeys the mean-value and maximum principles.
Line scans are interpolated linearly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["harmonic_fill_2d", "linear_fill_1d"]


def _fill_one(h, periodic, wy, wx):
    missing = ~np.isfinite(h)
    if not missing.any():
        return h
    if missing.all():
        raise ValueError("all data are missing; there is nothing to fill from")
    import scipy.sparse
    import scipy.sparse.linalg

    ny, nx = h.shape
    unknown = np.flatnonzero(missing)
    n = unknown.size
    index = np.full(h.size, -1, dtype=np.int64)
    index[unknown] = np.arange(n)
    iy, ix = np.divmod(unknown, nx)
    known = np.where(missing, 0.0, h).ravel()
    diag = np.zeros(n)
    rhs = np.zeros(n)
    rows, cols = [], []
    for dy, dx, w in ((1, 0, wy), (-1, 0, wy), (0, 1, wx), (0, -1, wx)):
        jy, jx = iy + dy, ix + dx
        if periodic:
            jy %= ny
            jx %= nx
            ok = np.ones(n, dtype=bool)
        else:
            ok = (jy >= 0) & (jy < ny) & (jx >= 0) & (jx < nx)
        ok &= (ny > 1) if dy else (nx > 1)  # no self-coupling on degenerate axes
        src = np.flatnonzero(ok)
        nb = jy[src] * nx + jx[src]
        diag[src] += w
        nb_idx = index[nb]
        is_unknown = nb_idx >= 0
        rows.append(src[is_unknown])
        cols.append(nb_idx[is_unknown])
        np.add.at(rhs, src[~is_unknown], w * known[nb[~is_unknown]])
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    # off-diagonal weights, in the order the directions were visited
    weights = np.concatenate([np.full(rr.size, w) for rr, w in zip(rows, (wy, wy, wx, wx))])
    off = scipy.sparse.csr_matrix((-weights, (r, c)), shape=(n, n))
    A = (off + scipy.sparse.diags(diag)).tocsc()
    values = scipy.sparse.linalg.spsolve(A, rhs)
    out = np.array(h, dtype=float, copy=True)
    out.ravel()[unknown] = values
    return out


def harmonic_fill_2d(h, periodic: bool = False, dy: float = 1.0, dx: float = 1.0):
    """Fill NaNs in maps ``h[..., ny, nx]`` with the discrete harmonic interpolant (see module doc)."""
    h = np.asarray(h, dtype=float)
    ny, nx = h.shape[-2:]
    batch = h.reshape(-1, ny, nx)
    out = np.stack([_fill_one(b, periodic, 1.0 / dy ** 2, 1.0 / dx ** 2) for b in batch])
    return out.reshape(h.shape)


def linear_fill_1d(h, x, periodic: bool = False, period: float | None = None):
    """Fill NaNs in line scans ``h[..., n]`` at positions ``x`` by linear interpolation.

    Missing points before the first (after the last) valid point take its value, unless the
    scan is ``periodic`` (then interpolation wraps with ``period``).
    """
    h = np.asarray(h, dtype=float)
    x = np.asarray(x, dtype=float)
    batch = h.reshape(-1, h.shape[-1])
    out = np.array(batch, copy=True)
    for row in out:
        bad = ~np.isfinite(row)
        if not bad.any():
            continue
        if bad.all():
            raise ValueError("all data are missing; there is nothing to fill from")
        row[bad] = np.interp(x[bad], x[~bad], row[~bad], period=period if periodic else None)
    return out.reshape(h.shape)
