"""ISO 16610 filtration: transmission, end correction, F-operator, history, laziness (issue 22)."""

import dask.array as dsa
import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo._kernels import gaussian_filter as gf
from xtopo.conventions import make_measurement
from xtopo.errors import GridError, UnitsError, XtopoError
from xtopo.filtration import iso_cutoffs
from xtopo.preprocess import apply_steps

from .conftest import batch


def _amplitude(h, x, wavelength, keep):
    """Amplitude of the sinusoid of ``wavelength`` in ``h`` over the points ``keep`` (least squares)."""
    A = np.stack([np.sin(2 * np.pi * x / wavelength), np.cos(2 * np.pi * x / wavelength)], -1)[keep]
    coef, *_ = np.linalg.lstsq(A, h[keep], rcond=None)
    return float(np.hypot(*coef))


def test_weighting_function_constant_and_shape():
    assert gf.ALPHA == pytest.approx(np.sqrt(np.log(2) / np.pi), rel=1e-15)
    w = gf.weights(100.0, 1.0)
    x = np.arange(-100, 101)
    expected = np.exp(-np.pi * (x / (gf.ALPHA * 100.0)) ** 2) / (gf.ALPHA * 100.0)  # ISO 16610-21 eq. (1)
    np.testing.assert_allclose(w, expected / expected.sum(), rtol=1e-12)
    assert expected.sum() == pytest.approx(1.0, rel=1e-6)  # integrates to 1; truncation at λc drops 8e-8
    assert gf.transmission(100.0, 100.0) == pytest.approx(0.5, rel=1e-15)


