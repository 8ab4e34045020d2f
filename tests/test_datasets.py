import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo._kernels.derivatives import forward_difference, second_difference
from xtopo.datasets import example_twin, fractal_surface, measure, prescribed_psd, sinusoid, sphere


@pytest.mark.parametrize("shape,size", [((128, 96), (1.0, 0.75)), (512, 2.0), ((64, 64), (1e-6, 1e-6))])
@pytest.mark.parametrize("hurst", [0.3, 0.8])
def test_fractal_rms_height_exact(shape, size, hurst):
    ds = fractal_surface(shape, size, hurst=hurst, rms_height=3.5e-3, seed=4)
    assert float(np.sqrt(np.mean(ds.height.values**2))) == pytest.approx(3.5e-3, rel=1e-10)
    assert float(ds.topo.scalars()["Sq" if ds.height.ndim == 2 else "Rq"].squeeze()) == pytest.approx(3.5e-3, rel=1e-10)


@pytest.mark.parametrize("shape,size", [((128, 96), (1.0, 0.75)), (512, 2.0)])
def test_fractal_rms_slope_exact(shape, size):
    ds = fractal_surface(shape, size, hurst=0.5, rms_slope=0.2, seed=1)
    sc = ds.topo.scalars()
    value = sc["Sdq"] if ds.height.ndim == 2 else sc["Rdq"].sel(direction="x")
    assert float(value) == pytest.approx(0.2, rel=1e-10)


def test_fractal_is_seeded_and_periodic_flags():
    a = fractal_surface((64, 64), 1.0, hurst=0.7, seed=3)
    b = fractal_surface((64, 64), 1.0, hurst=0.7, seed=3)
    c = fractal_surface((64, 64), 1.0, hurst=0.7, seed=4)
    xr.testing.assert_identical(a, b)
    assert not np.allclose(a.height, c.height)
    assert a.attrs["periodic"] == 1
    assert fractal_surface((64, 64), 1.0, hurst=0.7, periodic=False).attrs["periodic"] == 0


def test_fractal_expected_spectrum_matches_prescribed_psd():
    """Ensemble-averaged |h̃|²/A follows the prescribed PSD (checks the synthesis normalisation)."""
    shape, size = (64, 64), (1.0, 1.0)
    acc = 0
    for seed in range(40):
        ds = fractal_surface(shape, size, hurst=0.6, prefactor=1e-6, seed=seed)
        ht = np.fft.fft2(ds.height.values) * (1 / 64) ** 2
        acc = acc + np.abs(ht) ** 2 / 1.0
    c2d = acc / 40
    q = 2 * np.pi * np.fft.fftfreq(64, 1 / 64)
    qabs = np.hypot(*np.meshgrid(q, q, indexing="ij"))
    truth = prescribed_psd(ds).c_iso(qabs)
    ring = (qabs > 20) & (qabs < 150)
    ratio = np.mean(c2d[ring] / truth[ring])
    assert ratio == pytest.approx(1.0, abs=0.05)


def test_c1d_of_power_law_matches_closed_form():
    from math import gamma, pi, sqrt

    psd = xtopo.datasets.FractalPSD(hurst=0.7, prefactor=2.0)
    q = np.array([0.5, 3.0, 40.0])
    closed = 2.0 / pi * q ** (-1 - 1.4) * sqrt(pi) * gamma(0.7 + 0.5) / (2 * gamma(1.7))
    np.testing.assert_allclose(psd.c1d(q), closed, rtol=1e-6)


def test_sphere_and_sinusoid_geometry():
    s = sphere((64, 64), (2.0, 2.0), radius=10.0, center=(1.0, 1.0))
    assert float(s.height.max()) == pytest.approx(0.0, abs=1e-15)
    # at distance 1 from the apex: sqrt(R²-1)-R
    assert float(s.height.sel(x=0.0, y=1.0, method="nearest")) == pytest.approx(np.sqrt(99) - 10, rel=1e-12)
    w = sinusoid(64, 2.0, amplitude=0.5, wavelength=0.5)
    assert float(w.height.max()) == pytest.approx(0.5) and w.attrs["periodic"] == 1
    with pytest.raises(xtopo.XtopoError):
        sinusoid(64, 1.0, direction="y")


def _second_derivative_max(h, dx):
    """Largest curvature of the graph, -h''/(1+h'²)^(3/2), from central differences."""
    slope = (h[2:] - h[:-2]) / (2 * dx)
    return float(np.nanmax(-second_difference(h, dx, periodic=False) / (1 + slope**2) ** 1.5))


