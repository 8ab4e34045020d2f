"""Detrending and harmonic filling (paper §3.2)."""

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.conventions import make_measurement
from xtopo.errors import GridError
from xtopo.preprocess import detrend, fill_missing

from .conftest import batch


def _grid(ny=48, nx=64, d=0.5):
    y, x = np.mgrid[0:ny, 0:nx].astype(float)
    return y * d, x * d


def _rough(ny=48, nx=64, seed=0):
    rng = np.random.default_rng(seed)
    h = rng.standard_normal((ny, nx))
    k = np.fft.rfft2(h) / (1 + np.add.outer(np.fft.fftfreq(ny) ** 2, np.fft.rfftfreq(nx) ** 2) * 400)
    return np.fft.irfft2(k, s=(ny, nx))


# ---------------------------------------------------------------- detrend

@pytest.mark.parametrize("mode,coef", [("mean", [3.0]), ("plane", [3.0, 0.2, -0.4]),
                                       ("curvature", [3.0, 0.2, -0.4, 0.01, 0.02, -0.03])])
def test_detrend_removes_exact_polynomial(mode, coef):
    y, x = _grid()
    terms = [np.ones_like(x), x, y, x * x, x * y, y * y]
    h = sum(c * t for c, t in zip(coef, terms))
    ds = make_measurement(h, spacing=0.5, units="um")
    out = detrend(ds, mode)
    np.testing.assert_allclose(out.height.values, 0, atol=1e-9)
    assert out.height.attrs["units"] == "um"
    assert out.attrs["history"].endswith(f"detrend(mode={mode!r}, per_line=False)")


def test_detrend_minimises_rms_and_ignores_missing():
    y, x = _grid()
    rough = _rough()
    h = rough + 0.3 * x - 0.1 * y
    h[5:9, 10:20] = np.nan
    ds = make_measurement(h, spacing=0.5, units="um")
    snapshot = ds.copy(deep=True)
    out = detrend(ds, "plane")
    xr.testing.assert_identical(ds, snapshot)  # the input is never modified
    assert bool(out.mask[6, 12]) and np.isnan(out.height[6, 12])
    ok = np.isfinite(h)
    r = out.height.values[ok]
    # least squares: residual orthogonal to 1, x, y; any other plane gives a larger RMS
    for t in (np.ones_like(x), x, y):
        assert abs(np.dot(r, t[ok])) < 1e-8 * np.abs(t[ok]).sum()
    assert np.sqrt(np.mean(r ** 2)) < np.sqrt(np.mean((r + 1e-3 * x[ok]) ** 2))


def test_detrend_per_line_and_line_scans():
    y, x = _grid()
    offsets = np.arange(48.0)[:, None]
    ds = make_measurement(offsets + 0.5 * x * (1 + offsets), spacing=0.5, units="nm")
    np.testing.assert_allclose(detrend(ds, "plane", per_line=True).height.values, 0, atol=1e-9)
    assert np.abs(detrend(ds, "plane").height.values).max() > 1  # a single plane cannot do this
    xs = np.cumsum(np.random.default_rng(3).uniform(0.5, 2.0, 40))
    line = make_measurement(1 + 2 * xs - 0.05 * xs ** 2, x=xs, units="um")
    assert line.attrs["grid"] == "nonuniform"
    np.testing.assert_allclose(line.topo.detrend("curvature").height.values, 0, atol=1e-9)


def test_detrend_batch_numpy_and_dask():
    y, x = _grid()
    ds = make_measurement(_rough() + 0.1 * x, spacing=0.5, units="um")
    eager = detrend(batch(ds), "plane")
    lazy = detrend(batch(ds, dask=True), "plane")
    assert lazy.height.chunks is not None  # still lazy
    xr.testing.assert_allclose(lazy.compute(), eager)
    xr.testing.assert_allclose(eager.isel(sample=1), detrend(ds.assign(height=ds.height * 1.5), "plane"))


# ---------------------------------------------------------------- fill_missing

def _hole(y, x, cy, cx, r):
    return (y - cy) ** 2 + (x - cx) ** 2 < r ** 2


