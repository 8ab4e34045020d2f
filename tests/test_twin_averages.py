"""Issue 21: twin averages as in the paper (§4.9-4.10) — every reliable point of every measurement, equal
weight, no hole where measurements overlap in scale, the statistical uncertainty returned — on the example
twin (against its ground truth) and on a real AFM + optical + stylus twin."""

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.datasets import example_twin, prescribed_psd
from xtopo.stitching import ANALYSES


def _contiguous(avg):
    """Each measurement's averaged values cover its whole range (first to last finite point) without a hole,
    and the average has a value at every collocation point inside any measurement's range."""
    coord = avg.average.dims[0]
    covered = np.zeros(avg.sizes[coord], bool)
    for m in avg.measurement.values:
        ok = avg.curves.sel(measurement=m).notnull().values
        if ok.any():
            i, j = np.flatnonzero(ok)[[0, -1]]
            assert ok[i:j + 1].all(), f"{m}: holes inside its reliable range"
            covered[i:j + 1] = True
    np.testing.assert_array_equal(avg["count"].values > 0, covered)
    return covered


def _truth(tree, name):
    truth = prescribed_psd(tree)
    return {"psd": truth.c1d, "acf": truth.acf}[name]


def _check_example(tree, seed):
    averages = {name: a(tree).compute() for name, a in ANALYSES.items()}
    for name, avg in averages.items():
        covered = _contiguous(avg)
        coord = avg.average.dims[0]
        x = avg[coord].values[covered]
        decades = np.log10(x.max() / x.min())
        assert decades >= 5.5, (seed, name, decades)
        # nothing deleted by default but the lowest wavevector of each windowed spectrum (flag 1, with its reason)
        assert set(np.unique(avg["left_out"].values)) <= ({0, 1} if name == "psd" else {0}), (seed, name)
        # every measurement contributes (the 0.5 mm stylus campaign overlaps the others everywhere: still in)
        assert bool(avg.curves.notnull().any(coord).all()), (seed, name)
        assert (avg.uncertainty.values[covered] >= 0).all(), (seed, name)  # known wherever averaged
    psd = averages["psd"]
    ok = psd["count"].values > 0
    dev = psd.average.values[ok] / _truth(tree, "psd")(psd.q.values[ok]) - 1
    # the deviations are what the predicted standard error says: 90 % of points within 2 sigma
    z = np.abs(dev) / psd.relative_error.values[ok]
    assert np.mean(z <= 2) >= 0.9 and z.max() <= 3, (seed, np.sort(z)[-5:])
    assert np.median(np.abs(dev)) <= 0.10, (seed, np.median(np.abs(dev)))
    acf = averages["acf"]
    ok = acf["count"].values > 0
    dev_acf = acf.average.values[ok] / _truth(tree, "acf")(acf.distance.values[ok]) - 1
    assert np.median(np.abs(dev_acf)) <= 0.10 and np.abs(dev_acf).max() <= 0.5, seed
    return np.median(np.abs(dev)), np.abs(dev).max()


@pytest.fixture(scope="module")
def tree():
    return example_twin(0)


def test_example_twin_averages_are_continuous_and_follow_the_truth(tree):
    """example_twin(seed=7) had 31 of 71 PSD points over 4.3 decades with 13 holes and the stylus range gone;
    the ACF zig-zagged between two measurements. The Hann window's main lobe then biased the longest
    wavelengths of every AFM size upwards (+100 % at 2.5 µm on seed 0); prewhitened: median 5.4 %, max 43 %."""
    median, largest = _check_example(tree, 0)
    assert median <= 0.10 and largest <= 0.5


def test_prewhitening_removes_the_window_bias_at_the_longest_wavelengths(tree):
    """C1D ∝ q^-2.6 smoothed by the Hann window's main lobe: at k = 2 the windowed heights' spectrum of the
    nine AFM scans is about twice the truth, the prewhitened one (windowed slopes / |D̃x|²) within 25 %;
    from k = 8 on both agree (a flat slope spectrum changes nothing there)."""
    from xtopo.analysis.psd import psd
    from xtopo.stitching import _complete

    truth = prescribed_psd(tree)
    plain, white = [], []
    for name in [n for n in tree.children if n.startswith("afm")]:
        ds = _complete(tree[name].to_dataset(), name)
        for out, kw in ((plain, {}), (white, {"prewhiten": True})):
            c = psd(ds, kind="1d", reliable=False, **kw)
            out.append(c.values[1:40] / truth.c1d(c.q.values[1:40]))
    plain, white = np.mean(plain, axis=0), np.mean(white, axis=0)
    assert plain[1] > 1.5 and abs(white[1] - 1) < 0.25, (plain[:4], white[:4])
    np.testing.assert_allclose(white[7:], plain[7:], rtol=0.1)


