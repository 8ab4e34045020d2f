import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.datasets import fractal_surface, prescribed_psd
from xtopo.errors import ChunkError, GridError, XtopoError

from ..conftest import batch


@pytest.fixture(scope="module")
def periodic_area():
    return fractal_surface((64, 96), (0.5, 0.75), hurst=0.7, rms_height=1e-3, periodic=True, seed=3)


def test_parseval_2d(periodic_area):
    c2d = periodic_area.topo.psd("2d", window=None)
    assert c2d.attrs["units"] == "m4" and c2d.q_x.attrs["units"] == "m-1"
    dqx = 2 * np.pi / 0.75
    dqy = 2 * np.pi / 0.5
    total = float(c2d.sum()) * dqx * dqy / (2 * np.pi) ** 2
    sq = float(periodic_area.topo.scalars().Sq)
    np.testing.assert_allclose(total, sq**2, rtol=1e-10)


@pytest.mark.parametrize("dim", ["x", "y"])
def test_parseval_1d(periodic_area, dim):
    c1d = periodic_area.topo.psd("1d", dim=dim, window=None)
    n = periodic_area.sizes[dim]
    length = n * float(periodic_area[dim][1] - periodic_area[dim][0])
    mult = np.full(c1d.sizes["q"], 2.0)
    mult[0] = 1.0
    if n % 2 == 0:
        mult[-1] = 1.0
    total = float((c1d * mult).sum()) * (2 * np.pi / length) / (2 * np.pi)
    rq = float(periodic_area.topo.scalars().Rq.sel(direction=dim))
    np.testing.assert_allclose(total, rq**2, rtol=1e-10)
    assert c1d.attrs["units"] == "m3"


def test_iso_bins_and_variants(periodic_area):
    iso = periodic_area.topo.psd("iso")
    q = iso.q.values
    assert np.all(np.diff(q) > 0) and np.all(np.isfinite(iso.values))
    pers = periodic_area.topo.psd("iso", convention="persson")
    xr.testing.assert_allclose(pers.reset_coords(drop=True), (iso / (4 * np.pi**2)).reset_coords(drop=True))
    eq = periodic_area.topo.psd("iso", equivalent_1d=True)
    np.testing.assert_allclose(eq.values, iso.values * q / np.pi, rtol=1e-12)
    assert eq.attrs["units"] == "m3" and iso.attrs["units"] == "m4"
    assert iso.attrs["window"] == "none"


def _mean_psd_ratio(shape, nseeds, hurst, nb_points=40):
    acc = []
    for s in range(nseeds):
        ds = fractal_surface(shape, (1.0, 1.0), hurst=hurst, periodic=True, seed=s, prefactor=1.0,
                             long_cutoff=1 / 8, short_cutoff=8 / shape[-1])
        acc.append(ds.topo.psd(nb_points=nb_points).values)
    p = ds.topo.psd(nb_points=nb_points)
    truth = prescribed_psd(ds)
    q = p.q.values
    sel = (q >= truth.q_long) & (q <= truth.q_short)
    return np.mean(acc, 0)[sel] / truth.c1d(q[sel])


def test_psd_matches_prescribed_small():
    ratio = _mean_psd_ratio((256, 512), 4, 0.5, nb_points=20)
    assert np.all(np.abs(ratio - 1) < 0.15)


@pytest.mark.slow
@pytest.mark.parametrize("hurst", [0.3, 0.5, 0.8])
def test_psd_matches_prescribed_acceptance(hurst):
    ratio = _mean_psd_ratio((2048, 2048), 8, hurst)
    assert np.all(np.abs(ratio - 1) < 0.10), ratio


def test_hann_window_removes_edge_artifact():
    """Nonperiodic crop: the bare PSD is dominated by the q^-2 edge artifact, the Hann-windowed one is not."""
    ds = fractal_surface((128, 1024), (0.125, 1.0), hurst=0.8, periodic=False, seed=5, prefactor=1.0)
    truth = prescribed_psd(ds)
    bare = ds.topo.psd("1d", window=None, nb_points=20)
    hann = ds.topo.psd("1d", window="hann", nb_points=20)
    assert hann.attrs["window"] == "hann" and bare.attrs["window"] == "none"
    q = bare.q.values
    high = q > 2 * np.pi * 64  # wavelengths below L/64
    r_bare = bare.values[high] / truth.c1d(q[high])
    r_hann = hann.values[high] / truth.c1d(q[high])
    assert np.all(r_bare > 2.0), r_bare          # artifact dominates
    assert np.all(np.abs(r_hann - 1) < 0.2), r_hann
    # the artifact is ∝ q^-2 (∝ 1/sin²(qΔx/2) on the grid): log-log slope well below Nyquist
    mid = high & (q < 2 * np.pi * 256)
    slope = np.polyfit(np.log(q[mid]), np.log(bare.values[mid]), 1)[0]
    assert abs(slope + 2) < 0.3