def test_measure_with_tip_never_below_truth_and_rounds_peaks():
    truth = fractal_surface(8192, 1e-3, hurst=0.8, rms_slope=0.5, periodic=False, seed=2)
    R = 2e-6
    m = measure(truth, tip_radius=R)  # same grid: sample-by-sample comparison
    assert m.attrs["tip_radius"] == R
    h_true, h_meas = truth.height.values, m.height.values
    assert np.all(h_meas >= h_true - 1e-18)
    dx = float(truth.x[1] - truth.x[0])
    assert _second_derivative_max(h_true, dx) > 5 / R  # the truth is sharper than the tip ...
    assert _second_derivative_max(h_meas, dx) <= 1.05 / R  # ... the measurement is not
    # with noise: the noise-free dilation is never below the truth, so the noisy one stays above truth - noise
    noisy = measure(truth, tip_radius=R, noise=1e-9, seed=5)
    assert np.all(noisy.height.values >= h_true - 6e-9)


def test_measure_area_tip_and_missing_data():
    truth = fractal_surface((256, 256), (1e-6, 1e-6), hurst=0.8, rms_slope=0.8, periodic=False, seed=1)
    R = 2e-8
    m = measure(truth, tip_radius=R, missing_fraction=0.1, seed=3)
    present = ~m.mask.values
    assert np.all(m.height.values[present] >= truth.height.values[present] - 1e-18)
    assert 0.09 <= float(m.mask.mean()) <= 0.2
    # resampling a window to fewer pixels keeps units and records the history
    small = measure(truth, size=(5e-7, 5e-7), pixels=(64, 64), offset=(1e-7, 2e-7))
    assert small.height.shape == (64, 64)
    assert float(small.x[1] - small.x[0]) == pytest.approx(5e-7 / 64)
    assert "measure(" in small.attrs["history"]
    with pytest.raises(xtopo.GridError):
        measure(truth, size=(2e-6, 1e-6))


def test_example_twin_spans_four_decades():
    tree = example_twin()
    assert isinstance(tree, xr.DataTree)
    kids = [n.to_dataset() for n in tree.children.values()]
    assert len(kids) >= 6
    sizes = [float(k.x.max() - k.x.min()) for k in kids]
    spacings = [float(np.min(np.diff(k.x.values))) for k in kids]
    assert max(sizes) / min(spacings) > 1e4
    stylus = [k for k in kids if k.attrs.get("measurement_kind") == "profiles"]
    assert stylus and all(k.height.sizes["y"] >= 4 and k.attrs.get("tip_radius") for k in stylus)  # profile sets
    for k in stylus:  # parallel profiles L/20 apart
        np.testing.assert_allclose(float(k.y[1] - k.y[0]), float(k.x[-1] - k.x[0] + k.x[1] - k.x[0]) / 20, rtol=1e-9)
    assert any(k.height.ndim == 2 and k.attrs.get("tip_radius") for k in kids)  # AFM
    assert any(k.attrs.get("grid") == "nonuniform" for k in kids)
    for k in kids:
        xtopo.validate(k)
    xr.testing.assert_identical(example_twin()["afm-5um"].to_dataset(), tree["afm-5um"].to_dataset())
    # replicates: the same instrument at independent places
    a, b = tree["afm-5um"].to_dataset(), tree["afm-5um-2"].to_dataset()
    assert a.attrs["tip_radius"] == b.attrs["tip_radius"] and a.height.shape == b.height.shape
    assert abs(float(np.corrcoef(a.height.fillna(0).values.ravel(), b.height.fillna(0).values.ravel())[0, 1])) < 0.5


def test_long_modes_carry_the_band_power_of_the_truth():
    """Randomised long-wavelength modes: E[Σ a²/2] = ∫ C_iso d²q/(2π)² over the band (no quadrature bias)."""
    from xtopo.datasets import FractalPSD, _long_modes

    truth = FractalPSD(hurst=0.8, prefactor=1.0, long_cutoff=2e-4)
    q_low, q_split = 1e2, 4 * np.pi / 5e-6
    rng = np.random.default_rng(0)
    power = np.mean([np.sum(np.abs(_long_modes(truth, q_split, q_low, rng)[2]) ** 2) / 2 for _ in range(200)])
    lq = np.linspace(np.log(q_low), np.log(q_split), 20001)
    q = np.exp(lq)
    exact = np.trapezoid(truth.c_native(q) * q * q, lq) / (2 * np.pi)
    np.testing.assert_allclose(power, exact, rtol=0.02)


# ---------------------------------------------------------------- audit: argument checks


def test_fractal_surface_single_point_grid_says_why_it_is_empty():
    with pytest.raises(xtopo.XtopoError, match="more than one point"):
        fractal_surface(1, 1.0, hurst=0.5)
    fractal_surface(np.int64(8), np.float32(1.0), hurst=np.float32(0.5), seed=np.int64(2))  # numpy scalars are fine


def test_measure_everything_missing_and_single_row_patches():
    surf = fractal_surface((32, 32), 1.0, hurst=0.7)
    assert bool(measure(surf, missing_fraction=1.0).mask.all())
    # a 1×N map: patches scale with the long axis, not the single pixel across it
    row = measure(fractal_surface((1, 512), (1 / 512, 1.0), hurst=0.7), missing_fraction=0.5, seed=1)
    m = row.mask.values[0]
    assert 0.45 <= m.mean() <= 0.7
    assert np.count_nonzero(np.diff(m.astype(int)) == 1) < 40  # a few patches, not hundreds of single points


