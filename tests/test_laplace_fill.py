"""The harmonic fill's solvers (xtopo._kernels.laplace_fill): multigrid-CG agrees with the direct solve."""

import numpy as np
import pytest
import scipy.sparse.linalg

from xtopo._kernels import multigrid
from xtopo._kernels.laplace_fill import DIRECT_MAX, _system, harmonic_fill_2d

#: agreement of the iterative and the direct fill, relative to the height range
TOL = 1e-10


def _holes(kind, shape=(256, 256), seed=0):
    rng = np.random.default_rng(seed)
    h = rng.standard_normal(shape).cumsum(0).cumsum(1) * 1e-3 + 5.0  # rough, with an offset
    y, x = np.mgrid[0:shape[0], 0:shape[1]]
    if kind == "big":  # one contiguous hole over the left border (> DIRECT_MAX) plus small holes
        missing = (x < 150) & (y > 20) | (rng.random(shape) < 0.02)
    else:  # 60 % random pixels: one percolating island and many small ones
        missing = rng.random(shape) < 0.6
    return np.where(missing, np.nan, h), missing


@pytest.mark.parametrize("kind", ["big", "random"])
@pytest.mark.parametrize("periodic", [False, True])
@pytest.mark.parametrize("dy,dx", [(1.0, 1.0), (0.4, 1.3)])
def test_iterative_and_auto_fill_agree_with_direct(kind, periodic, dy, dx):
    h, missing = _holes(kind)
    direct = harmonic_fill_2d(h, periodic, dy, dx, method="direct")
    span = np.ptp(h[~missing])
    for method in ("iterative", "auto"):
        out = harmonic_fill_2d(h, periodic, dy, dx, method=method)
        np.testing.assert_array_equal(out[~missing], h[~missing])
        assert np.max(np.abs(out - direct)) <= TOL * span, method


def test_big_hole_reproduces_a_discrete_harmonic_function():
    # x² - y² + 3xy: its discrete Laplacian vanishes on an isotropic grid (xy's too), so the fill is exact
    y, x = np.mgrid[-130:130, -120:120].astype(float)
    h = x ** 2 - y ** 2 + 3 * x * y + 7
    hole = (y / 110) ** 2 + (x / 105) ** 2 < 1  # away from the (nonperiodic) border
    assert hole.sum() > DIRECT_MAX  # "auto" takes the iterative path
    for method in ("auto", "iterative"):
        out = harmonic_fill_2d(np.where(hole, np.nan, h), method=method)
        np.testing.assert_allclose(out, h, rtol=0, atol=TOL * np.ptp(h))


@pytest.mark.parametrize("periodic", [False, True])
@pytest.mark.parametrize("shape", [(1, 3000), (3000, 1)])
def test_iterative_fill_on_degenerate_maps(shape, periodic):
    line = np.sin(np.linspace(0, 7, max(shape)))
    line[100:2500] = np.nan
    h = line.reshape(shape)
    direct = harmonic_fill_2d(h, periodic, 0.5, 2.0, method="direct")
    out = harmonic_fill_2d(h, periodic, 0.5, 2.0, method="iterative")
    assert np.max(np.abs(out - direct)) <= TOL * 2


@pytest.mark.parametrize("dy", [0.1, 10.0])
def test_multigrid_cg_converges_on_strongly_anisotropic_grids(dy):
    h = np.random.default_rng(1).random((200, 200))
    h[:, :120] = np.nan
    missing = ~np.isfinite(h)
    unknown, iy, ix, A, rhs = _system(h, missing, False, 1 / dy ** 2, 1.0)
    M = multigrid.SmoothedAggregation(A, iy, ix, anisotropy=1 / dy ** 2)
    steps = []
    x, info = scipy.sparse.linalg.cg(A, rhs, rtol=1e-12, maxiter=1000, M=M, callback=steps.append)
    assert info == 0 and len(steps) < 60


@pytest.mark.parametrize("method", ["direct", "iterative", "auto"])
@pytest.mark.parametrize("view", ["transposed", "flipped"])
def test_fill_of_a_non_contiguous_map(method, view):
    """A map that is a transposed or flipped view (as readers return them) gets filled too.

    The filled values used to be written through ``ravel()``, which copies for such a view:
    the holes stayed NaN, silently.
    """
    h, missing = _holes("random", shape=(40, 30))
    src = h.T if view == "transposed" else h[::-1]
    assert not src.flags.c_contiguous
    out = harmonic_fill_2d(src, False, 1.0, 1.0, method=method)
    assert np.isfinite(out).all()
    np.testing.assert_array_equal(out, harmonic_fill_2d(np.ascontiguousarray(src), False, 1.0, 1.0,
                                                        method=method))