@pytest.mark.parametrize("ratio", [0.5, 1.0, 2.0, 4.0])
@pytest.mark.parametrize("periodic", [False, True])
def test_profile_transmission_follows_the_gaussian_and_is_half_at_the_cutoff(ratio, periodic):
    """Waviness amplitude / input amplitude = exp(-π(α λc/λ)²); 50 % at λ = λc within 1 %."""
    lc, dx = 0.8, 0.8 / 64  # mm
    lam = lc * ratio
    n = int(round(16 * lc / dx))  # 16 cut-offs, integer number of periods for every ratio
    x = np.arange(n) * dx
    ds = make_measurement(np.sin(2 * np.pi * x / lam), spacing=dx, units="mm", periodic=periodic)
    waviness = ds.topo.filter(lambda_s=None, lambda_c=lc, form=None, component="waviness").height.values
    roughness = ds.topo.filter(lambda_s=None, lambda_c=lc, form=None).height.values
    keep = slice(None) if periodic else slice(n // 4, 3 * n // 4)  # away from the ends (end correction)
    expected = float(gf.transmission(lam, lc))
    assert _amplitude(waviness, x, lam, keep) == pytest.approx(expected, rel=1e-2, abs=1e-4)
    assert _amplitude(roughness, x, lam, keep) == pytest.approx(1 - expected, rel=1e-2, abs=1e-4)
    if ratio == 1.0:
        assert _amplitude(waviness, x, lam, keep) == pytest.approx(0.5, rel=1e-2)


def test_s_filter_transmission_half_at_lambda_s():
    ls, dx = 2.5, 0.25  # µm
    x = np.arange(4000) * dx
    ds = make_measurement(np.sin(2 * np.pi * x / ls), spacing=dx, units="um")
    primary = ds.topo.filter(lambda_s=ls, lambda_c=None, form=None, component="primary").height.values
    assert _amplitude(primary, x, ls, slice(500, 3500)) == pytest.approx(0.5, rel=1e-2)


def test_areal_filter_is_isotropic_with_half_transmission_at_the_cutoff():
    """ISO 16610-61: a wave at 45° with |λ| = λc is passed at 50 %, like one along x."""
    lc, d = 40.0, 1.0
    n = 320
    y, x = np.meshgrid(np.arange(n) * d, np.arange(n) * d, indexing="ij")
    for h, k in ((np.sin(2 * np.pi * (x + y) / (lc * np.sqrt(2))), (x + y) / np.sqrt(2)),
                 (np.sin(2 * np.pi * x / lc), x)):
        ds = make_measurement(h, spacing=d, units="um")
        w = ds.topo.filter(lambda_s=None, lambda_c=lc, form=None, component="waviness").height.values
        keep = (slice(100, 220), slice(100, 220))
        amp = _amplitude(w[keep].ravel(), k[keep].ravel(), lc, slice(None))
        assert amp == pytest.approx(0.5, rel=1e-2)


def test_full_length_kept_and_end_correction_is_exact_for_a_constant():
    x = np.arange(500) * 0.01
    ds = make_measurement(np.full(500, 3.0), spacing=0.01, units="mm")
    w = ds.topo.filter(lambda_s=None, lambda_c=0.8, form=None, component="waviness")
    assert w.height.shape == (500,) and np.all(np.isfinite(w.height))
    np.testing.assert_allclose(w.height, 3.0, rtol=1e-12)  # renormalised weights: no droop at the ends
    ramp = make_measurement(2 * x, spacing=0.01, units="mm")
    wr = ramp.topo.filter(lambda_s=None, lambda_c=0.8, form=None, component="waviness").height.values
    np.testing.assert_allclose(wr[80:-80], 2 * x[80:-80], atol=1e-9)  # symmetric weights keep a line inside


def test_missing_data_stay_missing_and_are_left_out_of_the_weights():
    x = np.arange(2000) * 0.01
    h = np.full(2000, 1.0)
    h[700:760] = np.nan
    ds = make_measurement(h, spacing=0.01, units="mm")
    w = ds.topo.filter(lambda_s=None, lambda_c=0.8, form=None, component="waviness")
    assert np.isnan(w.height.values[700:760]).all()
    np.testing.assert_allclose(np.delete(w.height.values, np.s_[700:760]), 1.0, rtol=1e-12)


def test_form_operator_removes_a_polynomial_of_any_degree():
    y, x = np.meshgrid(np.linspace(0, 1, 40), np.linspace(0, 2, 50), indexing="ij")
    cubic = 1 + x - 2 * y + x**3 - 0.5 * x * y**2 + y**3
    ds = make_measurement(cubic, spacing=(1 / 39, 2 / 49), units="mm")
    flat = ds.topo.filter(lambda_s=None, lambda_c=None, form=3, component="primary")
    np.testing.assert_allclose(flat.height, 0, atol=1e-10)
    line = make_measurement(np.linspace(0, 1, 50) ** 2, spacing=0.02, units="mm")
    np.testing.assert_allclose(line.topo.filter(None, None, form="curvature", component="primary").height, 0,
                               atol=1e-12)


def test_history_attrs_and_the_preprocessing_step():
    ds = xtopo.datasets.fractal_surface((64, 128), (0.5, 1.0), hurst=0.8, rms_height=1e-3, periodic=False, seed=1,
                                        units="mm")
    f = ds.topo.filter(lambda_s="2.5 um", lambda_c="0.25 mm")
    assert f.attrs["lambda_c"] == pytest.approx(0.25) and f.attrs["lambda_s"] == pytest.approx(0.0025)
    assert "filter(lambda_s=0.0025, lambda_c=0.25 mm, form='plane'" in f.attrs["history"].splitlines()[-1]
    assert f.height.attrs["units"] == "mm"
    stepped = apply_steps(ds, {"filter": {"lambda_s": "2.5 um", "lambda_c": "0.25 mm"}})
    xr.testing.assert_identical(stepped.height, f.height)
    with pytest.raises(XtopoError, match="no option 'cutoff'"):
        apply_steps(ds, {"filter": {"cutoff": 1}})


def test_profiles_of_a_map_along_a_dim_equal_the_line_scans():
    ds = xtopo.datasets.fractal_surface((6, 256), (0.06, 2.56), hurst=0.8, rms_height=1e-3, seed=2, units="mm")
    lines = ds.topo.filter(lambda_s=None, lambda_c=0.8, dim="x")
    for i in (0, 5):
        one = make_measurement(ds.height.values[i], spacing=0.01, units="mm").topo.filter(lambda_s=None,
                                                                                        lambda_c=0.8, form="line")
        np.testing.assert_allclose(lines.height.values[i], one.height.values, atol=1e-14)
    square = xtopo.datasets.fractal_surface((64, 64), 0.64, hurst=0.8, rms_height=1e-3, seed=2, units="mm")
    cols = square.topo.filter(lambda_s=None, lambda_c=0.08, dim="y")
    assert cols.height.dims == ("y", "x")
    one = make_measurement(square.height.values[:, 7], spacing=0.01, units="mm").topo.filter(None, 0.08, form="line")
    np.testing.assert_allclose(cols.height.values[:, 7], one.height.values, atol=1e-14)


def test_dask_batch_is_lazy_and_equals_numpy():
    ds = xtopo.datasets.fractal_surface((32, 64), (0.32, 0.64), hurst=0.7, rms_height=1e-3, seed=3, units="mm")
    eager = batch(ds, 3).topo.filter(lambda_s=0.01, lambda_c=0.08)
    lazy = batch(ds, 3, dask=True).topo.filter(lambda_s=0.01, lambda_c=0.08)
    assert isinstance(lazy.height.data, dsa.Array)
    xr.testing.assert_allclose(lazy.compute().height, eager.height)


def test_interior_matches_surfalize_gaussian_filter():
    """Same weighting function: away from the ends (where surfalize reflects) the mean lines agree."""
    surfalize = pytest.importorskip("surfalize")
    from surfalize.filter import GaussianFilter

    rng = np.random.default_rng(5)
    dx, lc = 0.5, 80.0  # µm
    h = np.cumsum(rng.normal(size=3000)) * 0.01
    ours = make_measurement(h, spacing=dx, units="um").topo.filter(None, lc, form=None, component="waviness")
    theirs = GaussianFilter(lc, "lowpass")(surfalize.Profile(h, dx)).data
    keep = slice(400, -400)
    scale = np.ptp(h)
    assert np.max(np.abs(ours.height.values[keep] - theirs[keep])) < 1e-3 * scale  # scipy truncates at 4σ


def test_iso_cutoff_table_and_auto_selection():
    assert iso_cutoffs(0.015, "um") == pytest.approx((2.5, 80.0))
    assert iso_cutoffs(0.05, "um") == pytest.approx((2.5, 250.0))
    assert iso_cutoffs(1.0, "um") == pytest.approx((2.5, 800.0))
    assert iso_cutoffs(5e-6, "m") == pytest.approx((8e-6, 2.5e-3))
    assert iso_cutoffs(20.0, "um") == pytest.approx((25.0, 8000.0))
    dx = 1.0  # µm; Ra about 0.5 µm: the 0.8 mm class
    x = np.arange(6000) * dx
    h = 0.8 * np.sin(2 * np.pi * x / 60.0) + 0.3 * np.sin(2 * np.pi * x / 37.0)
    f = make_measurement(h, spacing=dx, units="um").topo.filter()
    assert f.attrs["lambda_c"] == pytest.approx(800.0) and f.attrs["lambda_s"] == pytest.approx(2.5)


def test_bad_arguments_name_the_parameter():
    ds = make_measurement(np.zeros(100), spacing=1.0, units="um")
    with pytest.raises(GridError, match="lambda_s=.* must be shorter than lambda_c"):
        ds.topo.filter(lambda_s=10, lambda_c=5)
    with pytest.raises(GridError, match="lambda_c=200 um is longer than the measurement"):
        ds.topo.filter(lambda_s=None, lambda_c=200)
    with pytest.raises(UnitsError, match="lambda_c='3 s'"):
        ds.topo.filter(lambda_c="3 s")
    with pytest.raises(XtopoError, match="lambda_c must be a"):
        ds.topo.filter(lambda_c=True)
    with pytest.raises(XtopoError, match="component"):
        ds.topo.filter(lambda_c=10, component="form")
    with pytest.raises(XtopoError, match="form must be"):
        ds.topo.filter(lambda_c=10, form=-1)
    nonuniform = make_measurement(np.zeros(5), x=[0, 1, 3, 4, 7], units="um")
    with pytest.raises(GridError, match="uniform grid"):
        nonuniform.topo.filter(lambda_c=2)


@pytest.mark.parametrize("dim", [None, "x"])
def test_roughness_plus_waviness_is_the_sf_surface(dim):
    """The L-filter splits the S-F surface: roughness + waviness = primary, missing points included."""
    ds = xtopo.datasets.fractal_surface((48, 96), (0.48, 0.96), hurst=0.8, rms_height=1e-3, seed=6, units="mm")
    ds["mask"] = (ds.height.dims, np.zeros(ds.height.shape, bool))
    ds["mask"][5:9, 10:30] = True
    kw = dict(lambda_s=0.01, form=2, dim=dim)
    r = ds.topo.filter(lambda_c=0.16, component="roughness", **kw).height
    w = ds.topo.filter(lambda_c=0.16, component="waviness", **kw).height
    p = ds.topo.filter(lambda_c=None, component="primary", **kw).height
    xr.testing.assert_allclose(r + w, p, atol=1e-15)
    assert int(np.isnan(p).sum()) == 4 * 20


def test_linear_end_correction_keeps_lines_and_planes_to_the_ends():
    """Order-1 regression (end="linear"): a tilted line or plane is its own mean line/surface up to the edges
    (the renormalised order-0 correction bends there); inside, both are the plain Gaussian filter."""
    x = np.arange(600) * 0.01
    ramp = make_measurement(0.3 * x + 2, spacing=0.01, units="mm")
    kw = dict(lambda_s=None, lambda_c=0.8, form=None, component="waviness")
    lin = ramp.topo.filter(end="linear", **kw).height.values
    norm = ramp.topo.filter(**kw).height.values
    np.testing.assert_allclose(lin, 0.3 * x + 2, atol=1e-11)
    assert np.abs(norm - (0.3 * x + 2)).max() > 0.01
    y, xx = np.meshgrid(np.arange(80) * 0.01, np.arange(120) * 0.01, indexing="ij")
    plane = 0.2 * xx - 0.1 * y + 1
    h = plane.copy()
    h[30:40, 50:70] = np.nan
    ds = make_measurement(h, spacing=0.01, units="mm")
    w = ds.topo.filter(end="linear", **{**kw, "lambda_c": 0.25}).height.values
    np.testing.assert_allclose(w[np.isfinite(h)], plane[np.isfinite(h)], atol=1e-11)
    rng = np.random.default_rng(2)
    rough = make_measurement(rng.normal(size=3000), spacing=0.01, units="mm")
    a = rough.topo.filter(end="linear", **kw).height.values
    b = rough.topo.filter(**kw).height.values
    np.testing.assert_allclose(a[80:-80], b[80:-80], atol=1e-12)  # one λc from the ends: the same filter
    assert "end='linear'" in rough.topo.filter(end="linear", **kw).attrs["history"]
    with pytest.raises(XtopoError, match="end must be one of"):
        rough.topo.filter(end="spline", **kw)
