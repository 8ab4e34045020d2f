"""Formats checked against files built from their published layout (no real sample committed)."""

import numpy as np
import pytest

import xtopo
from xtopo.conventions import spacing


def _bcrf(path, z, xlength, ylength, unicode=True):
    ny, nx = z.shape
    head = (f"fileformat = bcrf{'_unicode' if unicode else ''}\nheadersize = 2048\nxpixels = {nx}\nypixels = {ny}\n"
            f"xlength = {xlength}\nylength = {ylength}\nxunit = nm\nyunit = nm\nzunit = nm\nintelmode = 1\n")
    head = head.ljust(2048)
    path.write_bytes(head.encode("utf-16-le" if unicode else "latin-1") + z.astype("<f4").tobytes())


@pytest.mark.parametrize("unicode", [True, False])
def test_bcrf_length_is_the_scan_range_of_n_minus_1_steps(tmp_path, unicode):
    z = np.arange(5 * 8, dtype=float).reshape(5, 8)
    p = tmp_path / "a.bcrf"
    _bcrf(p, z, xlength=7 * 2.5, ylength=4 * 3.0, unicode=unicode)  # steps 2.5 nm and 3 nm
    ds = xtopo.open_topography(p, units="nm")
    assert spacing(ds, "x") == pytest.approx(2.5) and spacing(ds, "y") == pytest.approx(3.0)
    np.testing.assert_array_equal(ds.height.values, z)


def test_bcrf_size_differs_from_surfacetopography_by_n_over_n_minus_1(tmp_path):
    st = pytest.importorskip("SurfaceTopography")
    z = np.random.default_rng(0).normal(size=(6, 10))
    p = tmp_path / "b.bcrf"
    _bcrf(p, z, xlength=900.0, ylength=500.0)
    ds = xtopo.open_topography(p, units="nm")
    t = st.read_topography(str(p))
    sx, sy = t.to_unit("nm").physical_sizes
    assert (sx, sy) == pytest.approx((900.0, 500.0))  # SurfaceTopography: size = xlength
    assert spacing(ds, "x") * 10 == pytest.approx(sx * 10 / 9)  # xtopo: xlength spans 9 steps of 10 pixels
    np.testing.assert_allclose(ds.height.values, t.to_unit("nm").heights().T, rtol=1e-6)