@pytest.mark.parametrize("periodic", [False, True])
def test_fill_exact_on_linear_fields(periodic):
    y, x = _grid()
    h = 1.5 + 0.3 * x - 0.7 * y
    missing = _hole(y, x, 10, 15, 4) | _hole(y, x, 15, 22, 3) | (np.abs(x - 25) < 1.2) & (np.abs(y - 5) < 2)
    if periodic:  # a periodic linear field must be periodic: use a constant + wrapped holes
        h = np.full_like(h, 2.5)
        missing |= _hole(y, x, 0, 0, 3)
    ds = make_measurement(np.where(missing, np.nan, h), spacing=0.5, units="um", periodic=periodic)
    out = fill_missing(ds)
    np.testing.assert_allclose(out.height.values, h, atol=1e-10)
    assert "mask" not in out and out.filled.dtype == bool
    np.testing.assert_array_equal(out.filled.values, missing)
    assert out.attrs["history"].endswith("fill_missing(harmonic)")


def test_fill_anisotropic_spacing_exact_on_linear_field():
    y, x = np.mgrid[0:30, 0:40].astype(float)
    y, x = y * 2.0, x * 0.25
    h = 0.5 * x + 0.2 * y
    missing = _hole(y / 2.0, x / 0.25, 15, 20, 6)
    ds = make_measurement(np.where(missing, np.nan, h), spacing=(2.0, 0.25), units="um")
    np.testing.assert_allclose(fill_missing(ds).height.values, h, atol=1e-10)


def test_fill_mean_value_property_circular_hole():
    y, x = np.mgrid[0:96, 0:96].astype(float)
    h = _rough(96, 96, seed=4)
    hole = _hole(y, x, 48, 48, 15)
    edge = ~hole & (np.roll(hole, 1, 0) | np.roll(hole, -1, 0) | np.roll(hole, 1, 1) | np.roll(hole, -1, 1))
    ds = make_measurement(np.where(hole, np.nan, h), spacing=1.0, units="um")
    filled = fill_missing(ds).height.values
    assert filled[hole].mean() == pytest.approx(h[edge].mean(), abs=0.02 * h.std())


def test_fill_no_jumps_at_hole_edges():
    y, x = np.mgrid[0:96, 0:96].astype(float)
    h = _rough(96, 96, seed=5)
    hole = _hole(y, x, 40, 50, 20)
    out = fill_missing(make_measurement(np.where(hole, np.nan, h), spacing=1.0, units="um")).height.values
    step_x = np.abs(np.diff(out, axis=1))
    across = hole[:, 1:] != hole[:, :-1]  # steps that cross the hole edge
    typical = np.abs(np.diff(h, axis=1))[~across].max()
    assert step_x[across].max() <= typical
    # maximum principle: the fill stays within the edge values
    edge = ~hole & (np.roll(hole, 1, 0) | np.roll(hole, -1, 0) | np.roll(hole, 1, 1) | np.roll(hole, -1, 1))
    assert h[edge].min() - 1e-12 <= out[hole].min() and out[hole].max() <= h[edge].max() + 1e-12


def test_fill_holes_touching_border_and_half_missing():
    y, x = np.mgrid[0:64, 0:64].astype(float)
    h = _rough(64, 64, seed=6)
    corner = _hole(y, x, 0, 0, 12) | (x > 60)
    half = x < 32
    for missing in (corner, half):
        ds = make_measurement(np.where(missing, np.nan, h), spacing=1.0, units="um")
        out = fill_missing(ds).height.values
        assert np.all(np.isfinite(out))
        np.testing.assert_array_equal(out[~missing], h[~missing])
        assert h[~missing].min() <= out[missing].min() and out[missing].max() <= h[~missing].max()
    lin = 0.1 * x + 0.2 * y  # at a free border the fill has zero normal slope, so not exact here, but bounded
    out = fill_missing(make_measurement(np.where(half, np.nan, lin), spacing=1.0, units="um")).height.values
    assert np.abs(out - lin)[half].max() < np.ptp(lin)  # bounded, no blow-up


