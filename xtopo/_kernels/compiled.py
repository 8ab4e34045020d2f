"""Compiled passes of the contact solver's iteration (numba), one pass where numpy takes several.

The Polonsky–Keer iteration (:mod:`xtopo._kernels.pk_solver`) works on index sets: the gaps
of the contact set, the overlaps among the free points, the search direction and the
pressure increments written into transform buffers. Written with numpy each of these is a
chain of gathers, temporaries and reductions — about sixty calls per iteration, which cost
more than the iteration's FFTs on grids up to 1024². Each function here does one such chain
in one pass, without temporaries.

Index conventions: ``idx`` are flat indices into the active grid; the transform buffers
are addressed through :func:`_slot` (``nx`` the active row length, ``pad`` the extra
columns of a buffer row: 0 on line grids, 1–2 on periodic ones (rfft rows), ``nx + 2`` on
padded ones). The contact set is kept as buffer positions (``slots``): the passes over it
every iteration then index without an integer division per point (2× faster).
Functions release the GIL (solves in threads run in parallel) and are cached on disk
after their first compilation.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import overload

__all__ = ["slots", "slots_into", "flat_indices", "scatter", "gather_gaps", "center", "contact_gaps",
           "scan_overlaps", "set_direction", "energy", "scale_spectrum", "reference_gaps", "rebase", "split_sets",
           "step_project", "join"]

_JIT = dict(nogil=True, cache=True)
# reductions may be reordered (vectorised); inf and nan keep their meaning (the overlap test uses +inf)
_FAST = dict(_JIT, fastmath={"reassoc", "contract", "nsz", "arcp"})


@njit(inline="always")
def _at(i):
    """An index known to be ≥ 0: no wraparound test (which would keep loops from vectorising)."""
    return np.uintp(i)


@njit(inline="always")
def _slot(i, nx, pad):
    """Position in a transform buffer of flat active-grid index ``i``."""
    return np.uintp(i + (i // nx) * pad) if pad else np.uintp(i)


@njit(nogil=True, cache=True)
def slots(where, nx, pad):
    """Positions in a transform buffer of flat active-grid indices ``where`` (a new array)."""
    out = np.empty(where.size, np.intp)
    return slots_into(where, nx, pad, out)


@njit(nogil=True, cache=True)
def slots_into(where, nx, pad, out):
    """:func:`slots` written into ``out`` (which may be ``where`` itself); returns ``out``."""
    for j in range(where.size):
        out[j] = _slot(where[j], nx, pad)
    return out


@njit(nogil=True, cache=True)
def scatter(where, values, nx, pad, buf):
    """``buf[slot(where)] = values``; a single value is written at every point."""
    one = values.size == 1
    for j in range(where.size):
        buf[_slot(where[j], nx, pad)] = values[0] if one else values[j]


def _magnitudes(d):
    """``d``'s bits as integers and the mask that clears their sign: masked, in the order of ``|d|`` (nan above all)."""


@overload(_magnitudes)
def _magnitudes_jit(d):
    bits = np.int64 if d.dtype.bitwidth == 64 else np.int32
    mask = bits(np.iinfo(bits).max)
    return lambda d: (d.view(bits), mask)


@njit(**_FAST)
def center(d, shift):
    """``d -= shift`` in place; returns ``(max |d|, Σ d²)`` (the residual and the CG norm; a nan in ``d``: nan).

    The maximum is taken over :func:`_magnitudes`: an integer maximum vectorises, a float one did not (5×)."""
    ss = 0.0
    for j in range(d.size):
        v = d[j] - shift
        d[j] = v
        ss += float(v) * float(v)
    bits, mask = _magnitudes(d)
    big = np.zeros(1, bits.dtype)
    for j in range(d.size):
        big[0] = max(big[0], bits[j] & mask)
    return big.view(d.dtype)[0], ss


