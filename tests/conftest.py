import os
import pathlib

import numpy as np
import pytest
import xarray as xr

import xtopo  # noqa: F401  (registers accessors)

REPO = pathlib.Path(__file__).resolve().parents[1]
REAL_DATA = (REPO / ".." / "shared" / "data" / "real").resolve()


@pytest.fixture(scope="session")
def real_data():
    """Directory of the real instrument files; tests using it skip when it is absent."""
    if not REAL_DATA.is_dir():
        pytest.skip(f"real data directory {REAL_DATA} not present")
    return REAL_DATA


@pytest.fixture
def tilted_with_hole(tmp_path):
    """A rough map on a strong tilt with a hole of 40 points, written as an xtopo archive: (path, the file read)."""
    ds = xtopo.datasets.fractal_surface((48, 64), 1e-5, hurst=0.8, rms_height=1e-8, periodic=False, seed=4)
    ds = ds.assign(height=ds.height + 0.05 * ds.x)  # a tilt of 5 %: Sq of the file is that of the tilt
    ds["mask"] = (ds.height.dims, np.zeros(ds.height.shape, bool))
    ds["mask"][10:14, 20:30] = True
    path = tmp_path / "tilted.nc"
    xtopo.to_netcdf(ds, path)
    return path, xtopo.open_topography(path)


def batch(ds, n=3, dask=False):
    """Stack ``n`` scaled copies of a measurement along a ``sample`` dim (optionally dask-backed)."""
    out = xr.concat([ds.assign(height=ds.height * (1 + 0.5 * i)) for i in range(n)],
                    dim="sample")
    if dask:
        out = out.chunk({"sample": 1})
    return out
