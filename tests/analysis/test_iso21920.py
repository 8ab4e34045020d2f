"""ISO 21920-2 profile parameters: analytic anchors, surfalize side by side, real profile, laziness (issue 22)."""

import dask.array as dsa
import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo._kernels.material_ratio_rows import descending, functional_of_sorted
from xtopo.analysis.iso21920 import PARAMETERS
from xtopo.conventions import make_measurement
from xtopo.errors import GridError

from ..conftest import batch

A, LAM, DX = 0.5, 100.0, 0.25  # µm


def _cosine(periods=25, phase=0.0):
    x = np.arange(int(round(periods * LAM / DX))) * DX
    return make_measurement(A * np.cos(2 * np.pi * x / LAM + phase), spacing=DX, units="um")


@pytest.mark.parametrize("convention", ["iso21920", "iso4287"])
def test_sinusoid_anchors(convention):
    r = _cosine().topo.iso21920(form=None, convention=convention)  # 5 sections of 5 periods each
    expect = {"Ra": 2 * A / np.pi, "Rq": A / np.sqrt(2), "Rp": A, "Rv": A, "Rz": 2 * A, "Rt": 2 * A,
              "Rku": 1.5, "RSm": LAM, "Rdq": 2 * np.pi * A / LAM / np.sqrt(2)}
    for name, value in expect.items():
        assert float(r[name]) == pytest.approx(value, rel=2e-4), name
    assert abs(float(r.Rsk)) < 1e-9
    assert float(r.Rmr) == pytest.approx(50.0, abs=0.05)  # the samples at exactly 0 (x = λ/4, 3λ/4) are ties
    assert r.attrs["sampling_length"] == pytest.approx(25 * LAM / 5) and r.attrs["sections"] == 5


def test_sinusoid_anchors_hold_through_the_roughness_filter():
    """λ = λc/10 passes the L-filter at 1 - exp(-π α² 100) ≈ 1; λs = λ/40 passes it at 99.96 %."""
    r = _cosine(periods=70).topo.iso21920(lambda_s=LAM / 40, lambda_c=10 * LAM, form="line")
    assert r.attrs["evaluation_length"] == pytest.approx(5000.0) and r.attrs["lambda_c"] == 1000.0
    for name, value in {"Ra": 2 * A / np.pi, "Rq": A / np.sqrt(2), "Rp": A, "Rv": A, "Rz": 2 * A, "RSm": LAM,
                        "Rku": 1.5}.items():
        assert float(r[name]) == pytest.approx(value, rel=2e-3), name


def test_every_variable_has_units_and_long_name():
    r = _cosine().topo.iso21920()
    assert set(r.data_vars) == set(PARAMETERS)
    for name, v in r.data_vars.items():
        assert v.attrs["long_name"] and v.attrs["units"] in ("um", "1", "%"), name
    assert r.Rmr1.attrs["units"] == "%" and r.Rk.attrs["units"] == "um" and r.Rku.attrs["units"] == "1"


def test_linear_ramp_material_ratio():
    """A ramp's material ratio curve is a straight line: Rk is its whole height, Rmr(c) linear in c."""
    x = np.arange(1000) * 0.1
    ramp = make_measurement(0.02 * x, spacing=0.1, units="um")  # heights 0 .. ~2, mean ~1
    r = ramp.topo.iso21920(form=None, c=0.5)
    span = 0.02 * x.max()
    assert float(r.Rk) == pytest.approx(span, rel=1e-3)
    assert float(r.Rmr1) == pytest.approx(0, abs=0.2) and float(r.Rmr2) == pytest.approx(100, abs=0.2)
    assert float(r.Rmr) == pytest.approx(100 * (span / 2 - 0.5) / span, abs=0.1)  # c measured from the mean line