@njit(**_FAST)
def gather_gaps(c, inc, slots, fresh, out, grid, nx, pad):
    """``out = c (+ inc[slots])`` — the iterate's ``u - w - δ_ref`` at buffer positions ``slots``; returns its sum.

    ``c`` is ``u_ref - w - δ_ref`` (working precision) per point, or with ``grid`` the grid's (read at the
    flat indices), ``inc`` the float32 increment buffer (ignored when ``fresh``).
    """
    s = 0.0
    for j in range(slots.size):
        d = c[_flat(slots[j], nx, pad)] if grid else c[j]
        if not fresh:
            d += inc[_at(slots[j])]
        out[j] = d
        s += d
    return s


@njit(nogil=True, cache=True)
def contact_gaps(c, inc, slots, fresh, out, load_control, delta, delta_ref, grid, nx, pad):
    """The gaps of the contact set, centred: :func:`gather_gaps` and :func:`center` in one call.

    ``c`` is ``u_ref - w - δ_ref`` at the set's points (compact: one value per point; with ``grid``
    the grid's array, read at the flat indices of ``slots``), ``slots``
    their positions in the float32 increment buffer ``inc`` (ignored when ``fresh``). Under
    ``load_control`` the penetration becomes ``δ = δ_ref + mean(out)`` (the mean over the set);
    the gaps are then shifted by ``δ - δ_ref`` (rounded to ``out``'s precision). Returns
    ``(δ, shift, max |g|, Σ g²)``. The scalar arithmetic is exact IEEE (only the loops may be
    reordered).
    """
    total = gather_gaps(c, inc, slots, fresh, out, grid, nx, pad)
    n = slots.size
    if load_control and n:
        delta = delta_ref + total / n
    rounded = np.empty(1, out.dtype)
    rounded[0] = delta - delta_ref
    shift = rounded[0]
    big, ss = center(out, shift)
    return delta, shift, big, ss


_BLOCK = 1024  # the overlap scan's block: overlaps are few, so most blocks are passed on a count alone
_SUB = 64      # and the sub-blocks a block with overlaps is counted in again (overlaps are scattered)


@njit(**_FAST)
def _block_hits(c, c_low, inc, fresh, level, level_low):
    """Number of overlapping free points in a block (slices: a count over them vectorises)."""
    k = 0
    if fresh:
        for i in range(c.size):
            k += (c_low[i] != np.inf) & (c[i] < level)
    else:
        for i in range(c.size):
            k += c_low[i] + inc[i] < level_low
    return k


