"""The compiled passes of the contact solver against their numpy definitions (xtopo._kernels.compiled)."""

import numpy as np
import pytest

from xtopo._kernels import compiled

# (active shape, buffer row length): a line, a periodic grid, a padded free-boundary grid whose rows
# are not a multiple of the scan's block, and one row longer than a block
LAYOUTS = [((1000,), 1000), ((37, 300), 300), ((37, 300), 600), ((5, 700), 1400)]


def _layout(shape, row):
    nx = shape[-1]
    pad = 0 if len(shape) == 1 else row - nx
    rows = int(np.prod(shape[:-1]))
    return nx, pad, rows


def _increment(shape, row, seed, size):
    """Random float32 increments on the active grid and the transform buffer holding them in its rows
    (noise in the padding); returns ``rng, (nx, pad, rows), n, active, buffer``."""
    rng = np.random.default_rng(seed)
    nx, pad, rows = _layout(shape, row)
    n = rows * nx
    active = (rng.standard_normal(n) * size).astype(np.float32)
    buf = rng.standard_normal(rows * (nx + pad)).astype(np.float32)
    buf.reshape(rows, nx + pad)[:, :nx] = active.reshape(rows, nx)
    return rng, (nx, pad, rows), n, active, buf


@pytest.mark.parametrize("shape,row", LAYOUTS)
@pytest.mark.parametrize("fresh", [False, True])
def test_scan_overlaps_matches_numpy(shape, row, fresh):
    rng, (nx, pad, rows), n, inc_active, inc = _increment(shape, row, 3, 1e-3)
    c = rng.random(n) + 1e-3
    c[rng.choice(n, 25, replace=False)] = -rng.random(25) * 1e-2   # a few overlaps, scattered
    c[: nx // 3] = -1.0                                            # and a run of them
    c_low = c.astype(np.float32)
    contact = rng.choice(n, n // 10, replace=False)
    c_low[contact] = np.inf
    shift = 1.5e-4
    where, gaps = np.empty(n, np.intp), np.empty(n)
    clear = np.full(inc.size, 7.0, np.float32)   # the direction's buffer: cleared on the active grid

    k, low, where, gaps = compiled.scan_overlaps(c, c_low, inc, nx, pad, fresh, shift, where, gaps, clear)

    free = c_low != np.inf
    if fresh:
        expect = np.flatnonzero(free & (c < shift))
        expect_gaps = c[expect] - shift
    else:
        expect = np.flatnonzero(free & (c_low + inc_active < np.float32(shift)))
        expect_gaps = c[expect] + inc_active[expect] - shift
    assert k == expect.size > 20
    np.testing.assert_array_equal(where[:k], expect)
    np.testing.assert_allclose(gaps[:k], expect_gaps, rtol=1e-12, atol=0)
    assert low == pytest.approx(expect_gaps.min(), rel=1e-12)
    clear = clear.reshape(rows, nx + pad)
    assert not clear[:, :nx].any() and (clear[:, nx:] == 7).all()   # the padding is left alone
    # a shorter output pair is grown as it fills (one scan: the cleared buffer may be the increment's own)
    short, short_gaps = np.empty(7, np.int32), np.empty(7)
    inc_again = inc.copy()
    k2, low2, grown, grown_gaps = compiled.scan_overlaps(c, c_low, inc_again, nx, pad, fresh, shift, short, short_gaps,
                                                         inc_again)
    assert (k2, low2) == (k, low) and grown.size >= k
    np.testing.assert_array_equal(grown[:k], expect)
    np.testing.assert_allclose(grown_gaps[:k], expect_gaps, rtol=1e-12, atol=0)


@pytest.mark.parametrize("shape,row", LAYOUTS)
@pytest.mark.parametrize("fresh", [False, True])
def test_gather_gaps_matches_numpy(shape, row, fresh):
    rng, (nx, pad, rows), n, inc_active, inc = _increment(shape, row, 4, 1.0)
    c = rng.standard_normal(n)
    idx = rng.permutation(n)[: n // 4]
    out = np.empty(idx.size)
    total = compiled.gather_gaps(c, inc, compiled.slots(idx, nx, pad), fresh, out, True, nx, pad)   # c on the grid
    compact = np.empty(idx.size)
    assert compiled.gather_gaps(c[idx], inc, compiled.slots(idx, nx, pad), fresh, compact, False, nx, pad) == \
        pytest.approx(total, rel=1e-12)
    np.testing.assert_array_equal(compact, out)
    expect = c[idx] if fresh else c[idx] + inc_active[idx]
    np.testing.assert_allclose(out, expect, rtol=1e-12)
    assert total == pytest.approx(expect.sum(), rel=1e-9)


@pytest.mark.parametrize("shape,row", LAYOUTS)
@pytest.mark.parametrize("fresh", [False, True])
@pytest.mark.parametrize("load_control", [False, True])
def test_contact_gaps_gather_and_center(shape, row, fresh, load_control):
    """Compact reference gaps plus the increment, shifted by δ - δ_ref (δ the mean under load control)."""
    rng, (nx, pad, rows), n, inc_active, inc = _increment(shape, row, 4, 1.0)
    idx = rng.permutation(n)[: n // 4]
    c = rng.standard_normal(idx.size)
    out = np.empty(idx.size)
    slots = compiled.slots(idx, nx, pad).astype(np.int32)
    delta, shift, big, ss = compiled.contact_gaps(c, inc, slots, fresh, out, load_control, 0.7, 0.5, False, nx, pad)
    grid_c = np.full(n, np.nan)
    grid_c[idx] = c                                   # the same gaps read from a grid-sized array
    out_grid = np.empty(idx.size)
    assert compiled.contact_gaps(grid_c, inc, slots, fresh, out_grid, load_control, 0.7, 0.5, True, nx,
                                 pad) == (delta, shift, big, ss)
    np.testing.assert_array_equal(out_grid, out)
    d = c if fresh else c + inc_active[idx]
    expect_delta = 0.5 + d.sum() / d.size if load_control else 0.7
    assert delta == pytest.approx(expect_delta, rel=1e-12)
    assert shift == delta - 0.5
    np.testing.assert_allclose(out, d - shift, rtol=1e-12, atol=1e-15)
    assert big == pytest.approx(np.abs(d - shift).max(), rel=1e-12)
    assert ss == pytest.approx(np.sum((d - shift) ** 2), rel=1e-9)


@pytest.mark.parametrize("shape,row", LAYOUTS)
def test_writes_land_in_the_active_part(shape, row):
    rng = np.random.default_rng(5)
    nx, pad, rows = _layout(shape, row)
    n = rows * nx
    buf = np.zeros(rows * (nx + pad), np.float32)
    p_ref = rng.random(n)
    idx = rng.permutation(n)[: n // 3]
    p = rng.random(idx.size)
    p0 = p.copy()
    slots = compiled.slots(idx, nx, pad)
    zero = np.zeros(idx.size)   # no step: every point stays, scaled to twice its load
    step = (slots, p, zero, zero, p_ref[idx], idx.size, 0.0, np.inf, False, np.empty(n), buf, nx, pad, False,
            2 * p0.sum(), 0.0)
    assert compiled.step_project(*step)[0] == idx.size                               # r per point
    buf_grid = np.zeros_like(buf)
    # the reference pressures read on the grid at the flat indices
    compiled.step_project(slots.copy(), p0.copy(), zero, zero, p_ref, *step[5:10], buf_grid, *step[11:13], True,
                          *step[14:])
    np.testing.assert_array_equal(buf_grid, buf)
    np.testing.assert_allclose(p, 2 * p0)                       # scaled in place
    rest = np.setdiff1d(np.arange(n), idx)
    others, scattered, filled = rest[:50], rest[50:60], rest[60:70]
    compiled.scatter(others, 0.5 - p_ref[others], nx, pad, buf)
    compiled.scatter(scattered, p_ref[scattered], nx, pad, buf)
    compiled.scatter(filled, np.full(1, -3.0, np.float32), nx, pad, buf)   # one value at every point
    active = buf.reshape(rows, nx + pad)[:, :nx].reshape(-1)
    np.testing.assert_allclose(active[idx], (2 * p0 - p_ref[idx]).astype(np.float32), rtol=1e-6)
    np.testing.assert_allclose(active[others], (0.5 - p_ref[others]).astype(np.float32), rtol=1e-6)
    np.testing.assert_allclose(active[scattered], p_ref[scattered].astype(np.float32))
    np.testing.assert_array_equal(active[filled], -3.0)
    assert np.count_nonzero(active) == idx.size + 70
    assert not buf.reshape(rows, nx + pad)[:, nx:].any()        # the padding stays zero


@pytest.mark.parametrize("hardness", [None, 0.8, 2.0])
def test_split_sets(hardness):
    p = np.random.default_rng(5).random(300) * 1.6 - 0.3
    H = np.inf if hardness is None else hardness
    cg, pl = compiled.split_sets(p, H)
    assert cg.dtype == pl.dtype == np.int32
    np.testing.assert_array_equal(cg, np.flatnonzero((p > 0) & (p < H)))
    np.testing.assert_array_equal(pl, np.flatnonzero(p >= H))


@pytest.mark.parametrize("target", [0.0, 400.0])
@pytest.mark.parametrize("grid", [False, True])
@pytest.mark.parametrize("hardness", [None, 0.8])
def test_step_project_compacts_in_order(hardness, grid, target):
    rng = np.random.default_rng(6)
    nx, pad = 100, 28
    idx = rng.permutation(5000)[:1000].astype(np.int32)
    p = rng.random(1000)
    t = rng.standard_normal(1000)
    c = rng.standard_normal(1000)      # reference gaps and pressures, one per point
    r = rng.random(1000)
    tau = 0.3
    new = p - tau * t
    keep = (new > 0) & (new < hardness if hardness is not None else True)
    H = np.inf if hardness is None else hardness
    i0, t0, c0, r0 = idx.copy(), t.copy(), c.copy(), r.copy()
    c_low = np.full(5000, np.inf)
    buf = np.full(5000 // nx * (nx + pad), 9.0, np.float32)
    slots = compiled.slots(idx, nx, pad)
    s0 = slots.copy()
    if grid:   # the reference gaps and pressures on the grid, read at the flat indices
        c_grid, r_grid = np.full(5000, np.nan), np.full(5000, np.nan)
        c_grid[idx], r_grid[idx] = c, r
        c, r = c_grid, r_grid
    m, gone, capped, scale = compiled.step_project(slots, p, t, c, r, 1000, tau, H, hardness is not None, c_low,
                                                   buf, nx, pad, grid, target, 5.0)   # 5: the joins' load
    assert m == keep.sum() and 0 < m < 1000
    assert scale == pytest.approx(target / (new[keep].sum() + 5.0) if target else 1.0, rel=1e-14)
    np.testing.assert_array_equal(slots[:m], s0[keep])
    np.testing.assert_allclose(p[:m], new[keep] * scale, rtol=1e-14)
    np.testing.assert_allclose(buf[slots[:m]], p[:m] - r0[keep], rtol=1e-6)   # the increments of those that stay
    np.testing.assert_array_equal(t[:m], t0[keep])
    if grid:   # left where they are
        np.testing.assert_array_equal(c[i0], c0)
        np.testing.assert_array_equal(r[i0], r0)
    else:      # moved with their points
        np.testing.assert_array_equal(c[:m], c0[keep])
        np.testing.assert_array_equal(r[:m], r0[keep])
    np.testing.assert_array_equal(gone, i0[~keep])
    expect_capped = new[~keep] >= hardness if hardness is not None else np.zeros(0, bool)
    np.testing.assert_array_equal(capped, expect_capped)
    assert capped.any() == (hardness is not None)
    # the points that left: their new pressure (0 or H) over the reference in the increment's buffer, and
    # the freed ones back in the overlap test with their reference gap
    at_cap = np.zeros(gone.size, bool) if hardness is None else expect_capped
    slot = gone + (gone // nx) * pad
    np.testing.assert_allclose(buf[slot], np.where(at_cap, H, 0.0) - r0[~keep], rtol=1e-6)
    assert np.count_nonzero(buf != 9) == 1000
    np.testing.assert_array_equal(c_low[gone[~at_cap]], c0[~keep][~at_cap])
    assert np.isinf(c_low[gone[at_cap]]).all() and np.count_nonzero(np.isfinite(c_low)) == (~at_cap).sum()


def test_join_appends_with_reference_values():
    rng = np.random.default_rng(9)
    n, room, nx, pad = 30, 50, 20, 22
    slots, p, t, c, r = (np.zeros(room, np.int32), *(rng.random(room) for _ in range(4)))
    before = [a[:n].copy() for a in (slots, p, t, c, r)]
    c_full, p_ref, c_low = rng.random(400), rng.random(400), rng.random(400)
    where = np.array([5, 77, 301], np.int32)
    buf = np.zeros(20 * 42)
    m = compiled.join(slots, p, t, c, r, n, where, np.array([1.0, 2.0, 3.0]), 2.0, c_full, p_ref, c_low, buf, nx, pad,
                      False)
    assert m == n + 3
    for a, b in zip((slots, p, t, c, r), before):
        np.testing.assert_array_equal(a[:n], b)                  # the set so far is left alone
    np.testing.assert_array_equal(slots[n:m], where + (where // nx) * pad)
    np.testing.assert_array_equal(compiled.flat_indices(slots[n:m], nx, pad), where)
    np.testing.assert_array_equal(p[n:m], [2.0, 4.0, 6.0])                # scaled
    np.testing.assert_array_equal(buf[slots[n:m]], p[n:m] - p_ref[where])  # their increments
    assert np.count_nonzero(buf) == 3
    assert not t[n:m].any()                                      # their direction starts at 0
    np.testing.assert_array_equal(c[n:m], c_full[where])
    np.testing.assert_array_equal(r[n:m], p_ref[where])
    assert np.isinf(c_low[where]).all() and np.isfinite(np.delete(c_low, where)).all()


@pytest.mark.parametrize("zero_sum", [False, True])
def test_set_direction_conjugates_and_restarts(zero_sum):
    rng = np.random.default_rng(7)
    n, nx, pad = 400, 40, 40
    idx = rng.permutation(n)[:120]
    slots = compiled.slots(idx, nx, pad)
    g = rng.standard_normal(120)
    t = rng.standard_normal(120)
    buf = np.ones(n // nx * (nx + pad), np.float32)
    expect = 0.5 * t + g
    if zero_sum:
        expect -= expect.mean()
    slope = compiled.set_direction(t, g, 0.5, zero_sum, slots, buf)
    np.testing.assert_allclose(t, expect, rtol=1e-12)
    assert slope == pytest.approx(g @ expect)
    np.testing.assert_allclose(buf[slots], expect.astype(np.float32))
    assert np.count_nonzero(buf != 1) == 120                   # written on the set only
    # a direction that is not downhill restarts from g
    t = -100 * g
    slope = compiled.set_direction(t, g, 1.0, False, slots, buf)
    np.testing.assert_allclose(t, g)
    assert slope == pytest.approx(g @ g)


@pytest.mark.parametrize("rows", [16, 15, 1])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_spectrum_energy_and_scaling(dtype, rows):
    """A folded operator (rows 0 … M//2 stored) stands for the full one; the energy counts each rfft
    mode as often as it occurs in the full spectrum (once in the first and, for an even length, the
    last column)."""
    rng = np.random.default_rng(8)
    ctype = np.complex64 if dtype == np.float32 else np.complex128
    spec = (rng.standard_normal((rows, 9)) + 1j * rng.standard_normal((rows, 9))).astype(ctype)
    g = rng.random((rows // 2 + 1, 9)).astype(dtype)
    full = g[np.minimum(np.arange(rows), rows - np.arange(rows))]   # row r is row min(r, rows - r)
    m = np.full(9, 2.0)
    m[0] = m[-1] = 1.0        # a transform length of 16 (9 = 16 // 2 + 1)
    e = compiled.energy(g.reshape(-1), spec.view(dtype).reshape(-1), rows, True)
    assert e == pytest.approx(float(np.sum(m * full * np.abs(spec) ** 2)), rel=1e-6)
    m[-1] = 2.0               # a length of 17
    e = compiled.energy(g.reshape(-1), spec.view(dtype).reshape(-1), rows, False)
    assert e == pytest.approx(float(np.sum(m * full * np.abs(spec) ** 2)), rel=1e-6)
    expect = spec * full
    compiled.scale_spectrum(spec.view(dtype).reshape(-1), g.reshape(-1), rows)
    np.testing.assert_allclose(spec, expect, rtol=1e-6)


def test_center_reports_nan():
    d = np.array([1e-9, np.nan, -2e-9])
    big, ss = compiled.center(d, 0.0)
    assert np.isnan(big) and np.isnan(ss)
    d = np.array([1.0, -3.0, 2.0])
    assert compiled.center(d, 1.0) == (4.0, 0.0 + 16.0 + 1.0)
    np.testing.assert_array_equal(d, [0.0, -4.0, 1.0])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_reference_gaps_from_a_strided_buffer(dtype):
    rng = np.random.default_rng(10)
    buf = rng.standard_normal((6, 12)).astype(dtype)
    u = buf[:, :10]                                   # the active part of the transform's rows
    w = rng.standard_normal(60).astype(dtype)
    c, c_low = np.empty(60, dtype), np.empty(60, np.float32)
    compiled.reference_gaps(u, w, dtype(0.25), c, c_low)
    expect = (u.reshape(-1) - w) - dtype(0.25)
    np.testing.assert_array_equal(c, expect)           # the same rounding as numpy's two steps
    np.testing.assert_array_equal(c_low, expect.astype(np.float32))


def test_rebase_moves_the_reference():
    rng = np.random.default_rng(11)
    n = 200
    p_ref, c, c_low = np.zeros(n), rng.standard_normal(n), rng.standard_normal(n).astype(np.float32)
    old = np.array([3, 7, 50], np.int32)
    p_ref[old] = 9.0
    idx = np.array([7, 20, 150], np.int32)
    p = np.array([1.0, 2.0, 3.0])
    c_set, r_set = np.empty(3), np.empty(3)
    low0 = c_low.copy()
    compiled.rebase(idx, p, old, p_ref, c, c_low, c_set, r_set, True)
    expect = np.zeros(n)
    expect[idx] = p
    np.testing.assert_array_equal(p_ref, expect)          # cleared on the old support, set on the new
    assert np.isinf(c_low[idx]).all()
    np.testing.assert_array_equal(np.delete(c_low, idx), np.delete(low0, idx))
    np.testing.assert_array_equal(c_set, c[idx])
    np.testing.assert_array_equal(r_set, p)


@pytest.mark.parametrize("row,pad", [(514, 2), (1026, 514), (8194, 4098), (300001, 1), (600000, 300000)])
def test_flat_indices_invert_slots_exactly(row, pad):
    """The float reciprocal that finds a buffer position's row is exact at row starts and ends, up to 2³¹."""
    nx = row - pad
    rows = np.unique(np.r_[0, 1, 2, np.random.default_rng(12).integers(0, (2**31 - 1) // row, 200),
                           (2**31 - 1) // row - 1])
    cols = np.r_[0, 1, nx // 2, nx - 2, nx - 1]
    slots = (rows[:, None] * row + cols[None, :]).reshape(-1)
    slots = slots[slots < 2**31]
    flat = (slots // row) * nx + slots % row
    np.testing.assert_array_equal(compiled.flat_indices(slots, nx, pad), flat)
    np.testing.assert_array_equal(compiled.slots(flat, nx, pad), slots)