def test_fill_all_missing_raises():
    with pytest.raises(GridError, match="nothing to fill"):
        fill_missing(make_measurement(np.full((4, 4), np.nan), spacing=1.0, units="um"))


def test_fill_line_scans_linear_uniform_and_nonuniform():
    xs = np.cumsum(np.random.default_rng(7).uniform(0.5, 2.0, 30))
    h = 2.0 - 0.3 * xs
    hm = h.copy()
    hm[[3, 4, 5, 17]] = np.nan
    line = make_measurement(hm, x=xs, units="um")
    out = line.topo.fill_missing()
    np.testing.assert_allclose(out.height.values, h, atol=1e-12)
    assert out.attrs["history"].endswith("fill_missing(linear)")
    uni = make_measurement(hm, size=30.0, units="um")
    assert np.all(np.isfinite(fill_missing(uni).height.values))
    per = make_measurement(np.where(np.arange(8) == 0, np.nan, np.arange(8.0) % 4), size=8.0, units="um",
                           periodic=True)
    assert float(fill_missing(per).height[0]) == pytest.approx((3 + 1) / 2)  # wraps: between x=7 (3) and x=1 (1)


def test_fill_original_unchanged_and_batch_dask():
    y, x = _grid()
    h = _rough()
    h[10:14, 20:30] = np.nan
    ds = make_measurement(h, spacing=0.5, units="um")
    snapshot = ds.copy(deep=True)
    eager = fill_missing(batch(ds))
    xr.testing.assert_identical(ds, snapshot)
    lazy = fill_missing(batch(ds, dask=True))
    assert lazy.height.chunks is not None
    xr.testing.assert_allclose(lazy.compute(), eager)
    assert not np.isnan(eager.height.values).any()
    xr.testing.assert_allclose(ds.topo.fill_missing(), fill_missing(ds))


def test_fill_real_file_with_missing(real_data):
    path = real_data / "hfm-1.hfm"
    ds = xtopo.open_topography(path)
    filled = ds.topo.detrend("plane").topo.fill_missing()
    assert np.all(np.isfinite(filled.height.values))


@pytest.mark.parametrize("mode", ["linear", None, ["plane"], {}, 1])
def test_detrend_unknown_mode_refused(mode):
    # was a bare ValueError (or TypeError: unhashable) instead of an XtopoError
    ds = make_measurement(np.zeros((4, 4)), size=(1.0, 1.0))
    with pytest.raises(xtopo.XtopoError, match="mode must be one of"):
        detrend(ds, mode)


@pytest.mark.parametrize("dask", [False, True])
def test_fill_marks_infinite_heights_as_filled(dask):
    # an inf height was interpolated like a NaN, but ``filled`` said False there
    h = _rough(8, 8)
    ds = make_measurement(h, spacing=0.5, units="um")
    ds["height"][3, 4] = np.inf
    ds["height"][5, 1] = np.nan
    out = fill_missing(ds.chunk() if dask else ds)
    assert (out.filled.chunks is not None) == dask  # still lazy
    expected = xr.zeros_like(ds.height, dtype=bool)
    expected[3, 4] = expected[5, 1] = True
    xr.testing.assert_equal(out.filled.compute().reset_coords(drop=True), expected.reset_coords(drop=True))
    assert np.isfinite(out.height.values).all()


def test_fill_again_keeps_the_record_of_earlier_fills():
    # filling a filled (then detrended) measurement again reset ``filled`` to all False
    h = _rough(8, 8)
    h[2, 3] = np.nan
    once = fill_missing(make_measurement(h, spacing=0.5, units="um"))
    again = fill_missing(detrend(once))
    xr.testing.assert_identical(again.filled, once.filled)
    assert bool(again.filled[2, 3])


# ---------------------------------------------------------------- audit: preprocess edge cases