def test_prewhitening_ignores_a_tilt():
    """The slopes of a tilted profile differ by a constant, which the centring removes: its prewhitened spectrum
    is the untilted one's, while the windowed heights' spectrum picks the tilt up at the longest wavelengths."""
    from xtopo.analysis.psd import psd

    s = xtopo.datasets.fractal_surface((16, 256), (1e-6, 1.6e-5), hurst=0.8, rms_height=1e-8, seed=3,
                                       periodic=False)
    tilted = s.assign(height=s.height + 1e-3 * s.x)
    for kw, same in (({"prewhiten": True}, True), ({}, False)):
        a, b = psd(s, **kw).values, psd(tilted, **kw).values
        assert np.allclose(a, b, rtol=1e-6, atol=1e-9 * a.max()) == same, kw
    lazy = psd(xr.concat([s, tilted], dim="sample").chunk({"sample": 1}), prewhiten=True)  # a batch, lazily
    assert lazy.chunks is not None
    np.testing.assert_allclose(lazy.values, [psd(s, prewhiten=True).values] * 2, rtol=1e-6)
    with pytest.raises(xtopo.XtopoError, match="prewhiten"):
        psd(s, kind="iso", prewhiten=True)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, 2, 7])
def test_other_seeds_are_continuous_and_within_their_uncertainty(seed):
    """Median deviation 6.3 / 8.4 / 8.1 %. A single point may still be off by more than 50 % where few
    independent modes enter (seed 2: +69 % at λ = 1.6 mm, two 5 mm stylus campaigns, predicted error 56 %):
    random, within 3 predicted standard errors everywhere."""
    _check_example(example_twin(seed), seed)


def test_sdrp_order_is_the_same_in_registry_output_and_report():
    """The NetCDF output (analyze_twin) held the slope, the report the curvature: both are ANALYSES['sdrp']."""
    from xtopo.stitching import analyze_twin

    s = xtopo.datasets.fractal_surface((32, 32), 1e-5, hurst=0.8, rms_height=1e-7, seed=1, periodic=False)
    out = analyze_twin(xtopo.twin({"a": s}), per_decade=5)
    assert ANALYSES["sdrp"].kwargs == {"order": 2}
    assert out["sdrp"].average.attrs["units"] == "m-1"     # a curvature
    assert "order=2" in out["sdrp"].attrs["history"]
    assert "source_file" not in out["psd"].attrs            # a twin average is no single measurement's file


@pytest.fixture(scope="module")
def real_twin(real_data):
    """di-3.di (AFM), plu-1.plu (optical), dektak-1.csv (stylus profile), detrended as a user would."""
    from xtopo.preprocess import detrend

    files = {"di-3": ("di-3.di", "plane"), "plu-1": ("plu-1.plu", "plane"), "dektak-1": ("dektak-1.csv", "curvature")}
    missing = [f for f, _ in files.values() if not (real_data / f).is_file()]
    if missing:
        pytest.skip(f"real files {missing} not present")
    return xtopo.twin({k: detrend(xtopo.open_topography(real_data / f), mode) for k, (f, mode) in files.items()})


@pytest.mark.parametrize("name", list(ANALYSES))
def test_real_three_instrument_twin_has_no_gap(real_twin, name):
    """The stylus profile added 0 points to the PSD average and the AFM 4: every measurement contributes
    over its whole reliable range, and the average has no gap inside the union of their ranges."""
    avg = ANALYSES[name](real_twin).compute()
    covered = _contiguous(avg)
    coord = avg.average.dims[0]
    per = avg.curves.notnull().sum(coord)
    assert bool((per >= 5).all()), per.values
    x = avg[coord].values[covered]
    assert np.log10(x.max() / x.min()) >= 3.5
    assert set(avg.reliability_criterion.values) <= {"tip_radius", "resolution", "sampling", "none"}
