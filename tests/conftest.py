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


_MISSING = object()


def _default_client():
    try:
        from distributed import default_client
    except ImportError:
        return None
    try:
        return default_client()
    except ValueError:
        return None


@pytest.fixture(autouse=True)
def _no_leaked_dask_scheduler():
    """Fail the test that leaves dask's scheduler setting or a default distributed client behind.

    A failed ``distributed.Client(...)`` once stayed the process's default client with
    ``scheduler="dask.distributed"`` set; a cache test run after it (in another module) failed with
    "missing port number in address ''". The setting is undone for the tests that follow.
    """
    import dask

    before = {k: dask.config.config.get(k, _MISSING) for k in ("scheduler", "shuffle")}
    client = _default_client()
    yield
    leaked = _default_client()
    if leaked is not None and leaked is not client:
        pytest.fail(f"the test left a default distributed client behind: {leaked!r}")
    after = {k: dask.config.config.get(k, _MISSING) for k in before}
    if after != before:
        for key, value in before.items():
            if value is _MISSING:
                dask.config.config.pop(key, None)
            else:
                dask.config.config[key] = value
        pytest.fail(f"the test left dask's config changed: {({k: v for k, v in after.items() if v is not _MISSING})}")
