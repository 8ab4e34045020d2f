import dask.array as dsa
import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo._kernels import fft
from xtopo._kernels.derivatives import (forward_difference, fourier_first, fourier_second, second_difference,
                                        wavevectors)
from xtopo.conventions import make_measurement
from xtopo.datasets import fractal_surface, sinusoid

from ..conftest import batch


@pytest.mark.parametrize("n,periods", [(64, 4), (100, 5), (37, 1)])
def test_sinusoid_scalars_analytic(n, periods):
    L, A = 3.0, 0.7
    lam = L / periods
    ds = sinusoid(n, L, amplitude=A, wavelength=lam)
    dx = L / n
    q = 2 * np.pi / lam
    s = ds.topo.scalars().sel(direction="x")
    rel = dict(rel=1e-12)
    assert float(s.Rq) == pytest.approx(A / np.sqrt(2), **rel)
    assert float(s.Rdq) == pytest.approx(A * 2 * np.sin(q * dx / 2) / dx / np.sqrt(2), **rel)
    assert float(s.Rddq) == pytest.approx(A * (2 - 2 * np.cos(q * dx)) / dx**2 / np.sqrt(2), **rel)
    assert float(s.Rsk) == pytest.approx(0.0, abs=1e-12)
    assert float(s.Rku) == pytest.approx(1.5, **rel)


def test_area_sinusoid_scalars_analytic():
    L, A, n = 2.0, 0.3, 64
    ds = sinusoid((n, n), (L, L), amplitude=A, wavelength=L / 4, direction="xy")
    q, dx = 2 * np.pi / (L / 4), L / n
    s = ds.topo.scalars()
    assert float(s.Sq) == pytest.approx(A, rel=1e-12)  # two orthogonal cosines: Sq² = 2·A²/2
    assert float(s.Sdq) == pytest.approx(A * 2 * np.sin(q * dx / 2) / dx, rel=1e-12)
    lap = (2 * np.cos(q * dx) - 2) / dx**2
    assert float(s.Sddq) == pytest.approx(np.sqrt((A * lap) ** 2 * 2 / 2 / 4), rel=1e-12)
    assert float(s.Sz) == pytest.approx(4 * A, rel=1e-12)
    np.testing.assert_allclose(s.Rq.values, A / np.sqrt(2), rtol=1e-12)  # each profile: one cosine + const


def test_plane_scalars_analytic():
    ny, nx, dy, dx, a, b = 30, 40, 0.2, 0.1, 0.3, -0.05
    y, x = np.meshgrid(np.arange(ny) * dy, np.arange(nx) * dx, indexing="ij")
    ds = make_measurement(a * x + b * y + 7.0, spacing=(dy, dx), units="um")
    s = ds.topo.scalars()
    assert float(s.Sdq) == pytest.approx(np.hypot(a, b), rel=1e-12)
    assert float(s.Sddq) == pytest.approx(0.0, abs=1e-12)
    sq = np.sqrt(a**2 * dx**2 * (nx**2 - 1) / 12 + b**2 * dy**2 * (ny**2 - 1) / 12)
    assert float(s.Sq) == pytest.approx(sq, rel=1e-12)
    assert float(s.Rdq.sel(direction="x")) == pytest.approx(abs(a), rel=1e-12)
    assert float(s.Rdq.sel(direction="y")) == pytest.approx(abs(b), rel=1e-12)
    assert float(s.Rq.sel(direction="x")) == pytest.approx(abs(a) * dx * np.sqrt((nx**2 - 1) / 12), rel=1e-12)
    assert float(s.Sz) == pytest.approx(a * dx * (nx - 1) - b * dy * (ny - 1), rel=1e-12)
    assert s.Sq.attrs["units"] == "um" and s.Sdq.attrs["units"] == "1" and s.Sddq.attrs["units"] == "um-1"
    for v in s.data_vars.values():
        assert v.attrs["long_name"]


def test_rms_gradient_is_sqrt2_rms_slope_on_isotropic_surface():
    ds = fractal_surface((512, 512), (1.0, 1.0), hurst=0.8, rms_slope=0.1, seed=7)
    s = ds.topo.scalars()
    ratio = float(s.Sdq) / float(s.Rdq.mean())
    assert ratio == pytest.approx(np.sqrt(2), rel=0.05)


@pytest.mark.parametrize("periodic", [True, False])
def test_nonperiodic_does_not_wrap(periodic):
    h = np.zeros(16)
    h[-1] = 1.0  # a jump only across the periodic seam
    ds = make_measurement(h, spacing=1.0, periodic=periodic)
    rdq = float(ds.topo.scalars().Rdq.squeeze())
    assert rdq == pytest.approx(np.sqrt(2 / 16) if periodic else np.sqrt(1 / 15), rel=1e-12)


def test_table1_real_and_fourier_space_derivatives_agree():
    ds = fractal_surface((96, 128), (0.9, 1.3), hurst=0.6, seed=2)
    h = ds.height.values
    dy, dx = 0.9 / 96, 1.3 / 128
    qx = wavevectors(128, dx, real=True)[None, :]
    qy = wavevectors(96, dy)[:, None]
    ht = fft.rfftn(h)
    for real, symbol in [
        (forward_difference(h, dx, periodic=True, axis=-1), fourier_first(qx, dx)),
        (forward_difference(h, dy, periodic=True, axis=-2), fourier_first(qy, dy)),
        (second_difference(h, dx, periodic=True, axis=-1), fourier_second(qx, dx)),
        (second_difference(h, dy, periodic=True, axis=-2), fourier_second(qy, dy)),
    ]:
        spectral = fft.irfftn(symbol * ht, s=h.shape)
        np.testing.assert_allclose(spectral, real, rtol=0, atol=1e-10 * np.abs(real).max())