def test_line_scan_and_units():
    ds = fractal_surface(256, 10.0, hurst=0.5, periodic=True, seed=1, units="um")
    p = ds.topo.psd()
    assert p.attrs["units"] == "um3" and p.q.attrs["units"] == "um-1"
    with pytest.raises(GridError):
        ds.topo.psd("iso")


def test_numpy_dask_identical_and_lazy(periodic_area):
    b = batch(periodic_area, 3)
    bd = batch(periodic_area, 3, dask=True)
    for kind in ("1d", "2d", "iso"):
        lazy = bd.topo.psd(kind)
        assert lazy.chunks is not None
        xr.testing.assert_allclose(lazy.compute(), b.topo.psd(kind), rtol=1e-12)


def test_chunked_lateral_dim_refused(periodic_area):
    with pytest.raises(ChunkError, match="rechunk"):
        periodic_area.chunk({"x": 16}).topo.psd("iso")


def test_missing_data_raises():
    h = np.random.default_rng(0).standard_normal((16, 16))
    h[3, 4] = np.nan
    ds = xtopo.make_measurement(h, size=(1.0, 1.0))
    with pytest.raises(XtopoError, match="fill_missing"):
        ds.topo.psd("iso")


def test_nonuniform_line_resampled():
    rng = np.random.default_rng(2)
    x = np.cumsum(rng.uniform(0.5, 1.5, 200))
    ds = xtopo.make_measurement(np.sin(x / 7), x=x)
    p = ds.topo.psd()
    assert "resampled" in p.attrs and np.all(np.isfinite(p.values))


def test_nonuniform_line_in_memory_resampled_as_xarray_interpolates():
    # a float64 line in memory is resampled by numpy directly, a lazy one by xarray's interp: the same values
    from xtopo.analysis._scale import prepare

    rng = np.random.default_rng(5)
    x = np.cumsum(rng.uniform(0.5, 1.5, 300))
    h = np.sin(x / 7)
    h[[17, 18, 150]] = np.nan
    ds = xtopo.make_measurement(h, x=x)
    eager, lazy = prepare(ds).h, prepare(ds.chunk()).h.compute()
    uniform = np.linspace(x[0], x[-1], x.size)
    np.testing.assert_array_equal(eager.values, ds.height.interp(x=uniform, method="linear").values)
    xr.testing.assert_identical(eager, lazy)
    assert eager.x.attrs["spacing"] == uniform[1] - uniform[0] and "grid" not in eager.attrs


def test_resolution_cutoff_drops_high_q(periodic_area):
    ds = periodic_area.assign_attrs(resolution=0.05, resolution_units="m")
    p = ds.topo.psd("iso")
    assert p.attrs["reliability_cutoff"] == 0.05
    assert float(p.q.max()) <= 2 * np.pi / 0.05
    full = ds.topo.psd("iso", reliable=False)
    assert full.sizes["q"] > p.sizes["q"]


@pytest.mark.parametrize("analysis", [lambda d: d.topo.psd("1d"), lambda d: d.topo.psd("2d"),
                                      lambda d: d.topo.psd("iso"), lambda d: d.topo.acf("1d"),
                                      lambda d: d.topo.acf("iso")], ids=["psd1d", "psd2d", "psdiso", "acf1d", "acfiso"])
def test_float32_heights_give_float64_on_both_backends(analysis):
    # psd 1d/2d and acf 1d of float32 heights came out float32 while dask declared float64:
    # a lazy result's dtype differed from what it computed to (and from psd iso, vbm, sdrp: float64)
    ds = fractal_surface((32, 48), (1.0, 1.5), hurst=0.7, periodic=True, seed=4)
    ds32 = ds.assign(height=ds.height.astype(np.float32))
    eager = analysis(ds32)
    lazy = analysis(ds32.chunk())
    computed = lazy.compute()
    assert eager.dtype == lazy.dtype == computed.dtype == np.float64
    xr.testing.assert_allclose(computed, eager)
    # the float32 heights' spectrum, not a different one: within float32 precision of the float64 analysis
    exact = analysis(ds32.assign(height=ds32.height.astype(np.float64)))
    xr.testing.assert_allclose(eager, exact, rtol=1e-4, atol=1e-5 * float(exact.max()))


@pytest.mark.parametrize("kw,match", [({"dim": np.array(["x", "y"])}, "is not a lateral dimension")])
def test_bad_options_refused(periodic_area, kw, match):
    # arrays raised numpy's 'truth value of an array is ambiguous'; window=0 was taken as False (no window)
    with pytest.raises(XtopoError, match=match):
        periodic_area.topo.psd(**kw)


def test_window_none_and_false_mean_no_window():
    ds = fractal_surface(64, 1.0, hurst=0.7, seed=2, periodic=False)
    xr.testing.assert_allclose(ds.topo.psd(window=False), ds.topo.psd(window=None))
    xr.testing.assert_allclose(ds.topo.psd(window="none"), ds.topo.psd(window=None))
    assert not np.allclose(ds.topo.psd(window="hann").values, ds.topo.psd(window=None).values)