@njit(nogil=True, cache=True)
def scan_overlaps(c, c_low, inc, nx, pad, fresh, shift, where, gaps, clear):
    """Free points that overlap: ``u - w - δ_ref < shift`` (a negative gap).

    Points with ``c_low = +inf`` (the contact and plastic sets) are skipped. After a refresh
    (``fresh``) the test is on the working-precision ``c``, otherwise on ``c_low + inc`` in
    the precision of ``c_low`` (``shift`` rounded to it). Returns ``(count, lowest gap, where,
    gaps)``: the first ``count`` entries of ``where`` hold the indices, of ``gaps`` their gaps
    ``c + inc - shift`` (working precision). The arrays passed in may be shorter than the grid
    (overlaps are few); when they fill up, the scan goes on in arrays of twice the length
    (returned in their place). Row segments of :data:`_BLOCK` points without overlaps are
    passed on a vectorised count.

    ``clear`` (a buffer of ``inc``'s layout, or empty) is set to zero on the active grid as the scan
    passes: the search direction's buffer, which shares its memory with ``inc`` (each block is
    cleared after it is read), so that the direction need not be zero-filled in a pass of its own.
    The scan therefore runs once: a second one would find ``inc`` cleared.
    """
    rounded = np.empty(1, c_low.dtype)
    rounded[0] = shift
    level_low = rounded[0]
    k = 0
    low = np.inf
    for r in range(c.size // nx):
        a0 = r * nx
        b0 = r * (nx + pad)
        for lo in range(0, nx, _BLOCK):
            hi = min(lo + _BLOCK, nx)
            cs = c[a0 + lo:a0 + hi]
            cls = c_low[a0 + lo:a0 + hi]
            incs = inc[:0] if fresh else inc[b0 + lo:b0 + hi]
            if not _block_hits(cs, cls, incs, fresh, shift, level_low):
                if clear.size:
                    clear[b0 + lo:b0 + hi] = 0
                continue
            for s0 in range(0, hi - lo, _SUB):   # the overlaps are scattered: count sub-blocks, then look
                s1 = min(s0 + _SUB, hi - lo)
                if not _block_hits(cs[s0:s1], cls[s0:s1], incs[s0:s1] if not fresh else incs, fresh, shift,
                                   level_low):
                    continue
                for j in range(s0, s1):
                    cl = cls[j]
                    if cl == np.inf:
                        continue
                    if fresh:
                        if not cs[j] < shift:
                            continue
                        g = cs[j] - shift
                    else:
                        v = incs[j]
                        if not cl + v < level_low:
                            continue
                        g = (cs[j] + v) - shift
                    if k == where.size:
                        where, gaps = _grown(where, gaps, c.size)
                    where[k] = a0 + lo + j
                    gaps[k] = g
                    low = min(low, g)
                    k += 1
            if clear.size:
                clear[b0 + lo:b0 + hi] = 0
    return k, low, where, gaps


@njit(nogil=True, cache=True)
def _grown(where, gaps, limit):
    """``where`` and ``gaps`` copied into arrays of twice their length (at least 16, at most ``limit``)."""
    n = min(max(16, 2 * where.size), limit)
    w = np.empty(n, where.dtype)
    g = np.empty(n, gaps.dtype)
    w[:where.size] = where
    g[:gaps.size] = gaps
    return w, g


@njit(**_FAST)
def set_direction(t, g, beta, zero_sum, slots, buf):
    """Conjugate direction ``t ← β t + g`` (zero-sum when ``zero_sum``), written into ``buf`` at ``slots``.

    A direction that is not downhill (``Σ g t ≤ 0``) restarts from ``g`` (``β = 0``). Returns the
    slope ``Σ g t`` (≤ 0 when even ``t = g`` is not downhill).
    """
    n = t.size
    slope = 0.0
    for attempt in range(2):
        b = beta if attempt == 0 else beta * 0
        s = 0.0
        for j in range(n):
            v = t[j] * b + g[j]
            t[j] = v
            s += v
        m = s / n if zero_sum and n else 0.0
        slope = 0.0
        for j in range(n):
            t[j] -= m
            slope += float(g[j]) * float(t[j])
        if slope > 0:
            break
    for j in range(n):
        buf[_at(slots[j])] = t[j]
    return slope


@njit(inline="always")
def _folded_row(r, rows, stored):
    """Row of a folded operator (rows ``0 … M//2`` stored) that stands for spectrum row ``r`` of ``rows``."""
    return r if r < stored else rows - r


@njit(**_FAST)
def energy(g, spectrum, rows, halve_last):
    """``Σ_k m_k g_k |x̂_k|²`` in float64 over an rfft spectrum of ``rows`` rows.

    ``g`` is a folded operator (:mod:`xtopo._kernels.greens`: ``rows//2 + 1`` rows of the spectrum's
    row length), ``spectrum`` the interleaved real and imaginary parts; ``m_k`` counts the modes of
    the full spectrum an rfft mode stands for (1 in the first column, and in the last when
    ``halve_last``: an even transform length; 2 elsewhere). The loops run over row slices, which
    they vectorise on (indexing the whole arrays, they did not: 2.5× slower).
    """
    nc = spectrum.size // (2 * rows)
    stored = g.size // nc
    e = 0.0
    for r in range(rows):
        gr = _folded_row(r, rows, stored) * nc
        sp = spectrum[2 * r * nc:2 * (r + 1) * nc]
        gg = g[gr:gr + nc]
        s = 0.0
        for k in range(nc):
            a = sp[2 * k]
            b = sp[2 * k + 1]
            s += float(gg[k]) * (float(a) * float(a) + float(b) * float(b))
        s *= 2
        a = sp[0]
        b = sp[1]
        s -= float(gg[0]) * (float(a) * float(a) + float(b) * float(b))
        if halve_last and nc > 1:
            a = sp[2 * nc - 2]
            b = sp[2 * nc - 1]
            s -= float(gg[nc - 1]) * (float(a) * float(a) + float(b) * float(b))
        e += s
    return e


@njit(**_FAST)
def scale_spectrum(spectrum, g, rows):
    """``x̂_k *= g_k`` in place for a folded real operator ``g`` (see :func:`energy`; row slices, vectorised)."""
    nc = spectrum.size // (2 * rows)
    stored = g.size // nc
    for r in range(rows):
        gr = _folded_row(r, rows, stored) * nc
        sp = spectrum[2 * r * nc:2 * (r + 1) * nc]
        gg = g[gr:gr + nc]
        for k in range(nc):
            w = gg[k]
            sp[2 * k] *= w
            sp[2 * k + 1] *= w


@njit(nogil=True, cache=True)
def reference_gaps(u, w, delta, c, c_low):
    """``c = u - w - δ`` and ``c_low = c`` (in its precision) in one pass: ``u`` 2-D (rows of a transform
    buffer, a strided view), ``w``, ``c`` and ``c_low`` flat on the active grid."""
    rows, n = u.shape
    for r in range(rows):
        ur = u[r]
        base = r * n
        for j in range(n):
            v = (ur[j] - w[base + j]) - delta
            c[base + j] = v
            c_low[base + j] = v


@njit(nogil=True, cache=True)
def rebase(idx, p, old, p_ref, c, c_low, c_set, r_set, compact):
    """Make the pressures ``p`` at flat indices ``idx`` the reference, after :func:`reference_gaps`.

    ``p_ref`` is cleared on the previous reference's support ``old`` and set to ``p`` on ``idx``;
    the points leave the overlap test (``c_low = +inf``) and, with ``compact``, the set's per-point
    reference gaps ``c_set`` and pressures ``r_set`` are read (``c[idx]``, ``p``).
    """
    for j in range(old.size):
        p_ref[_at(old[j])] = 0
    for j in range(idx.size):
        i = _at(idx[j])
        v = p[j]
        p_ref[i] = v
        c_low[i] = np.inf
        if compact:
            c_set[j] = c[i]
            r_set[j] = v


@njit(nogil=True, cache=True)
def split_sets(p, hardness):
    """Flat int32 indices of the CG set ``0 < p < H`` and of the plastic set ``p ≥ H`` (``H = inf``: none)."""
    n_cg = 0
    n_pl = 0
    for i in range(p.size):
        v = p[i]
        n_pl += v >= hardness
        n_cg += (v > 0) & (v < hardness)
    cg = np.empty(n_cg, np.int32)
    pl = np.empty(n_pl, np.int32)
    a = 0
    b = 0
    for i in range(p.size):
        v = p[i]
        if v >= hardness:
            pl[b] = i
            b += 1
        elif v > 0:
            cg[a] = i
            a += 1
    return cg, pl


@njit(inline="always")
def _flat(k, nx, pad):
    """Flat active-grid index of buffer position ``k`` (the inverse of :func:`_slot`).

    The row ``k // (nx + pad)`` by a float multiplication (4x faster than the integer division, which
    kept the set's passes slow while the set is large): ``(k + ½)/row`` lies at least ``½/row`` from
    an integer and is off by at most ``2⁻⁵² (k + ½)/row < 2⁻²¹`` for ``k < 2³¹``, so it truncates to
    the row exactly for rows shorter than 2¹⁹ (longer ones divide).
    """
    if not pad:
        return k
    row = nx + pad
    if row >= 524288:
        return k - (k // row) * pad
    return k - np.int64((k + 0.5) * (1.0 / row)) * pad


@njit(nogil=True, cache=True)
def flat_indices(slots, nx, pad):
    """Flat active-grid indices (int32) of buffer positions ``slots``."""
    out = np.empty(slots.size, np.int32)
    for j in range(slots.size):
        out[j] = _flat(slots[j], nx, pad)
    return out


@njit(**dict(_JIT, fastmath={"reassoc", "nsz", "arcp"}))   # no fused p - τ t: rounded as written
def _kept(p, t, tau, n, hardness, capped_flag):
    """``p ← p - τ t`` for the first ``n`` points; how many stay in the set (``0 < p``, and ``p < H`` with
    ``capped_flag``) and their sum (float64)."""
    m = 0
    total = 0.0
    for j in range(n):
        v = p[j] - tau * t[j]
        p[j] = v
        keep = (v > 0) & ((not capped_flag) | (v < hardness))
        m += keep
        total += v if keep else 0.0
    return m, total


@njit(nogil=True, cache=True)
def step_project(slots, p, t, c, r, n, tau, hardness, capped_flag, c_low, buf, nx, pad, grid, target, joining):
    """``p ← p - τ t`` and the projection onto ``0 < p < H`` of the first ``n`` points, compacting the set in place,
    and the increment's input written for all of them.

    The set is given by the points' positions ``slots`` in the increment buffer ``buf``. The
    points that stay are moved to the front of ``slots``, ``p``, ``t``, ``c`` and ``r`` (order
    kept; ``c`` and ``r`` are the points' reference gaps and pressures); under load control (``target > 0``:
    the load over the pixel area) their pressures are scaled by ``target / (Σ p + joining)``, ``joining`` the
    sum of the pressures of the points that join next (:func:`join`, with the same scale), and each gets its
    increment ``p - r`` written into ``buf``. A point that leaves
    gets its new pressure (0, or ``H`` at the cap) minus its reference pressure written into
    ``buf``, and a freed one (``p ≤ 0``) its reference gap ``c`` back in ``c_low`` (the overlap
    test, on the active grid). With ``grid``, ``c`` and ``r`` are the grid's arrays (read at the
    points' flat indices, not moved). Returns ``(count, gone, capped, scale)``: how many stay, the flat
    (int32) indices of those that left, flags of the latter that left at the cap (``p ≥ H``;
    empty unless ``capped_flag``) and the scale (1 without load control).
    """
    m, total = _kept(p, t, tau, n, hardness, capped_flag)
    scale = np.ones(1, p.dtype)   # in the pressures' precision
    if target > 0 and total + joining > 0:
        scale[0] = target / (total + joining)
    sc = scale[0]
    gone = np.empty(n - m, np.int32)
    capped = np.zeros(n - m if capped_flag else 0, np.bool_)
    a = 0
    b = 0
    for j in range(n):   # indices known to be ≥ 0 (_at): 25 % faster
        v = p[_at(j)]
        k = slots[_at(j)]
        if v > 0 and not (capped_flag and v >= hardness):
            if sc != 1:
                v = v * sc
            ua = _at(a)
            slots[ua] = k
            p[ua] = v
            t[ua] = t[_at(j)]
            ref = r[_at(_flat(k, nx, pad))] if grid else r[_at(j)]
            if not grid:
                c[ua] = c[_at(j)]
                r[ua] = ref
            buf[_at(k)] = v - ref
            a += 1
        else:
            i = _flat(k, nx, pad)
            jj = i if grid else j
            gone[b] = i
            full = capped_flag and v >= hardness
            if capped_flag:
                capped[b] = full
            if full:
                buf[_at(k)] = hardness - r[jj]
            else:
                buf[_at(k)] = 0 - r[jj]
                c_low[_at(i)] = c[jj]
            b += 1
    return m, gone, capped, sc


@njit(nogil=True, cache=True)
def join(slots, p, t, c, r, n, where, values, scale, c_full, p_ref, c_low, buf, nx, pad, grid):
    """Append the points ``where`` (flat indices) with pressures ``values · scale`` after the first ``n`` of the set.

    Their increments over the reference go into ``buf`` (:func:`step_project`, whose scale this is),
    their buffer positions to ``slots``, their direction starts at 0, their reference gap and
    pressure are read from the grids ``c_full`` and ``p_ref`` (unless ``grid``: the set reads them
    there), and they leave the overlap test (``c_low = +inf``). The arrays must have room for them.
    Returns the new count.
    """
    for j in range(where.size):
        i = where[j]
        k = _slot(i, nx, pad)
        slots[n + j] = k
        p[n + j] = values[j] if scale == 1 else values[j] * scale
        buf[k] = p[n + j] - p_ref[_at(i)]
        t[n + j] = 0
        if not grid:
            c[n + j] = c_full[_at(i)]
            r[n + j] = p_ref[_at(i)]
        c_low[_at(i)] = np.inf
    return n + where.size
