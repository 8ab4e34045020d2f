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


def batch(ds, n=3, dask=False):
    """Stack ``n`` scaled copies of a measurement along a ``sample`` dim (optionally dask-backed)."""
    out = xr.concat([ds.assign(height=ds.height * (1 + 0.5 * i)) for i in range(n)],
                    dim="sample")
    if dask:
        out = out.chunk({"sample": 1})
    return out