def test_nonuniform_line_scan_scalars_match_uniform_on_uniform_positions():
    def f(x):
        return np.sin(2 * np.pi * 3 * x) + 0.1 * x

    x = np.linspace(0, 1, 400)
    uni = make_measurement(f(x), spacing=x[1], units="m").topo.scalars().squeeze()
    xn = x.copy()
    xn[1:-1] += 0.3 * x[1] * np.sin(np.arange(398))  # irregular, still increasing
    non = make_measurement(f(xn), x=xn, units="m").topo.scalars().squeeze()
    assert non.Rdq.attrs["units"] == "1"
    assert float(non.Rdq) == pytest.approx(float(uni.Rdq), rel=0.01)
    assert float(non.Rq) == pytest.approx(float(uni.Rq), rel=0.01)
    assert float(non.Rddq) == pytest.approx(float(uni.Rddq), rel=0.05)


@pytest.mark.parametrize("shape", [(48, 64), (256,)])
def test_scalars_numpy_and_dask_batch_agree_and_stay_lazy(shape):
    ds = fractal_surface(shape, 1.0, hurst=0.7, periodic=False, seed=3)
    eager = xtopo.analysis.scalars.scalars(batch(ds, 3))
    lazy = batch(ds, 3, dask=True).topo.scalars()
    assert all(isinstance(v.data, dsa.Array) for v in lazy.data_vars.values())
    xr.testing.assert_allclose(lazy.compute(), eager)
    single = ds.topo.scalars()
    xr.testing.assert_allclose(eager.isel(sample=0, drop=True), single)


def test_scalars_refuse_chunked_lateral_dims():
    ds = fractal_surface((64, 64), 1.0, hurst=0.7).chunk({"x": 16})
    with pytest.raises(xtopo.ChunkError, match="single chunk"):
        ds.topo.scalars()


def test_missing_data_is_ignored_not_propagated():
    ds = fractal_surface((64, 64), 1.0, hurst=0.7, seed=1)
    h = ds.height.values.copy()
    h[10:14, 20:30] = np.nan
    s = make_measurement(h, spacing=1 / 64, periodic=True).topo.scalars()
    assert all(np.all(np.isfinite(v.values)) for v in s.data_vars.values())


@pytest.mark.parametrize("kind", ["height", "slope", "curvature"])
def test_distribution_is_normalised_with_units(kind):
    ds = fractal_surface((64, 64), (1.0, 1.0), hurst=0.7, seed=1, units="um")
    d = ds.topo.distribution(kind, bins=40)
    width = np.diff(d.bin_center.values)[0]
    assert float(d.probability_density.sum()) * width == pytest.approx(1.0, rel=1e-10)
    assert d.bin_center.attrs["units"] == {"height": "um", "slope": "1", "curvature": "um-1"}[kind]
    lazy = batch(ds, 2, dask=True).topo.distribution(kind, bins=40)
    assert isinstance(lazy.probability_density.data, dsa.Array)
    xr.testing.assert_allclose(lazy.isel(sample=0).compute().probability_density, d.probability_density)


@pytest.mark.parametrize("engine", ["netcdf4", "h5netcdf"])
def test_scalars_direction_is_fixed_width_unicode_for_line_and_area_scans(tmp_path, engine):
    # line scans gave an object-dtype 'direction' (expand_dims), area scans '<U1'
    x = np.linspace(0, 1, 64) ** 1.2
    line, area = fractal_surface(256, 1.0, hurst=0.7), fractal_surface((32, 32), 1.0, hurst=0.7)
    for ds in (line, batch(line, 2, dask=True), make_measurement(np.sin(7 * x), x=x, units="m"), area):
        s = ds.topo.scalars()
        assert s.direction.dtype.kind == "U", ds.sizes
        assert s.direction.attrs["long_name"] == "direction of the profiles"
    s = line.topo.scalars()
    back = xr.open_dataset(xtopo.to_netcdf(s, tmp_path / "s.nc", engine=engine), engine=engine).load()
    assert back.direction.dtype == s.direction.dtype == area.topo.scalars().direction.dtype
    xr.testing.assert_allclose(back, s)


def test_distribution_bins_beyond_the_data_refused():
    # 10**30 raised numpy's 'Maximum allowed dimension exceeded', 10**9 allocated gigabytes
    for bins in [10**9, 10**30]:
        ds = fractal_surface((16, 16), 1.0, hurst=0.7, seed=1)
        with pytest.raises(xtopo.XtopoError, match="bins must be at most 10000"):
            ds.topo.distribution(bins=bins)


def test_distribution_bad_dim_refused():
    # arrays raised numpy's 'truth value of an array is ambiguous', a list TypeError
    for dim in [np.array(["x", "y"]), np.array([]), ["x"], None]:
        ds = fractal_surface((16, 16), 1.0, hurst=0.7, seed=1)
        with pytest.raises(xtopo.XtopoError, match="is not a lateral dim"):
            ds.topo.distribution("slope", dim=dim)
