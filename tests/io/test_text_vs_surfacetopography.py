"""Side by side with SurfaceTopography: every text/CSV example of its test suite that it reads, xtopo reads with
the same positions and heights.

SurfaceTopography's example files (``test/file_format_examples`` of its repository) are not shipped with the
installed package; the files here are built with the same layouts (separators, number formats, headers, encodings,
point order, missing values). Real exports of those layouts in the shared data (Gwyddion, DHM, Dektak, HFM and
two-column text) are compared too when present.
"""

import numpy as np
import pytest

import xtopo

st = pytest.importorskip("SurfaceTopography")

_RNG = np.random.default_rng(23)


def _xyz_rows(x_fastest, nan=False):
    z = np.ones((4, 4))
    z[1, 1] = z[2, 1] = 2.0  # ST's xyz-1: heights 2 at x=1, y=1..2
    if nan:
        z[0, 1] = z[1, 2] = np.nan
    pts = [(x, y) for y in range(4) for x in range(4)] if x_fastest else [(x, y) for x in range(4) for y in range(4)]
    return "".join(f"{x} {y} {'NaN' if np.isnan(z[y, x]) else f'{z[y, x]:g}'}\n" for x, y in pts)


def _nonuniform_sci(n, sep="", start=13.381669, lo=1.0, hi=2.0):
    x = start + np.cumsum(_RNG.uniform(lo, hi, n))
    return "".join(f"{a:16.7e}{sep}{b:16.7e}\n" for a, b in zip(x, 17 + _RNG.normal(size=n)))


# (name, content or bytes, xtopo options, SurfaceTopography options): the layouts of ST's examples
LAYOUTS = [
    ("xyz-1.txt", _xyz_rows(False), {"file_units": "um"}, {"unit": "um"}),
    ("xyz-1-different-order.txt", _xyz_rows(True), {"file_units": "um"}, {"unit": "um"}),
    ("xyz-2.txt", _xyz_rows(False, nan=True), {"file_units": "um"}, {"unit": "um"}),
    ("xy-1.txt", _nonuniform_sci(132), {"file_units": "um"}, {"unit": "um"}),
    ("xy-2.txt", "µm µm\n23\n" + _nonuniform_sci(24, sep=","), {}, {"unit": "um"}),
    ("xy-3.txt", "".join(f"{x:g} {int(x == 4.5)}\n" for x in [0, 1, 2, 3, 4, 4.5, 5, 6, 7, 8, 9]),
     {"file_units": "um"}, {"unit": "um"}),
    ("xy-4.txt", "".join(f"{i * 0.0000995713:.6f}\t{0.003581 + 1e-6 * np.sin(i / 50):.6f}\n" for i in range(10001)),
     {"file_units": "um"}, {"unit": "um"}),
    ("xy-5.txt", "0 1\n1 NaN\n2 1\n3 1\n", {"file_units": "um"}, {"unit": "um"}),
    ("xy-6.txt", "0 1\n1 NaN\n2.5 1\n3 1\n", {"file_units": "um"}, {"unit": "um"}),
    ("nonuniform.asc", _nonuniform_sci(134, start=39.2, lo=10, hi=16), {"file_units": "um"}, {"unit": "um"}),
    ("csv-1.csv", "X_(microns),y1\n" + "".join(f"{0.0386 * (i + 1):.4f},{2.1 - 0.02 * i:.5f}\n" for i in range(8)),
     {"file_units": "um"}, {"unit": "um"}),
    ("csv-2.csv", ("index,x in µm,y in µm\r\n" + "".join(
        f"{i},{-99.958333333333 + i / 12:.15g},{-1.42743285743491}\r\n" for i in range(8))).encode("utf-16"),
     {}, {"unit": "um"}),
    ("csv-3.csv", ("x in µm,y in µm\n" + "".join(
        f"{-99.958333333333 + i / 12:.15g},{-1.42743285743491 + i * 1e-3}\n" for i in range(8))).encode("utf-16"),
     {}, {"unit": "um"}),
    ("gwyddion-export-english.txt", "# Channel: My Channel Name\n# Width: 12.34 µm\n# Height: 5678.9 nm\n"
     "# Value units: m\n1 1.5 3\n-2 -3 -6\n0 0 0\n9 9 9", {}, {}),
    ("gwyddion-export-german.txt", "# Kanal: My Channel Name\n# Breite: 12.34 µm\n# Höhe: 5678.9 nm\n"
     "# Value units: m\n1 1.5 3\n-2 -3 -6\n0 0 0\n9 9 9\n", {}, {}),
    ("matrix-5.txt", "".join(("2 " * 10 if i < 5 else "0 " * 10).strip() + "\n" for i in range(10)),
     {"file_units": "um", "physical_size": (2.0, 3.0)}, {"unit": "um", "physical_sizes": (3.0, 2.0)}),
    ("matrix-6.txt", "# Channel: Main\n# Width: 10 µm\n# Height: 10 µm\n# Value units: m\n 1.0  2.0  3.0  4.0\n"
     " 5.0  6.0  7.0  8.0\n 9.0 10.0 11.0 12.0\n\n", {}, {}),
    ("txt_example.txt", "# Channel: Raw\n# Width: 1.0e-6 m\n# Height: 0.5e-6 m\n# Value units: m\n"
     "1.0e-007\t0.0e-007\t0.0e-007\t0.0e-007\t0.0e-007\t0.0e-007\n"
     "0.5e-007\t0.5e-007\t0.0e-008\t0.0e-008\t0.0e-008\t0.0e-008\n"
     "0.0e-007\t0.0e-007\t0.0e-007\t0.0e-007\t0.0e-007\t0.0e-007", {}, {}),
    ("single_column.txt", "\n".join(str(i) for i in range(1, 10)), {"file_units": "um", "physical_size": 3.0},
     {"unit": "um", "physical_sizes": (3.0,)}),
    ("memory-example.txt", "\n            0 0\n            1 2\n            2 4\n            3 6\n            ",
     {"file_units": "um"}, {"unit": "um"}),  # ST's in-memory text example
    ("matrix-2.txt", "h=4 w=5\npixel size=3.69862e-007 m\ndata unit=rad\nheight conversion factor (-> m)=6.30079e-008\n"
     + "".join(" ".join(f"{v:.6f}" for v in row) + "\n" for row in _RNG.normal(size=(4, 5))), {}, {}),
]