def test_preprocess_leaves_the_input_height_attrs_alone():
    # height_of copied periodic/tip_radius into the caller's own height variable; later changes of the
    # Dataset's attrs (periodic=0, a converted tip radius) were then shadowed by these stale copies
    ds = make_measurement(_rough(8, 8), spacing=0.5, units="um", periodic=True, tip_radius=0.1)
    before = dict(ds.height.attrs)
    detrend(ds, "mean")
    fill_missing(ds)
    xtopo.conventions.height_of(ds)
    assert ds.height.attrs == before
    ds.attrs["periodic"] = 0
    assert not xtopo.conventions.is_periodic(xtopo.conventions.height_of(ds))


def test_detrend_and_fill_history_one_line_per_step():
    ds = make_measurement(_rough(8, 8), spacing=0.5, units="um")
    ds.attrs["history"] = "read\n"  # a trailing newline gave an empty line
    out = fill_missing(detrend(detrend(ds)))
    assert out.attrs["history"].split("\n") == ["read", "detrend(mode='plane', per_line=False)",
                                                "detrend(mode='plane', per_line=False)", "fill_missing(harmonic)"]
    assert "history" not in out.height.attrs
    ds.attrs["history"] = np.array(["read", "scaled"])  # as some readers give a multi-line text attr
    assert detrend(ds, "mean").attrs["history"] == "read\nscaled\ndetrend(mode='mean', per_line=False)"


@pytest.mark.parametrize("mode", ["plane", "curvature"])
def test_detrend_tilt_of_periodic_surface_makes_it_nonperiodic(mode):
    # subtracting a tilt leaves a step where a periodic surface wraps around; keeping periodic=1 made
    # the analyses differentiate across that step (PSD x12 at short wavelengths, Sdq +55% for H = 0.8)
    from xtopo.datasets import fractal_surface

    s = fractal_surface((128, 128), 1.0, hurst=0.8, seed=3)
    out = detrend(s, mode)
    assert out.attrs["periodic"] == 0 and not xtopo.conventions.is_periodic(out)
    assert out.attrs["history"].endswith("; periodic set to 0")
    assert detrend(s.height.assign_attrs(periodic=1), mode).attrs["periodic"] == 0  # DataArray too
    assert xtopo.conventions.is_periodic(s)  # the input is untouched
    # short wavelengths are those of the surface, not of a step's q^-2 tail
    ratio = out.topo.psd(kind="1d", dim="x", reliable=False) / s.topo.psd(kind="1d", dim="x", reliable=False)
    assert 0.8 < float(ratio[-10:].mean()) < 1.25
    # the mean keeps a periodic surface periodic
    assert detrend(s, "mean").attrs["periodic"] == 1
    assert detrend(s, "mean", per_line=True).attrs["periodic"] == 1


@pytest.mark.parametrize("dims", [("y", "x"), ("x", "y")])
def test_fill_single_row_map_needs_no_y_spacing(dims):
    # a 1×N map (or N×1) without a 'spacing' attr on its single-point axis raised GridError
    # ("cannot infer the spacing of 'y'"), though no y-neighbours enter the fill
    h = np.arange(6.0)
    h[2] = np.nan
    ds = make_measurement(h[None, :] if dims == ("y", "x") else h[:, None], size=(1.0, 6.0) if dims == ("y", "x")
                          else (6.0, 1.0), units="um")
    single = "y" if dims == ("y", "x") else "x"
    del ds[single].attrs["spacing"]
    for obj in (ds, ds.height):
        out = fill_missing(obj)
        np.testing.assert_allclose(out.values.ravel() if isinstance(out, xr.DataArray) else out.height.values.ravel(),
                                   np.arange(6.0))


def test_fill_with_y_in_another_unit_uses_the_true_anisotropy():
    # y in nm and x in um (a dataset validate would refuse): the fill weighted y-neighbours 10⁶x too weakly
    h = _rough(20, 20, seed=9)
    h[8:12, 6:14] = np.nan
    m = make_measurement(h, spacing=(1.0, 1.0), units="um")
    mixed = m.assign_coords(y=m.y.copy(data=m.y.values * 1000).assign_attrs(units="nm"))
    np.testing.assert_allclose(fill_missing(mixed).height.values, fill_missing(m).height.values, atol=1e-12)