def test_measure_refuses_a_batch_of_surfaces():
    surf = fractal_surface((16, 16), 1.0, hurst=0.7)
    with pytest.raises(xtopo.GridError, match="extra dims"):
        measure(xr.concat([surf, surf], dim="sample"))


@pytest.mark.parametrize("ds", [None, "surface.nc", np.zeros(4)])
def test_prescribed_psd_of_what_is_no_dataset(ds):
    # a bare AttributeError ('NoneType' object has no attribute 'attrs')
    with pytest.raises(xtopo.XtopoError, match="carries no prescribed PSD"):
        prescribed_psd(ds)


@pytest.mark.parametrize("shape", [10**30, (10**30, 4), 2**40, (2**31, 2**31), (2**15, 2**16)])
def test_fractal_surface_refuses_a_shape_beyond_memory(shape):
    """10**30 raised numpy's 'Maximum allowed size exceeded', 2**40 a MemoryError (4 TiB), (2**31, 2**31) was
    killed by the kernel (out of memory)."""
    with pytest.raises(xtopo.GridError, match=r"shape=.* more than the 1073741824"):
        xtopo.datasets.fractal_surface(shape, 1.0, hurst=0.8)


def test_nonperiodic_surface_counts_its_parent_grid():
    """A nonperiodic window is cut from a parent four times as large: its size counts."""
    with pytest.raises(xtopo.GridError, match="twice as large"):
        xtopo.datasets.fractal_surface((2**15, 2**14), 1.0, hurst=0.8, periodic=False)


@pytest.mark.parametrize("pixels", [10**30, (10**30, 4), 2**40])
def test_measure_refuses_pixels_beyond_memory(pixels):
    """pixels=10**30 raised OverflowError 'Python int too large to convert to C long', 2**40 a MemoryError."""
    surface = xtopo.datasets.fractal_surface((16, 16), 1.0, hurst=0.8)
    with pytest.raises(xtopo.GridError, match="pixels=.* more than the"):
        xtopo.datasets.measure(surface, pixels=pixels)


@pytest.mark.parametrize("radius", [1e30, 1e300])
def test_a_huge_tip_records_the_highest_point(radius):
    """tip_radius=1e30 raised numpy's 'zero-size array to reduction operation fmax' (the crop margin overflowed);
    a flat tip rests on the highest point of the surface everywhere."""
    for surface in (xtopo.datasets.fractal_surface((16, 16), 1.0, hurst=0.8, seed=3),
                    xtopo.datasets.fractal_surface(32, 1.0, hurst=0.8, seed=3)):
        out = xtopo.datasets.measure(surface, tip_radius=radius)
        np.testing.assert_allclose(out.height.values, float(surface.height.max()), rtol=1e-12)


def test_large_tip_dilation_is_unchanged_by_the_stable_formula():
    surface = xtopo.datasets.fractal_surface((32, 32), 1.0, hurst=0.8, rms_height=0.01, seed=3)
    out = xtopo.datasets.measure(surface, tip_radius=0.05)
    h, dx = surface.height.values, 1.0 / 32
    expected = h.copy()
    for i in range(-32, 33):
        for j in range(-32, 33):
            r2 = (i * dx) ** 2 + (j * dx) ** 2
            if r2 > 0.05 ** 2:
                continue
            shifted = np.full_like(h, -np.inf)
            shifted[max(0, -i):32 - max(0, i), max(0, -j):32 - max(0, j)] = \
                h[max(0, i):32 - max(0, -i), max(0, j):32 - max(0, -j)]
            expected = np.maximum(expected, shifted - (0.05 - np.sqrt(0.05 ** 2 - r2)))
    np.testing.assert_allclose(out.height.values, expected, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("method", ["c_native", "c_iso", "c1d", "__call__"])
@pytest.mark.parametrize("q", ["abc", {"a": 1}, np.nan, [1.0, np.inf], object()])
def test_fractal_psd_refuses_wavevectors_that_are_no_numbers(method, q):
    """q='abc' raised numpy's 'could not convert string to float', NaN gave NaN."""
    psd = xtopo.datasets.FractalPSD(hurst=0.8, prefactor=1.0, long_cutoff=1e-6)
    with pytest.raises(xtopo.XtopoError, match="q .wavevectors. must be finite real numbers"):
        getattr(psd, method)(q)


def test_fractal_psd_c1d_keeps_the_shape_of_q():
    psd = xtopo.datasets.FractalPSD(hurst=0.8, prefactor=1.0, long_cutoff=1e-6)
    q = np.geomspace(1e5, 1e8, 6)
    np.testing.assert_array_equal(psd.c1d(q.reshape(2, 3)), psd.c1d(q).reshape(2, 3))
