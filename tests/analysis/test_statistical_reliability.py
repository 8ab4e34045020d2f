"""Long-scale (statistical) reliability: predicted relative error of ACF and SDRP estimates."""

import dask.array as dsa
import numpy as np
import pytest

import xtopo

from xtopo._kernels.estimator_error import mean_square_relative_error, variogram_from_samples
from xtopo.analysis.acf import acf
from xtopo.analysis.statistical_reliability import stencil_error
from xtopo.analysis.sdrp import sdrp
from xtopo.datasets import fractal_surface


def _power_law(hurst):
    return lambda r: np.abs(np.asarray(r, dtype=float)) ** (2 * hurst)


def _brute_force(gamma, n, k, rows=1, dy=1.0):
    """Direct double sum of the variance of the mean squared difference (no quadrature)."""
    m = n - k
    s = np.arange(-(m - 1), m, dtype=float)
    total = 0.0
    for j in range(-(rows - 1), rows):
        def g(a):
            return gamma(np.hypot(a, j * dy))
        cov = g(s + k) + g(s - k) - 2 * g(s)
        total += (rows - abs(j)) * np.sum((m - np.abs(s)) * cov**2)
    return np.sqrt(total / (2 * m**2 * rows**2)) / gamma(k)


@pytest.mark.parametrize("n,rows,dy", [(300, 1, 1.0), (3000, 1, 1.0), (200, 40, 3.0)])
def test_quadrature_matches_the_direct_sum(n, rows, dy):
    gamma = _power_law(0.8)
    ks = np.array([1.0, 5.0, 30.0, 90.0])
    fast = mean_square_relative_error(gamma, ks, offsets=[0, 1], weights=[-1, 1], n=n, dx=1.0, rows=rows,
                                      row_spacing=dy)
    exact = [_brute_force(gamma, n, int(k), rows, dy) for k in ks]
    np.testing.assert_allclose(fast, exact, rtol=2e-3)


def _loop_over_lengths(gamma, lengths, *, offsets, weights, n, dx, rows=1, row_spacing=0.0):
    """The kernel as first written: one length, and all pairs (i, j), at a time."""
    from xtopo._kernels.estimator_error import _quadrature

    a, w = np.asarray(offsets, dtype=float), np.asarray(weights, dtype=float)
    pair_a, pair_w = (a[:, None] - a[None, :]).ravel(), (w[:, None] * w[None, :]).ravel()
    j_nodes, j_weights = _quadrature(rows, 16)
    out = np.full(len(lengths), np.nan)
    for i, ell in enumerate(lengths):
        span = (a.max() - a.min()) * ell
        m = int(np.floor(n - span / dx + 1e-9))
        s_nodes, s_weights = _quadrature(m, int(min(m, max(64, 8 * np.ceil(span / dx)))))
        lag = s_nodes[None, :, None] * dx + ell * pair_a[None, None, :]
        cov = -np.sum(pair_w * gamma(np.hypot(lag, j_nodes[:, None, None] * row_spacing)), axis=-1)
        mult_s = s_weights * (m - s_nodes) * np.where(s_nodes > 0, 2.0, 1.0)
        mult_j = j_weights * (rows - j_nodes) * np.where(j_nodes > 0, 2.0, 1.0)
        var = 2.0 * np.sum(mult_j[:, None] * mult_s[None, :] * cov**2) / (m * rows) ** 2
        out[i] = np.sqrt(var) / -np.sum(pair_w * gamma(ell * np.abs(pair_a)))
    return out