def test_detrend_plane_plus_noise_recovers_the_noise_least_squares():
    # independent check: the result is the noise minus its own least-squares plane, whatever the units
    y, x = np.mgrid[0:40, 0:50].astype(float)
    y, x = 0.3 * y, 0.7 * x
    noise = np.random.default_rng(0).standard_normal((40, 50))
    out = detrend(make_measurement(noise + 2 + 0.3 * x - 0.2 * y, spacing=(0.3, 0.7), units="nm"))
    A = np.stack([np.ones(x.size), x.ravel(), y.ravel()], axis=1)
    own_plane = (A @ np.linalg.lstsq(A, noise.ravel(), rcond=None)[0]).reshape(noise.shape)
    np.testing.assert_allclose(out.height.values, noise - own_plane, atol=1e-12)
    assert out.height.attrs["units"] == "nm"


@pytest.mark.parametrize("dask", [False, True])
def test_fill_reproduces_a_harmonic_function_on_an_anisotropic_grid(dask):
    # x² - y² + xy has a vanishing spacing-weighted discrete Laplacian: the fill is exact, not only for planes
    y, x = np.mgrid[0:40, 0:50].astype(float)
    y, x = 0.3 * y, 0.7 * x
    h = x ** 2 - y ** 2 + 0.5 * x * y + 3
    hole = (y / 0.3 - 20) ** 2 + (x / 0.7 - 25) ** 2 < 100
    ds = make_measurement(np.where(hole, np.nan, h), spacing=(0.3, 0.7), units="nm")
    out = fill_missing(ds.chunk() if dask else ds)
    np.testing.assert_allclose(out.height.values, h, atol=1e-9)


@pytest.mark.parametrize("mode", ["plane", "curvature"])
def test_detrend_refuses_nan_positions(mode):
    # a NaN coordinate raised numpy's LinAlgError ('SVD did not converge in Linear Least Squares')
    x = np.r_[np.arange(15.0), np.nan]
    ds = xr.Dataset({"height": ("x", np.random.default_rng(0).random(16), {"units": "um"})},
                    coords={"x": ("x", x, {"units": "um"})}, attrs={"grid": "nonuniform"})
    with pytest.raises(GridError, match="coordinate 'x' has 1 NaN or infinite positions"):
        detrend(ds, mode=mode)


def test_steps_by_name_apply_in_the_order_given(tilted_with_hole):
    """apply_steps (the form xtopo.batch and the command line request preprocessing in) runs the named
    steps in the order given, with their options, as the functions do; the same request in another form
    is the same steps."""
    from xtopo.preprocess import apply_steps, checked_steps

    _, ds = tilted_with_hole
    xr.testing.assert_identical(apply_steps(ds, {"detrend": "curvature", "fill_missing": True}),
                                fill_missing(detrend(ds, "curvature")))
    xr.testing.assert_identical(apply_steps(ds, ["fill_missing", ("detrend", {"per_line": True})]),
                                detrend(fill_missing(ds), "plane", per_line=True))
    xr.testing.assert_identical(apply_steps(ds, {"detrend": False, "fill_missing": None}), ds)
    assert checked_steps({"detrend": "plane"}) == checked_steps([("detrend", {"mode": "plane", "per_line": False})])
    with pytest.raises(xtopo.XtopoError, match="steps: step 'detrend': mode must be one of"):
        apply_steps(ds, {"detrend": "tilt"})


@pytest.mark.parametrize("mode", ["mean", "plane", "curvature"])
def test_detrending_a_flat_line_of_tiny_heights_gives_zeros(mode):
    """A flat line at 6.3e-304 m: the fit's rounding residual (1e-320) underflowed on the way back from scaled units
    and was refused as 'beyond the range of float64' (found by hypothesis); it is rounding noise, so 0."""
    ds = xtopo.make_measurement(np.full(5, 6.301e-304), size=5e-9)
    out = ds.topo.detrend(mode)
    np.testing.assert_array_equal(out["height"].values, 0.0)
