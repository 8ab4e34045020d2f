"""Kurtosis of the scale-dependent curvature distribution: physics identities, backends, and the
demonstration that one module plus one record of ``xtopo.stitching.ANALYSES`` puts a new analysis in
the twin averages, the report, the command line and batch runs."""

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo import batch
from xtopo.analysis.curvature_kurtosis import curvature_kurtosis
from xtopo.cli import main
from xtopo.stitching import ANALYSES, analyze_twin

NAME = "curvature_kurtosis"


def _gaussian(shape=(128, 128), size=1e-6, seed=1, **kw):
    return xtopo.datasets.fractal_surface(shape, size, hurst=0.8, rms_slope=0.1, seed=seed, **kw)


def test_a_sinusoid_has_the_kurtosis_of_the_arcsine_distribution():
    """``D²h`` of ``sin(kx)`` is ``sin(kx)`` times a factor of the scale: ``⟨sin⁴⟩/⟨sin²⟩² = 3/2``
    at every stencil length that is not a multiple of twice the wavelength."""
    x = np.arange(1024)
    ds = xtopo.make_measurement(np.sin(2 * np.pi * x / 64), spacing=1.0, units="um", periodic=True)
    k = curvature_kurtosis(ds, distances=[2.0, 6.0, 20.0, 50.0, 100.0, 300.0])
    np.testing.assert_allclose(k.values, 1.5, rtol=1e-9)
    assert k.attrs["units"] == "1" and k["distance"].attrs["units"] == "um"


def test_a_gaussian_surface_has_kurtosis_three_at_the_small_scales():
    k = curvature_kurtosis(_gaussian((256, 256)))
    small = k.where(k["distance"] < 20 * float(k["distance"][0]), drop=True)  # many independent samples
    assert small.size >= 8
    np.testing.assert_allclose(small.values, 3.0, atol=0.15)


def test_sparse_spikes_make_heavy_tails_that_fade_with_scale():
    """Spikes on a Gaussian self-affine profile: their curvature falls as 1/ℓ², the profile's only as
    ℓ^(H-2), so the kurtosis is far above 3 at the pixel scale and back near 3 a decade and a half up."""
    ds = xtopo.datasets.fractal_surface(4096, 4096.0, hurst=0.8, rms_slope=0.1, seed=5, units="nm")
    h = ds.height.values.copy()
    h[np.random.default_rng(3).choice(h.size, 8, replace=False)] += 2.0
    k = curvature_kurtosis(ds.assign(height=("x", h)))
    assert float(k[0]) > 100
    assert float(k.sel(distance=slice(40, 150)).max()) < 4  # where the profile has many independent samples


def test_independent_of_the_height_scale_and_lazy_on_dask():
    ds = _gaussian((64, 96), periodic=False)
    k = curvature_kurtosis(ds)
    huge = curvature_kurtosis(ds.assign(height=ds.height * 1e250))  # analysed in scaled units
    np.testing.assert_allclose(huge.values, k.values, rtol=1e-10)
    stack = xr.concat([ds.height, 2 * ds.height], dim="sample").chunk({"sample": 1})
    lazy = curvature_kurtosis(ds.assign(height=stack))
    assert lazy.chunks is not None
    np.testing.assert_allclose(lazy.compute().values, np.stack([k.values, k.values]), rtol=1e-10)


def test_missing_data_are_refused_with_advice():
    ds = _gaussian((32, 32))
    ds["height"][3, 4] = np.nan
    with pytest.raises(xtopo.XtopoError, match="fill_missing"):
        curvature_kurtosis(ds)


def test_the_record_puts_it_in_the_twin_averages_cli_report_and_batch(tmp_path, capsys):
    """The module and its record in ANALYSES, nothing else: the twin average (equal weight per
    measurement: 3 for Gaussian measurements of different sizes, within its predicted error), the NetCDF
    group and the summary line of ``xtopo analyze``, a panel of the report, and a name of
    ``xtopo.batch.analyze``."""
    ms = {"fine": _gaussian((64, 64), 1e-6, seed=1), "coarse": _gaussian((64, 64), 4e-6, seed=2)}  # overlapping
    assert ANALYSES[NAME].measure is curvature_kurtosis
    tree = analyze_twin(xtopo.twin(ms))
    avg = tree[NAME].to_dataset()
    assert set(avg["measurement"].values) == set(ms) and avg["average"].attrs["units"] == "1"
    ok = avg["count"].values > 0
    assert int(avg["count"].max()) == 2 and np.isfinite(avg["uncertainty"].values[ok]).all()
    assert np.mean(np.abs(avg["average"].values[ok] - 3) <= 2 * avg["uncertainty"].values[ok]) >= 0.9

    paths = []
    for name, ds in ms.items():
        paths.append(str(tmp_path / f"{name}.nc"))
        xtopo.to_netcdf(ds, paths[-1])
    assert main(["analyze", *paths, "-o", str(tmp_path / "out.nc")]) == 0
    assert f"{NAME} average of 2 of 2 measurements" in capsys.readouterr().out
    with xr.open_datatree(tmp_path / "out.nc") as out:
        assert NAME in out.children

    assert set(ANALYSES) <= set(batch._analyze._available_analyses())  # batch finds every twin analysis's module
    res = batch.analyze(ms, [NAME], scheduler="sync", progress=False)
    for name, ds in ms.items():
        np.testing.assert_allclose(res[NAME].sel(measurement=name).dropna("distance").values,
                                   curvature_kurtosis(ds).values)

    pytest.importorskip("holoviews")
    pytest.importorskip("bokeh")
    from xtopo.report import report

    page = report(xtopo.twin(ms), analyses=(NAME,), maps=False)
    assert ANALYSES[NAME].title in page and 'class="error"' not in page