@pytest.mark.parametrize("stencil", [([0, 1], [-1, 1]), ([-0.5, 0, 0.5], [1, -2, 1])])
@pytest.mark.parametrize("n,rows", [(4000, 1), (600, 8), (256, 256)])
def test_kernel_equals_the_loop_over_lengths_and_pairs(stencil, n, rows):
    """Shared evaluations of γ and their order of summation leave the numbers as they were (≤ 1e-12)."""
    dx = 0.3
    lags = np.arange(1, n // 4 + 1) * dx
    gamma = variogram_from_samples(lags ** 1.6 * (1 + 0.1 * np.sin(lags)), lags)
    lengths = np.geomspace(dx, n * dx / 2, 25)
    kw = dict(offsets=stencil[0], weights=stencil[1], n=n, dx=dx, rows=rows, row_spacing=2 * dx)
    np.testing.assert_allclose(mean_square_relative_error(gamma, lengths, **kw),
                               _loop_over_lengths(gamma, lengths, **kw), rtol=1e-12)


def test_single_difference_is_chi_square_with_one_degree_of_freedom():
    err = mean_square_relative_error(_power_law(0.5), [3.0], offsets=[0, 1], weights=[-1, 1], n=4, dx=1.0)
    np.testing.assert_allclose(err, np.sqrt(2))


@pytest.mark.parametrize("hurst,exponent", [(0.8, 2 - 2 * 0.8), (0.5, 0.5)])
def test_error_scales_like_the_self_affine_prediction(hurst, exponent):
    """Relative error ∝ (ℓ/L)^(2-2H) for H > 3/4 (long wavelengths dominate), (ℓ/L)^(1/2) below."""
    ks = np.array([4.0, 64.0])
    err = mean_square_relative_error(_power_law(hurst), ks, offsets=[0, 1], weights=[-1, 1], n=200000, dx=1.0)
    slope = np.log(err[1] / err[0]) / np.log(ks[1] / ks[0])
    assert slope == pytest.approx(exponent, abs=0.06)


@pytest.mark.parametrize("hurst", [0.8, 0.5])
@pytest.mark.parametrize("shape,window", [((8192,), (512,)), ((512, 512), (32, 128))])
def test_predicted_error_matches_scatter_over_realisations(hurst, shape, window):
    """Windows of a larger surface (all wavelengths up to the roll-off): observed scatter of A(ℓ) and of the
    slope over 40 realisations vs the median prediction from each window's own ACF, within a factor 1.5."""
    ells = np.array([1.0, 4.0, 16.0, 64.0])
    values, slopes, predicted, predicted_slope = [], [], [], []
    for seed in range(40):
        surf = fractal_surface(shape, float(shape[-1]), hurst=hurst, prefactor=1.0, long_cutoff=shape[-1] / 4,
                               seed=seed)
        win = surf.isel({d: slice(0, w) for d, w in zip(("y", "x")[-len(window):], window)})
        win.attrs["periodic"] = 0
        values.append(acf(win, reliable=False).sel(distance=ells).values)
        slopes.append(sdrp(win, distances=ells, reliable=False).values)
        predicted.append(stencil_error(win, ells).values)
        predicted_slope.append(stencil_error(win, ells, quantity="slope").values)
    for obs, pred in ((np.array(values), predicted), (np.array(slopes), predicted_slope)):
        scatter = obs.std(0) / obs.mean(0)
        ratio = np.median(pred, axis=0) / scatter
        assert np.all((ratio > 1 / 1.5) & (ratio < 1.5)), ratio


def test_stencil_error_is_lazy_on_dask():
    surf = fractal_surface((64, 256), (64.0, 256.0), hurst=0.7, periodic=False, seed=1)
    lazy = stencil_error(surf.chunk(), [2.0, 8.0], quantity="curvature")
    assert isinstance(lazy.data, dsa.Array)
    np.testing.assert_allclose(lazy.compute().values, stencil_error(surf, [2.0, 8.0], quantity="curvature").values)
    assert lazy.attrs["units"] == "1" and lazy["distance"].attrs["units"] == surf["x"].attrs["units"]


@pytest.mark.parametrize("kw,match", [({"dim": "z"}, "dim='z' is not a lateral dimension"),
                                      ({"fraction": 10**30}, "fraction must be a share"),  # was used as 1
                                      ({"fraction": 2.5}, "fraction must be a share"),
                                      ({"dim": np.array(["x", "y"])}, "is not a lateral dimension")])
def test_stencil_error_refuses_bad_dim_and_fraction(kw, match):
    surf = fractal_surface(128, 128.0, hurst=0.7, periodic=False, seed=1)
    with pytest.raises(xtopo.XtopoError, match=match):
        stencil_error(surf, [2.0, 8.0], **kw)


@pytest.mark.parametrize("kw,match", [({"dim": "y"}, "dim='y' is not a lateral dimension"),
                                      ({"dim": None}, "dim=None is not a lateral dimension"),
                                      ({"dim": ["x"]}, "is not a lateral dimension")])
def test_sampling_cutoff_refuses_bad_factor_and_dim(kw, match):
    # factor was used unchecked (a negative or NaN cutoff wavelength, a bare ValueError for "4"),
    # dim a bare KeyError/TypeError
    from xtopo.analysis.statistical_reliability import sampling_cutoff

    surf = fractal_surface(128, 128.0, hurst=0.7, periodic=False, seed=1)
    assert sampling_cutoff(surf, factor=4) == pytest.approx(4.0)
    with pytest.raises(xtopo.XtopoError, match=match):
        sampling_cutoff(surf, **kw)