def _write(tmp_path, name, content):
    p = tmp_path / name
    if isinstance(content, bytes):
        p.write_bytes(content)
    else:
        p.write_text(content, encoding="utf-8")
    return p


def _printed_precision(path):
    from xtopo.io._text import column_precision, read_text
    from xtopo.io.formats.text import _drop_count_line, _fields, split_header

    _, data, _ = split_header(read_text(path).splitlines())
    data = _drop_count_line(data)
    col = 1 if len(_fields(data[0])) == 3 else 0
    return column_precision(_fields(ln)[col] for ln in data)


def compare(path, xtopo_options, st_options):
    """Read ``path`` with both packages in metres; check grid, positions and heights agree (returns the number of
    heights compared)."""
    ds = xtopo.open_topography(path, units="m", **xtopo_options)
    t = st.read_topography(str(path), **st_options)
    t = t.to_unit("m")
    if t.dim == 1:
        xs, hs = t.positions_and_heights()
        x = ds.x.values - ds.x.values[0]  # ST moves a line scan to start at 0
        if not t.is_uniform and ds.attrs.get("grid") == "nonuniform":  # both keep the positions as printed
            np.testing.assert_allclose(x, xs, rtol=1e-12, atol=1e-12 * abs(xs[-1]))
        else:  # a grid fitted to the printed positions (ST: end points, xtopo: all): they differ by the rounding
            factor = xtopo.conventions.length_factor(ds.attrs.get("original_lateral_units", "m"), "m")
            tol = _printed_precision(path) * factor
            assert tol > 0 and np.max(np.abs(x - xs)) <= tol
        np.testing.assert_allclose(ds.height.values, hs, rtol=1e-12, atol=0)
    else:
        assert ds.height.shape == t.nb_grid_pts[::-1]
        sx, sy = t.physical_sizes
        assert xtopo.conventions.physical_size(ds, "x") == pytest.approx(sx, rel=1e-12)
        assert xtopo.conventions.physical_size(ds, "y") == pytest.approx(sy, rel=1e-12)
        np.testing.assert_allclose(ds.height.values, t.heights().T, rtol=1e-12, atol=0)
    np.testing.assert_array_equal(np.isnan(ds.height.values), np.isnan(t.heights().T if t.dim == 2 else hs))
    return ds.height.size


@pytest.mark.parametrize("name, content, xopts, sopts", LAYOUTS, ids=[lay[0] for lay in LAYOUTS])
def test_surfacetopography_text_example_layouts(tmp_path, name, content, xopts, sopts):
    assert compare(_write(tmp_path, name, content), xopts, sopts) > 1


@pytest.mark.real_data
@pytest.mark.parametrize("name, xopts, sopts", [
    ("matrix-3.txt", {}, {}), ("matrix-4.txt", {}, {}), ("dektak-1.csv", {}, {}), ("hfm-1.hfm", {}, {}),
    ("opdx-3.txt", {"file_units": "m"}, {"unit": "m"})])
def test_surfacetopography_real_text_exports(real_data, name, xopts, sopts):
    assert compare(real_data / name, xopts, sopts) > 1