def test_side_by_side_with_surfalize_profile():
    """Same definitions as surfalize's Profile (mean line, 5 sections via equal splits, 13565-2 construction).

    Rdq: surfalize differentiates by forward differences, ISO 4287 by the 7-point formula; a smooth
    profile (many points per wavelength) makes both the derivative.
    """
    surfalize = pytest.importorskip("surfalize")
    rng = np.random.default_rng(7)
    x = np.arange(5000) * 0.2
    smooth = sum(rng.normal() * np.sin(2 * np.pi * x / lam + rng.uniform(0, 6.3)) for lam in (37.0, 53.0, 91.0, 140.0))
    h = smooth + 0.3 * rng.exponential(size=x.size) ** 2 * (rng.uniform(size=x.size) < 0.02)  # some sharp peaks
    ours = make_measurement(h, spacing=0.2, units="um").topo.iso21920(form=None)
    p = surfalize.Profile(h, 0.2)
    for name in ("Ra", "Rq", "Rp", "Rv", "Rz", "Rt", "Rsk", "Rku"):
        assert float(ours[name]) == pytest.approx(getattr(p, name)(), rel=1e-10), name
    for name in ("Rk", "Rpk", "Rvk", "Rmr1", "Rmr2"):  # functional: issue 22 asks 2 %
        assert float(ours[name]) == pytest.approx(getattr(p, name)(), rel=2e-2), name
    rdq = make_measurement(smooth, spacing=0.2, units="um").topo.iso21920(form=None).Rdq
    assert float(rdq) == pytest.approx(surfalize.Profile(smooth, 0.2).Rdq(), rel=1e-3)


def test_functional_parameters_match_surfalize_on_random_heights():
    surfalize = pytest.importorskip("surfalize")
    rng = np.random.default_rng(3)
    for z in (rng.normal(size=4000), rng.exponential(size=4000) - 1, -rng.exponential(size=4000)):
        ours = functional_of_sorted(*descending(z))
        p = surfalize.Profile(z, 1.0)
        theirs = [p.Rk(), p.Rpk(), p.Rvk(), p.Rmr1(), p.Rmr2()]
        np.testing.assert_allclose(ours, theirs, rtol=2e-3, atol=0.05)  # atol: % of Rmr1/Rmr2 and 0-valued Rvk


def test_conventions_differ_only_where_the_standards_differ():
    rng = np.random.default_rng(1)
    h = np.cumsum(rng.normal(size=5000))
    ds = make_measurement(h, spacing=1.0, units="um")
    new, old = ds.topo.iso21920(convention="iso21920"), ds.topo.iso21920(convention="iso4287")
    for name in ("Rp", "Rv", "Rz", "Rt", "Rmr", "Rk", "Rpk", "Rvk", "Rmr1", "Rmr2"):
        assert float(new[name]) == float(old[name]), name
    assert float(new.Rq) != float(old.Rq)  # sqrt of a mean vs mean of square roots per section


def test_every_line_of_a_map_along_either_dim():
    ds = xtopo.datasets.fractal_surface((40, 300), (40.0, 300.0), hurst=0.8, rms_height=0.1, seed=4, units="um")
    rx = ds.topo.iso21920(dim="x", lambda_c=50.0)
    ry = ds.topo.iso21920(dim="y", sections=2)
    assert rx.Ra.dims == ("y",) and ry.Ra.dims == ("x",)
    one = make_measurement(ds.height.values[3], spacing=1.0, units="um").topo.iso21920(lambda_c=50.0)
    for name in PARAMETERS:
        np.testing.assert_allclose(rx[name].values[3], one[name].values, rtol=1e-10, err_msg=name)


def test_dask_batch_is_lazy_and_equals_numpy():
    ds = xtopo.datasets.fractal_surface((16, 256), (16.0, 256.0), hurst=0.7, rms_height=0.1, seed=5, units="um")
    eager = batch(ds, 2).topo.iso21920(lambda_s=2.5, lambda_c=40.0)
    lazy = batch(ds, 2, dask=True).topo.iso21920(lambda_s=2.5, lambda_c=40.0)
    assert all(isinstance(v.data, dsa.Array) for v in lazy.data_vars.values())
    xr.testing.assert_allclose(lazy.compute(), eager)
    assert eager.Ra.dims == ("sample", "y")


def test_missing_points_are_left_out():
    d = _cosine()
    h = d.height.values.copy()
    h[1000:1003] = np.nan
    r = make_measurement(h, spacing=DX, units="um").topo.iso21920(form=None)
    assert float(r.Rq) == pytest.approx(A / np.sqrt(2), rel=1e-3) and np.isfinite(float(r.Rk))


