"""ISO 25178-2 feature parameters (§5): watershed segmentation with Wolf pruning, numpy + numba.

Dales are segmented on ``z``, hills on ``-z``:

1. every pixel flows to its lowest strictly lower 8-neighbour; the pixels reaching the same
   local minimum form a basin (the over-segmented watershed);
2. neighbouring basins meet at saddles: the height ``max(z_a, z_b)`` of a pair of 8-neighbour
   pixels in different basins; taken in ascending order these merge basins the way a
   rising water level would;
3. Wolf pruning: when two motifs meet at a saddle, the shallower one (the higher minimum) has
   local depth ``saddle - minimum``; below the threshold (a share of Sz) it is merged into the
   other, at or above it it is significant and keeps its region. Merging the shallowest
   motif first, as Wolf pruning does, and this elder rule give the same significant
   motifs: a motif that meets a deeper one first at its lowest saddle is the shallower one there.

A motif whose region (its basin and the basins merged into it) reaches the border of a
nonperiodic map is incomplete and left out. Periodic maps wrap around.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["significant_extrema", "FEATURES", "feature_parameters"]

_JIT = dict(nogil=True, cache=True)

#: names and order of :func:`feature_parameters`' outputs
FEATURES = ("Spd", "Spc", "S10z", "S5p", "S5v")
_OFFSETS = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)], np.int64)


@njit(inline="always")
def _neighbour(r, c, k, ny, nx, periodic):
    """Flat index of the ``k``-th 8-neighbour of pixel (r, c), wrapped on periodic maps; -1 off a nonperiodic map."""
    rr = r + _OFFSETS[k, 0]
    cc = c + _OFFSETS[k, 1]
    if periodic:
        return (rr % ny) * nx + cc % nx
    if rr < 0 or rr >= ny or cc < 0 or cc >= nx:
        return -1
    return rr * nx + cc


@njit(**_JIT)
def _basins(z, periodic):
    """Flat index of the local minimum every pixel flows down to (steepest descent over 8 neighbours)."""
    ny, nx = z.shape
    n = ny * nx
    zf = z.ravel()
    down = np.empty(n, np.int64)
    for r in range(ny):
        for c in range(nx):
            best = z[r, c]
            to = r * nx + c
            for k in range(8):
                j = _neighbour(r, c, k, ny, nx, periodic)
                if j < 0:
                    continue
                v = zf[j]
                if v < best:
                    best = v
                    to = j
            down[r * nx + c] = to
    # pointer jumping: follow the flow to its end, compressing the paths
    for i in range(n):
        j = i
        while down[j] != j:
            j = down[j]
        k = i
        while down[k] != j:
            nxt = down[k]
            down[k] = j
            k = nxt
    return down


@njit(**_JIT)
def _saddle_table(z, basin, periodic, size):
    """Open-addressing table (``size``: a power of 2) of touching basin pairs and their lowest saddle.

    None if the table fills beyond half (call again with a larger ``size``).
    """
    ny, nx = z.shape
    n = ny * nx
    zf = z.ravel()
    keys = np.full(size, -1, np.int64)
    vals = np.empty(size)
    used = 0
    mask = size - 1
    for r in range(ny):
        for c in range(nx):
            i = r * nx + c
            for k in range(4, 8):  # each unordered pair once: right, down-left, down, down-right
                j = _neighbour(r, c, k, ny, nx, periodic)
                if j < 0:
                    continue
                bi = basin[i]
                bj = basin[j]
                if bi == bj:
                    continue
                key = min(bi, bj) * n + max(bi, bj)
                v = max(zf[i], zf[j])
                h = ((key * 0x9E3779B1) >> 7) & mask
                while keys[h] != -1 and keys[h] != key:
                    h = (h + 1) & mask
                if keys[h] == -1:
                    used += 1
                    if 2 * used > size:
                        return None
                    keys[h] = key
                    vals[h] = v
                elif v < vals[h]:
                    vals[h] = v
    keep = keys != -1
    return keys[keep] // n, keys[keep] % n, vals[keep]


def _saddles(z, basin, periodic):
    """Pairs of basins that touch (as 8-neighbours) and their saddle, the lowest ``max(z_a, z_b)`` of their pixels."""
    basins = int(np.count_nonzero(basin == np.arange(basin.size)))
    size = 1 << max(10, int(np.ceil(np.log2(16 * basins))))  # about 6 neighbours a basin: rarely refilled
    while True:
        out = _saddle_table(z, basin, periodic, size)
        if out is not None:
            return out
        size *= 4


@njit(**_JIT)
def _find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(**_JIT)
def _prune(zflat, basin, a, b, s, order, threshold, edge):
    """Wolf pruning (elder rule) over the saddles in ``order``; the minima of the significant complete motifs."""
    n = zflat.size
    parent = np.arange(n)
    closed = np.zeros(n, np.bool_)
    touches = edge.copy()  # per basin root: its region reaches the border
    for t in range(order.size):
        e = order[t]
        ra = _find(parent, a[e])
        rb = _find(parent, b[e])
        if ra == rb or (closed[ra] and closed[rb]):
            continue
        # ra: the shallower motif (higher minimum; ties by index), the one that may die here
        if zflat[ra] < zflat[rb] or (zflat[ra] == zflat[rb] and ra < rb):
            ra, rb = rb, ra
        if closed[ra]:
            continue  # already significant: keeps its region
        if s[e] - zflat[ra] < threshold:
            parent[ra] = rb
            touches[rb] = touches[rb] or touches[ra]
        else:
            closed[ra] = True
    out = []
    for i in range(n):
        if basin[i] == i and parent[i] == i and not touches[i]:
            out.append(i)
    return np.array(out, np.int64)


def significant_extrema(z: np.ndarray, threshold: float, periodic: bool) -> np.ndarray:
    """Flat indices of the pits of the significant, complete dales of ``z[ny, nx]`` (finite)."""
    ny, nx = z.shape
    basin = _basins(z, periodic)
    a, b, s = _saddles(z, basin, periodic)
    order = np.argsort(s, kind="stable")
    edge = np.zeros(ny * nx, np.bool_)
    if not periodic:
        border = np.zeros((ny, nx), np.bool_)
        border[0, :] = border[-1, :] = border[:, 0] = border[:, -1] = True
        edge[basin[border.ravel()]] = True
    return _prune(z.ravel(), basin, a, b, s, order, threshold, edge)


def _curvature(z, idx, dy, dx, periodic):
    """``-(1/2)(∂²z/∂x² + ∂²z/∂y²)`` at flat indices ``idx`` (central second differences); NaN on the border."""
    ny, nx = z.shape
    r, c = np.divmod(idx, nx)
    if not periodic:
        keep = (r > 0) & (r < ny - 1) & (c > 0) & (c < nx - 1)
        r, c = r[keep], c[keep]
    zxx = (z[r, (c + 1) % nx] - 2 * z[r, c] + z[r, (c - 1) % nx]) / dx**2
    zyy = (z[(r + 1) % ny, c] - 2 * z[r, c] + z[(r - 1) % ny, c]) / dy**2
    return -0.5 * (zxx + zyy)


def feature_parameters(z: np.ndarray, dy: float, dx: float, periodic: bool, pruning: float) -> np.ndarray:
    """Spd, Spc, S10z, S5p, S5v of ``z[ny, nx]`` (mean removed); NaN if it has missing points.

    ``pruning``: Wolf pruning threshold in % of Sz. Spd counts the significant complete hills
    per unit area (the map's area ``nx Δx · ny Δy``); Spc is their mean curvature at the peak;
    S5p the mean height of the five highest peaks, S5v the mean depth of the five deepest
    pits (fewer when there are fewer), S10z their sum.
    """
    if not np.isfinite(z).all():
        return np.full(len(FEATURES), np.nan)
    threshold = pruning / 100 * float(z.max() - z.min())
    peaks = significant_extrema(-z, threshold, periodic)
    pits = significant_extrema(z, threshold, periodic)
    flat = z.ravel()
    ny, nx = z.shape
    spd = peaks.size / (ny * dy * nx * dx)
    curv = _curvature(z, peaks, dy, dx, periodic)
    spc = float(curv.mean()) if curv.size else np.nan
    s5p = float(np.sort(flat[peaks])[::-1][:5].mean()) if peaks.size else np.nan
    s5v = float(np.sort(-flat[pits])[::-1][:5].mean()) if pits.size else np.nan
    return np.array([spd, spc, s5p + s5v, s5p, s5v])
