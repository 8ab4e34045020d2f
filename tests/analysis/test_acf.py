import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.datasets import fractal_surface

from ..conftest import batch


def _direct_1d(h, periodic):
    n = h.shape[-1]
    kmax = n // 2 + 1 if periodic else n
    out = []
    for k in range(kmax):
        if periodic:
            d = np.roll(h, -k, axis=-1) - h
        else:
            d = h[..., k:] - h[..., : n - k]
        out.append(np.mean(d**2) / 2)
    return np.array(out)


def _direct_map(h):
    ny, nx = h.shape
    out = np.zeros((ny, 2 * nx - 1))
    for i in range(ny):
        for jj, j in enumerate(range(-(nx - 1), nx)):
            a = h[: ny - i, max(0, -j): nx - max(0, j)]
            b = h[i:, max(0, j): nx - max(0, -j)]
            out[i, jj] = np.mean((a - b) ** 2) / 2
    return out


@pytest.mark.parametrize("periodic,rtol", [(True, 1e-10), (False, 1e-8)])
def test_wiener_khinchin_direct_equals_fft(periodic, rtol):
    ds = fractal_surface((24, 40), (0.3, 0.5), hurst=0.6, periodic=periodic, seed=2)
    a = ds.topo.acf("1d")
    np.testing.assert_allclose(a.values[1:], _direct_1d(ds.height.values, periodic)[1:], rtol=rtol)
    assert a.attrs["units"] == "m2" and a.distance.attrs["units"] == "m"


def test_map_direct_equals_fft_nonperiodic():
    from xtopo._kernels.correlation import acf_map

    h = fractal_surface((12, 17), (1.0, 1.0), hurst=0.6, periodic=False, seed=4).height.values
    np.testing.assert_allclose(acf_map(h, periodic=False)[1:], _direct_map(h)[1:], rtol=1e-8)


def test_acf_psd_wiener_khinchin_periodic():
    """A(ℓ) = Rq² - Σ_q C1D(q) cos(qℓ) Δq/2π (two-sided sum), the theorem itself."""
    ds = fractal_surface((32, 64), (1.0, 2.0), hurst=0.7, periodic=True, seed=1)
    c = ds.topo.psd("1d", window=None)
    a = ds.topo.acf("1d")
    n, length = 64, 2.0
    mult = np.full(c.sizes["q"], 2.0)
    mult[0] = mult[-1] = 1.0
    rq2 = float((c * mult).sum()) / length
    expected = rq2 - (mult * c.values * np.cos(np.outer(a.distance.values, c.q.values))).sum(-1) / length
    np.testing.assert_allclose(a.values, expected, rtol=1e-10, atol=1e-14 * rq2)


def test_saturates_at_sq2_for_uncorrelated():
    h = np.random.default_rng(0).standard_normal((256, 256))
    ds = xtopo.make_measurement(h - h.mean(), size=(1.0, 1.0), periodic=True)
    sq2 = float(ds.topo.scalars().Sq) ** 2
    a = ds.topo.acf("iso")
    np.testing.assert_allclose(a.values, sq2, rtol=0.02)
    a1 = ds.topo.acf("1d")
    np.testing.assert_allclose(a1.values[1:].mean(), sq2, rtol=0.01)


def test_iso_nonperiodic_and_batch_lazy():
    ds = fractal_surface((32, 48), (1.0, 1.5), hurst=0.6, periodic=False, seed=3)
    for kind in ("1d", "iso"):
        lazy = batch(ds, 2, dask=True).topo.acf(kind, nb_points=12)
        assert lazy.chunks is not None
        xr.testing.assert_allclose(lazy.compute(), batch(ds, 2).topo.acf(kind, nb_points=12), rtol=1e-12)


def test_nonuniform_line():
    rng = np.random.default_rng(1)
    x = np.cumsum(rng.uniform(0.5, 1.5, 300))
    ds = xtopo.make_measurement(rng.standard_normal(300).cumsum(), x=x)
    a = ds.topo.acf()
    assert "resampled" in a.attrs and np.all(a.values[1:] > 0)


@pytest.mark.parametrize("analysis", ["acf", "psd"])
@pytest.mark.parametrize("kind", ["1d", "iso"])
def test_nb_points_far_beyond_the_data_refused(analysis, kind):
    """nb_points=10**9 allocated gigabytes of empty bins (MemoryError or the OOM killer); sparse bins are fine up
    to MAX_SPARSE_BINS."""
    from xtopo._checks import MAX_SPARSE_BINS

    ds = fractal_surface((16, 16), 1.0, hurst=0.6, seed=3)
    run = getattr(ds.topo, analysis)
    with pytest.raises(xtopo.XtopoError, match=r"nb_points must be at most 10000 here \(\d+ values to bin"):
        run(kind, nb_points=10**9)
    sparse = run(kind, nb_points=MAX_SPARSE_BINS)     # more bins than values: the empty ones are dropped
    assert 0 < sparse.size <= 16 * 16 and np.all(np.isfinite(sparse.values))


@pytest.mark.parametrize("kw,match", [({"dim": np.array([])}, "is not a lateral dimension")])
def test_acf_bad_options_refused(kw, match):
    # arrays raised numpy's 'truth value of an array is ambiguous'
    ds = fractal_surface((16, 16), 1.0, hurst=0.7, seed=1)
    with pytest.raises(xtopo.XtopoError, match=match):
        ds.topo.acf(**kw)