def test_real_stylus_profile_side_by_side(real_data):
    """The Dektak stylus profile (opdx-3): the R-set of its form-removed profile, next to surfalize's."""
    surfalize = pytest.importorskip("surfalize")
    ds = xtopo.open_topography(real_data / "opdx-3.opdx", units="um")
    r = ds.topo.iso21920(lambda_c=None, form="line")
    vals = {k: float(v) for k, v in r.data_vars.items()}
    assert all(np.isfinite(list(vals.values())))
    assert vals["Rq"] >= vals["Ra"] > 0 and vals["Rt"] >= vals["Rz"] >= 2 * vals["Ra"]
    profile = xtopo.filtration.filter(ds, lambda_s=None, lambda_c=None, form="line", component="primary")
    n = r.attrs["evaluation_length"] / float(ds.x[1] - ds.x[0])
    start = (ds.sizes["x"] - int(round(n))) // 2
    z = profile.height.values[start:start + int(round(n))]
    p = surfalize.Profile(z, float(ds.x[1] - ds.x[0]))
    for name in ("Ra", "Rq", "Rz", "Rt", "Rsk", "Rku"):
        assert vals[name] == pytest.approx(getattr(p, name)(), rel=1e-6), name
    assert vals["Rk"] == pytest.approx(p.Rk(), rel=2e-2)


def test_bad_arguments():
    ds = _cosine()
    with pytest.raises(GridError, match="evaluation length sections × lambda_c"):
        ds.topo.iso21920(lambda_c=2000.0)
    with pytest.raises(GridError, match="dim='y'"):
        ds.topo.iso21920(dim="y")


def test_rsm_height_and_width_discrimination():
    """Elements alternate 30 and 4 points wide: RSm is their mean, 17; with a width discrimination of 10 points
    the narrow ones join the next element (34); ripples below the height discrimination are no elements."""
    from xtopo._kernels.profile_iso import mean_width

    z = np.concatenate([np.r_[np.ones(w // 2), -np.ones(w // 2)] for w in [30, 4] * 20])
    z = z + 0.01  # no sample exactly on the mean line
    assert float(mean_width(z, 1.0, 0.5)) == pytest.approx(17.0)
    assert float(mean_width(z, 1.0, 0.5, min_width=10)) == pytest.approx(34.0)
    ripple = 0.3 * np.sin(2 * np.pi * np.arange(4000) / 10) + np.sin(2 * np.pi * np.arange(4000) / 400)
    assert float(mean_width(ripple, 1.0, 0.35)) == pytest.approx(400.0, rel=1e-2)


def test_real_map_every_line_side_by_side(real_data):
    """Every line of the MountainsMap X3P export (650 × 650): the vectorised set equals surfalize line by line."""
    surfalize = pytest.importorskip("surfalize")
    ds = xtopo.open_topography(real_data / "x3p-2.x3p", units="um")
    dx = float(ds.x[1] - ds.x[0])
    r = ds.topo.iso21920(lambda_s=None, lambda_c=20 * dx * 5, form="line")  # 100 points per section
    assert r.Ra.dims == ("y",) and bool(np.isfinite(r.Ra).all())
    rough = xtopo.filtration.filter(ds, lambda_s=None, lambda_c=r.attrs["lambda_c"], form="line", dim="x")
    n = int(round(r.attrs["evaluation_length"] / dx))
    start = (ds.sizes["x"] - n) // 2
    for i in (0, 321, 649):
        z = rough.height.values[i, start:start + n]
        p = surfalize.Profile(z, dx)
        for name in ("Rz", "Rt", "Rp", "Rv"):  # Rp, Rv: surfalize measures from the evaluation length's mean
            shift = {"Rp": -z.mean(), "Rv": z.mean()}.get(name, 0.0)
            assert float(r[name][i]) == pytest.approx(getattr(p, name)() - shift, rel=1e-9), (i, name)
        # ISO: ordinates about the L-filter's mean line, not re-centred; surfalize re-centres
        assert float(r.Rq[i]) == pytest.approx(np.hypot(p.Rq(), z.mean()), rel=1e-9)
