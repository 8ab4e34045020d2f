"""Properties of the scale-dependent analyses (issue 9): PSD ∝ h², periodic translation invariance."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import strategies as st

import xtopo

from .strategies import heights, measurements, property_tests

pytestmark = [pytest.mark.timeout(120), pytest.mark.filterwarnings("error::RuntimeWarning")]


def _spectra(ds):
    out = {"psd_1d": ds.topo.psd(reliable=False), "acf_1d": ds.topo.acf(reliable=False)}
    if ds.height.ndim == 2:
        out["psd_1d_y"] = ds.topo.psd(dim="y", reliable=False)
        out["psd_2d"] = ds.topo.psd("2d")
        if ds.height.size > 1:
            out["psd_iso"] = ds.topo.psd("iso", reliable=False)
            out["acf_iso"] = ds.topo.acf("iso", reliable=False)
    return out


def _spectra_or_refused(ds):
    """``_spectra(ds)``, or None where xtopo refuses the heights as giving results beyond float64: allowed only
    where the spectra's own scale, h² times the lengths' powers (up to m⁴ for a 2D PSD), lies near or below the
    smallest normal float64 (a constant map's rounding noise there cannot be told from a true value)."""
    try:
        return _spectra(ds)
    except xtopo.XtopoError as exc:
        h = float(np.abs(ds.height.values).max())
        length = max(ds.sizes[d] * ds[d].attrs["spacing"] for d in ds.height.dims)
        assert "beyond the range of float64" in str(exc)
        assert h**2 * max(length, 1.0) ** 2 * min(length, 1.0) ** 2 < 1e-280, (h, length, exc)
        return None


def _like(ds, h):
    return xtopo.make_measurement(h, spacing=ds.x.attrs["spacing"], periodic=xtopo.conventions.is_periodic(ds))


def check_psd_scales_with_h2(ds, alpha):
    """C(αh) = α² C(h) for every PSD kind (windowed or not), and A(αh) = α² A(h)."""
    ref = _spectra_or_refused(ds)
    out = _spectra_or_refused(_like(ds, ds.height.values * alpha))
    if ref is None or out is None:
        return
    h = np.abs(ds.height.values).max() * alpha
    length = max(ds.sizes[d] * ds[d].attrs["spacing"] for d in ds.height.dims)
    for name, c in ref.items():
        scaled = c.values * alpha**2
        # round-off of the mean removal is relative to |h|, not to the fluctuations (constant maps)
        lengths = length ** (int(c.attrs["units"][-1]) - 2)  # m2 (ACF), m3 (1D PSD), m4 (2D PSD)
        atol = 1e-12 * float(np.abs(scaled).max()) + (1e-13 * h) ** 2 * lengths + 1e-300
        np.testing.assert_allclose(out[name].values, scaled, rtol=1e-9, atol=atol, err_msg=name)
        assert out[name].attrs["units"] == c.attrs["units"]


test_psd_scales_with_h2, test_psd_scales_with_h2_nightly = property_tests(
    ds=measurements(), alpha=st.sampled_from([1e-12, 1e-6, 3.0, 1e3]))(check_psd_scales_with_h2)


def _rolled(h, shifts):
    return np.roll(h, shifts[-h.ndim:], axis=tuple(range(h.ndim)))


def check_periodic_translation(h, dx, shifts):
    """np.roll of a periodic map leaves its PSD, ACF and scalar parameters unchanged."""
    ds = xtopo.make_measurement(h, spacing=dx, periodic=True)
    moved = xtopo.make_measurement(_rolled(h, shifts), spacing=dx, periodic=True)
    a = _spectra_or_refused(ds)
    if a is None:
        return
    b = _spectra(moved)
    for name in a:
        atol = 1e-10 * float(np.abs(a[name].values).max()) + 1e-300
        np.testing.assert_allclose(b[name].values, a[name].values, rtol=1e-9, atol=atol, err_msg=name)
    sa, sb = ds.topo.scalars(), moved.topo.scalars()
    for name in sa.data_vars:
        x, y = sa[name].values, sb[name].values
        assert (np.isnan(x) == np.isnan(y)).all(), name
        scale = max(float(np.nanmax(np.abs(x))) if np.isfinite(x).any() else 0.0, 1e-300)
        np.testing.assert_allclose(y, x, rtol=1e-8, atol=1e-8 * scale, err_msg=name)


test_periodic_translation, test_periodic_translation_nightly = property_tests(
    h=heights(), dx=st.sampled_from([1e-9, 1.0]), shifts=st.tuples(st.integers(-20, 20), st.integers(-20, 20)))(
    check_periodic_translation)
