"""Analysis results say which measurement they came from and how they were computed."""

import dask
import dask.array as dsa
import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.analysis.hurst import hurst
from xtopo.datasets import fractal_surface

from ..conftest import batch

SOURCE = dict(source_file="scan_07.sur", source_sha256="9f2c" * 16)

#: analysis → (call, a parameter its history line must name)
ANALYSES = {
    "psd": (lambda d: d.topo.psd(), "kind='1d'"),
    "psd_2d": (lambda d: d.topo.psd("2d"), "kind='2d'"),
    "psd_iso": (lambda d: d.topo.psd("iso", nb_points=12), "nb_points=12"),
    "acf": (lambda d: d.topo.acf("iso"), "kind='iso'"),
    "vbm": (lambda d: d.topo.vbm(min_pixels=3), "min_pixels=3"),
    "sdrp": (lambda d: d.topo.sdrp(2, distances=[0.1, 0.2]), "distances=[0.1, 0.2]"),
    "scalars": (lambda d: d.topo.scalars(), "scalars()"),
    "distribution": (lambda d: d.topo.distribution("slope", bins=20), "bins=20"),
    "hurst": (lambda d: d.topo.hurst("vbm", scale_range=(0.05, 0.5)), "method='vbm'"),
}


def _measurement():
    ds = fractal_surface((64, 64), 1.0, hurst=0.7, seed=4, periodic=False)
    ds.attrs.update(SOURCE)
    return ds


@pytest.mark.parametrize("name", list(ANALYSES))
def test_results_carry_source_and_history(name):
    # results had no source_file/source_sha256/history: a written PSD did not say where it came from
    ds = _measurement()
    call, param = ANALYSES[name]
    res = call(ds)
    for key, value in SOURCE.items():
        assert res.attrs[key] == value
    lines = res.attrs["history"].split("\n")
    assert lines[:-1] == ds.attrs["history"].split("\n")
    assert lines[-1].startswith(f"xtopo.{name.split('_')[0]}(") and param in lines[-1], lines[-1]
    assert ds.attrs["history"].count("\n") == len(lines) - 2  # the measurement's history is not changed


@pytest.mark.parametrize("name", list(ANALYSES))
def test_provenance_keeps_dask_lazy_and_backends_identical(name):
    ds = _measurement()
    call, _ = ANALYSES[name]
    with dask.config.set(scheduler=lambda *a, **k: pytest.fail("computed while building the result")):
        lazy = call(batch(ds, 2, dask=True))
    arrays = [lazy.data] if isinstance(lazy, xr.DataArray) else [v.data for v in lazy.data_vars.values()]
    assert all(isinstance(a, dsa.Array) for a in arrays)
    eager, computed = call(batch(ds, 2)), lazy.compute()
    if name == "scalars":  # the profile parameters of a dask batch differ in the last bit (summation order)
        xr.testing.assert_allclose(computed, eager, rtol=1e-14)
        computed = computed.copy(data={v: eager[v].values for v in eager.data_vars})
    xr.testing.assert_identical(computed, eager)
    assert lazy.attrs["source_sha256"] == SOURCE["source_sha256"]


def test_hurst_of_a_result_extends_the_result_history():
    ds = _measurement()
    curve = ds.topo.acf()
    fit = hurst(curve, scale_range=(0.02, 0.2))
    assert fit.attrs["history"] == curve.attrs["history"] + "\nxtopo.hurst(scale_range=[0.02, 0.2])"
    assert fit.attrs["source_file"] == SOURCE["source_file"]


def test_long_parameters_are_summarised_in_the_history():
    ds = _measurement()
    res = ds.topo.sdrp(distances=np.linspace(0.02, 0.3, 20))
    assert res.attrs["history"].endswith("distances=<20 values from 0.02 to 0.3>, reliable=True)")


@pytest.mark.parametrize("engine", ["netcdf4", "h5netcdf"])
def test_written_result_says_where_it_came_from(tmp_path, engine):
    ds = _measurement()
    res = ds.topo.psd()
    before = dict(res.attrs)
    back = xr.open_dataset(xtopo.to_netcdf(res, tmp_path / "psd.nc", engine=engine), engine=engine).load()
    # the file's provenance is global (CF), not buried in the variable's attrs
    assert back.attrs["source_sha256"] == SOURCE["source_sha256"]
    assert back.attrs["history"] == res.attrs["history"]
    assert not {"source_file", "source_sha256", "history"} & set(back["psd"].attrs)
    assert back["psd"].attrs["units"] == res.attrs["units"]
    assert res.attrs == before  # the result itself keeps them
