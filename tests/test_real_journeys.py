"""Journeys on the real instrument files in ../shared/data/real: read, preprocess, analyse, archive.

Each test skips when the directory is absent (see the ``real_data`` fixture).
"""

import numpy as np
import pytest
import xarray as xr

import xtopo


def test_fill_missing_fills_a_real_map_read_as_a_transposed_view(real_data):
    """opd-1.opd is stored column by column; the reader's map is a transposed view of the file.

    fill_missing left its 116 undefined pixels NaN and dropped the mask (the fill was written
    into a copy), so every analysis after it failed or ran on NaN.
    """
    ds = xtopo.open_topography(real_data / "opd-1.opd")
    assert int(ds["mask"].sum()) > 0
    filled = ds.topo.fill_missing()
    assert np.isfinite(filled.height).all()
    xr.testing.assert_equal(filled["filled"], ds["mask"].rename("filled").assign_attrs(filled["filled"].attrs))
    # the measured pixels are untouched
    keep = ~ds["mask"].values
    np.testing.assert_array_equal(filled.height.values[keep], ds.height.values[keep])
