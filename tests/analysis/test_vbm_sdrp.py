import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.datasets import fractal_surface
from xtopo.errors import ChunkError

from ..conftest import batch


def _tilt_corrected_sq(h, dy=1.0, dx=1.0):
    ny, nx = h.shape
    yy, xx = np.meshgrid(np.arange(ny) * dy, np.arange(nx) * dx, indexing="ij")
    a = np.c_[np.ones(h.size), xx.ravel(), yy.ravel()]
    coef, *_ = np.linalg.lstsq(a, h.ravel(), rcond=None)
    return np.sqrt(np.mean((h.ravel() - a @ coef) ** 2))


def test_vbm_zeta1_is_tilt_corrected_sq():
    ds = fractal_surface((48, 80), (0.6, 1.0), hurst=0.7, periodic=False, seed=2)
    v = ds.topo.vbm()
    assert v.bandwidth.attrs["units"] == "m" and v.attrs["units"] == "m"
    top = v.sel(bandwidth=v.bandwidth.max())
    assert int(top.magnification) == 1
    np.testing.assert_allclose(float(top), _tilt_corrected_sq(ds.height.values), rtol=1e-12)


def test_vbm_blocks_match_direct_and_line():
    ds = fractal_surface((37, 53), (1.0, 1.0), hurst=0.5, periodic=False, seed=1)
    v = ds.topo.vbm()
    h = ds.height.values
    for zeta in v.magnification.values:
        by = np.append((np.arange(zeta) * 37) // zeta, 37)
        bx = np.append((np.arange(zeta) * 53) // zeta, 53)
        vals = [_tilt_corrected_sq(h[by[i]:by[i + 1], bx[j]:bx[j + 1]]) for i in range(zeta) for j in range(zeta)]
        got = v.values[v.magnification.values == zeta]
        np.testing.assert_allclose(got, np.mean(vals), rtol=1e-10)
    line = ds.isel(y=0)
    assert line.topo.vbm().sizes["bandwidth"] >= 3


def test_vbm_on_non_square_pixels_fits_planes_in_physical_coordinates():
    """The kernel fits each block's plane in pixel units and is given no spacing: right for any pixel aspect,
    since a plane in x/Δx, y/Δy is a plane in x, y (the same residuals). Checked against planes fitted in
    physical coordinates on pixels 20 times longer in x than in y."""
    ds = fractal_surface((40, 24), (0.2, 2.4), hurst=0.6, periodic=False, seed=5)
    dy, dx = (float(ds[d][1] - ds[d][0]) for d in ("y", "x"))
    assert dx / dy == pytest.approx(20)
    v, h = ds.topo.vbm(reliable=False), ds.height.values
    for zeta in v.magnification.values:
        by, bx = (np.append((np.arange(zeta) * n) // zeta, n) for n in h.shape)
        vals = [_tilt_corrected_sq(h[by[i]:by[i + 1], bx[j]:bx[j + 1]], dy, dx)
                for i in range(zeta) for j in range(zeta)]
        np.testing.assert_allclose(v.values[v.magnification.values == zeta], np.mean(vals), rtol=1e-10)


@pytest.mark.parametrize("shape", [(24, 256), (1, 512)])
def test_profile_vbm_with_rms_average_is_surfacetopographys(shape):
    """kind="1d", average="rms" is SurfaceTopography's variable_bandwidth_from_profile (the definition its container
    average, hence contact.engineering's, uses): the benchmark's VBM deviation (30 %) was this difference of
    definitions, the AFM map's profile VBM lying 5-27 % below its areal one."""
    ST = pytest.importorskip("SurfaceTopography")
    ds = fractal_surface(shape if shape[0] > 1 else (2, shape[1]), (1e-6 * shape[0] / shape[1], 1e-6), hurst=0.8,
                         periodic=False, seed=4)
    if shape[0] == 1:
        ds = ds.isel(y=0)
    h = ds.height.values
    dx = float(ds.x[1] - ds.x[0])
    topo = (ST.UniformLineScan(h, h.size * dx, periodic=False) if h.ndim == 1 else
            ST.Topography(h.T, (h.shape[1] * dx, h.shape[0] * float(ds.y[1] - ds.y[0])), periodic=False))
    b, v = topo.variable_bandwidth_from_profile(reliable=False)
    mine = ds.topo.vbm(kind="1d", average="rms", reliable=False)
    np.testing.assert_allclose(mine.bandwidth.values, np.sort(b), rtol=1e-12)
    np.testing.assert_allclose(mine.values, v[np.argsort(b)], rtol=1e-10)
    mean = ds.topo.vbm(kind="1d", reliable=False)  # the paper's arithmetic mean of the segments' RMS: below
    assert (mean.values <= mine.values * (1 + 1e-12)).all()
    if h.ndim == 1:  # one segment: one RMS height
        assert mean.values[-1] == pytest.approx(mine.values[-1], rel=1e-12)
    if h.ndim == 2:
        along_y = ds.topo.vbm(kind="1d", dim="y", reliable=False)
        swapped = xr.Dataset({"height": (("y", "x"), h.T)}, coords={"y": ds.x.values, "x": ds.y.values},
                             attrs=ds.attrs).assign(height=lambda d: d.height.assign_attrs(ds.height.attrs))
        np.testing.assert_allclose(along_y.values, swapped.topo.vbm(kind="1d", reliable=False).values, rtol=1e-12)
        lazy = ds.chunk({"y": 8}).topo.vbm(kind="1d", average="rms", reliable=False)
        assert lazy.chunks is not None
        np.testing.assert_allclose(lazy.values, mine.values, rtol=1e-12)
    with pytest.raises(xtopo.XtopoError, match="average"):
        ds.topo.vbm(average="median")


def test_sdrp_smallest_distance_is_rdq():
    for periodic in (True, False):
        ds = fractal_surface((32, 64), (0.5, 1.0), hurst=0.6, periodic=periodic, seed=4)
        s = ds.topo.scalars()
        for dim in ("x", "y"):
            r1 = ds.topo.sdrp(1, dim=dim)
            np.testing.assert_allclose(float(r1.isel(distance=0)), float(s.Rdq.sel(direction=dim)), rtol=1e-12)
            r2 = ds.topo.sdrp(2, dim=dim)
            np.testing.assert_allclose(float(r2.isel(distance=0)), float(s.Rddq.sel(direction=dim)), rtol=1e-12)
        assert r1.attrs["units"] == "1" and r2.attrs["units"] == "m-1"


def test_sdrp_fractional_interpolates_linearly():
    ds = xtopo.make_measurement(np.arange(50.0) ** 2, spacing=0.1)  # h = (x/Δ)²: linear interp exact formula
    r = ds.topo.sdrp(1, distances=[0.25])  # η = 2.5
    x = np.arange(50.0)
    hp = np.interp(x + 2.5, x, x**2)
    ok = x + 2.5 <= 49
    expected = np.sqrt(np.mean(((hp - x**2)[ok] / 0.25) ** 2))
    np.testing.assert_allclose(r.values[0], expected, rtol=1e-12)


def test_sdrp_acf_relation_periodic():
    """h'_rms(ℓ) = sqrt(2A(ℓ))/ℓ at integer η (paper §4.7)."""
    ds = fractal_surface(128, 1.0, hurst=0.5, periodic=True, seed=0)
    a = ds.topo.acf()
    d = a.distance.values[1:10]
    s = ds.topo.sdrp(1, distances=d)
    np.testing.assert_allclose(s.values, np.sqrt(2 * a.values[1:10]) / d, rtol=1e-10)


def test_numpy_dask_identical_and_lazy():
    ds = fractal_surface((32, 32), (1.0, 1.0), hurst=0.6, periodic=False, seed=1)
    for f in (lambda o: o.topo.vbm(), lambda o: o.topo.sdrp(1), lambda o: o.topo.sdrp(2, dim="y")):
        lazy = f(batch(ds, 2, dask=True))
        assert lazy.chunks is not None
        xr.testing.assert_allclose(lazy.compute(), f(batch(ds, 2)), rtol=1e-12)
    with pytest.raises(ChunkError):
        ds.chunk({"y": 8}).topo.vbm()


def test_nonuniform_line_sdrp_vbm():
    rng = np.random.default_rng(3)
    x = np.cumsum(rng.uniform(0.5, 1.5, 256))
    ds = xtopo.make_measurement(rng.standard_normal(256).cumsum(), x=x)
    assert "resampled" in ds.topo.sdrp(1).attrs
    assert np.all(np.isfinite(ds.topo.vbm().values))


def test_vbm_line_needs_three_pixel_blocks():
    line = fractal_surface(64, 1.0, hurst=0.7, seed=2)
    with pytest.raises(xtopo.XtopoError, match="min_pixels must be an integer >= 3"):
        line.topo.vbm(min_pixels=2)  # a line through 2 points leaves RMS 0 in every block
    assert float(line.topo.vbm(min_pixels=3).min()) > 0


@pytest.mark.parametrize("distances", [[0.1, 2.0]])
def test_sdrp_bad_distances_refused(distances):
    # NaN/inf crashed in int(), strings were parsed or crashed in float(), and lengths beyond the scan
    # allocated the wrapped profile out to the stencil (61 GiB at 1e6 on a 64-pixel periodic map)
    ds = fractal_surface((16, 16), 1.0, hurst=0.7, seed=2)
    with pytest.raises(xtopo.XtopoError, match="distances must"):
        ds.topo.sdrp(distances=distances)


@pytest.mark.parametrize("size", [4e-6, 1.0, 250.0])
def test_vbm_line_bandwidth_is_length_over_zeta(size):
    # line scans got sqrt(L)/ζ (the area formula sqrt(Lx Ly) applied to one length): right only for L = 1
    ds = fractal_surface(256, size, hurst=0.7, periodic=False, seed=1)
    v = ds.topo.vbm(reliable=False)
    length = 256 * float(ds.x[1] - ds.x[0])
    np.testing.assert_allclose(v.bandwidth.values, length / v.magnification.values, rtol=1e-12)
    # the block of side ℓ = L/ζ holds L/ζ/Δx pixels: the finest block has min_pixels
    np.testing.assert_allclose(float(v.bandwidth.min()) / float(ds.x[1] - ds.x[0]), 4)
    area = fractal_surface((32, 128), (size / 4, size), hurst=0.7, periodic=False, seed=1).topo.vbm(reliable=False)
    np.testing.assert_allclose(area.bandwidth.values, np.sqrt(size**2 / 4) / area.magnification.values, rtol=1e-12)


def _reference_stats(h, etas, order, periodic, rows):
    """RMS of D^(η) h and the minimum of D²^(η) h from the whole difference fields (numpy, one η at a time)."""
    from xtopo._kernels.scaled import scaled_difference

    lead = h.shape[: h.ndim - 1 - rows]
    rms = np.full(lead + (len(etas),), np.nan)
    low = np.full(lead + (len(etas),), np.inf)
    for i, eta in enumerate(etas):
        d = scaled_difference(h, float(eta), order=order, periodic=periodic)
        if d.shape[-1]:
            flat = d.reshape(lead + (-1,))
            rms[..., i] = np.sqrt(np.mean(flat * flat, axis=-1))
            low[..., i] = flat.min(axis=-1)
    return rms, low


@pytest.mark.parametrize("periodic", [True, False])
@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("shape,rows", [((3, 40, 257), 1), ((64, 200), 1), ((500,), 0), ((4, 300), 0)])
def test_compiled_scale_passes_equal_the_difference_fields(shape, rows, order, periodic):
    """The one-pass compiled SDRP and curvature kernels give the values of the difference fields to 1e-13,
    at integer and fractional η, stencils longer than the profile (NaN / no curvature) included."""
    from xtopo._kernels.scaled import max_negative_curvature, sdrp_rms

    h = np.cumsum(np.random.default_rng(1).standard_normal(shape), axis=-1)
    n = shape[-1]
    etas = np.concatenate([np.geomspace(1, n - 1, 25), [1.0, 2.0, 3.5, n / 2 - 0.5, n + 3.0]])
    rms, low = _reference_stats(h, etas, order, periodic, rows)
    np.testing.assert_allclose(sdrp_rms(h, 0.3, etas, order=order, periodic=periodic, rows=rows), rms / 0.3**order,
                               rtol=1e-13, atol=1e-13 * np.nanmax(rms) / 0.3**order)
    if order == 2:
        curv = max_negative_curvature(h, 0.3, etas, periodic=periodic, rows=rows)
        expect = -low / 0.09
        assert np.array_equal(np.isinf(curv), np.isinf(expect))
        fin = np.isfinite(expect)
        np.testing.assert_allclose(curv[fin], expect[fin], rtol=1e-13, atol=1e-13 * np.abs(expect[fin]).max())
