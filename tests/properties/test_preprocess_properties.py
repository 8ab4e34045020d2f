"""Properties of preprocessing (issue 9): detrending is idempotent, fill_missing keeps measured values."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import strategies as st

import xtopo

from .strategies import heights, masks, property_tests

pytestmark = [pytest.mark.timeout(120), pytest.mark.filterwarnings("error::RuntimeWarning")]


@st.composite
def masked_measurements(draw, **kw):
    h = draw(heights(**kw))
    m = draw(masks(h.shape)) if draw(st.booleans()) else None
    return xtopo.make_measurement(h, spacing=draw(st.sampled_from([1e-9, 1.0])), periodic=draw(st.booleans()),
                                  mask=m)


def check_detrend_idempotent(ds, mode, per_line):
    once = ds.topo.detrend(mode, per_line=per_line)
    twice = once.topo.detrend(mode, per_line=per_line)
    h1, h2 = once.height.values, twice.height.values
    missing = np.isnan(ds.topo.height.values)
    assert (np.isnan(h1) == missing).all() and (np.isnan(h2) == missing).all()
    scale = float(np.nanmax(np.abs(ds.topo.height.values))) if not missing.all() else 0.0
    np.testing.assert_allclose(h2[~missing], h1[~missing], rtol=0, atol=1e-9 * scale + 1e-300)
    assert once.height.attrs["units"] == "m" and once.x.attrs["units"] == "m"


test_detrend_idempotent, test_detrend_idempotent_nightly = property_tests(
    ds=masked_measurements(), mode=st.sampled_from(["mean", "plane", "curvature"]), per_line=st.booleans())(
    check_detrend_idempotent)


def check_fill_missing_keeps_values(ds):
    h = ds.topo.height.values
    missing = np.isnan(h)
    filled = ds.topo.fill_missing()
    v = filled.height.values
    np.testing.assert_array_equal(v[~missing], h[~missing])
    assert np.isfinite(v).all()
    # maximum principle of harmonic (maps) and linear (lines) interpolation
    lo, hi = h[~missing].min(), h[~missing].max()
    tol = 1e-9 * max(abs(lo), abs(hi))
    assert v.min() >= lo - tol and v.max() <= hi + tol
    np.testing.assert_array_equal(filled.filled.values, missing)


test_fill_missing_keeps_values, test_fill_missing_keeps_values_nightly = property_tests(
    ds=masked_measurements())(check_fill_missing_keeps_values)
