"""Text layouts that were read wrong or refused: uneven line scans, x y z grids, localized Gwyddion
exports, UTF-16 CSV, unit lines."""

import numpy as np
import pytest

import xtopo
from xtopo.conventions import physical_size, spacing
from xtopo.errors import ReaderError
from xtopo.io._text import uniform_spacing
from xtopo.io.registry import detect


def _open(path, **kw):
    kw.setdefault("units", None)
    return xtopo.open_topography(path, **kw)


def test_line_scan_with_one_missing_sample_is_nonuniform(tmp_path):
    # regression: x = 0.0 … 4.9, 5.1 … 9.9 was read as 99 equally spaced points (x moved by up to 0.74 step)
    x = np.delete(np.round(np.arange(100) * 0.1, 1), 50)
    p = tmp_path / "gap.txt"
    p.write_text("".join(f"{a:.1f} {np.sin(a):.6f}\n" for a in x))
    ds = _open(p, file_units="um")
    assert ds.attrs["grid"] == "nonuniform"
    np.testing.assert_array_equal(ds.x.values, x)
    np.testing.assert_allclose(ds.height.values, np.round(np.sin(x), 6))


@pytest.mark.parametrize("columns", ["x h", "index x h"])
def test_line_scan_of_positions_keeps_its_channel_and_refuses_a_size(tmp_path, columns):
    # regression: the x h reader dropped the header's channel (the other layouts kept it)
    p = tmp_path / "profile.txt"
    rows = [f"{i} {0.5 * i:.1f} {i * i}" if columns == "index x h" else f"{0.5 * i:.1f} {i * i}" for i in range(6)]
    p.write_text("# Channel: Profile A\n" + "\n".join(rows) + "\n")
    ds = _open(p, file_units="um")
    assert ds.attrs["channel"] == "Profile A"
    assert ds.height.dims == ("x",) and spacing(ds, "x") == pytest.approx(0.5)
    np.testing.assert_array_equal(ds.height.values, [0, 1, 4, 9, 16, 25])
    with pytest.raises(ReaderError, match="do not pass physical_size"):
        _open(p, file_units="um", physical_size=3.0)


@pytest.mark.parametrize("where", [1, 7, 50, 97])
def test_a_missing_sample_anywhere_is_found(where):
    x = np.delete(np.round(np.arange(100) * 0.1, 1), where)
    assert uniform_spacing(x, 0.1) is None
    assert uniform_spacing(np.round(np.arange(100) * 0.1, 1), 0.1) == pytest.approx(0.1)


def test_uniform_within_printed_precision_uses_every_token(tmp_path):
    # one position printed with more digits than the others: the coarsest precision decides
    x = np.arange(300) * 0.15625
    rows = [f"{a:.1f},{np.cos(a):.5f}" for a in x]
    rows[3] = f"{x[3]:.4f},{np.cos(x[3]):.5f}"
    p = tmp_path / "xy.csv"
    p.write_text("\n".join(rows))
    ds = _open(p, file_units="um")
    assert "grid" not in ds.attrs
    assert spacing(ds) == pytest.approx(0.15625, rel=1e-3)


def test_positions_too_coarse_to_tell_a_grid_stay_as_printed():
    # steps of 0.15 printed to 0.1 move a position by a third of a step: still a grid;
    # steps of 0.12 printed to 0.1 move it by 0.42 of a step: too coarse, read as printed
    assert uniform_spacing(np.round(np.arange(50) * 0.15, 1), 0.1) is not None
    assert uniform_spacing(np.round(np.arange(50) * 0.12, 1), 0.1) is None


def test_drifting_positions_are_nonuniform():
    x = np.arange(200) * 1.0 + 1e-4 * np.arange(200) ** 2  # printed to 1e-6: a slow chirp is no rounding
    assert uniform_spacing(np.round(x, 6), 1e-6) is None


def _xyz(tmp_path, name, x_fastest, header="", nan=None):
    xs, ys = np.arange(5) * 0.5, np.arange(3) * 0.25
    z = np.add.outer(10 * ys, xs)  # (ny, nx)
    if nan is not None:
        z[nan] = np.nan
    rows = [(x, y, z[j, i]) for j, y in enumerate(ys) for i, x in enumerate(xs)] if x_fastest else \
        [(x, y, z[j, i]) for i, x in enumerate(xs) for j, y in enumerate(ys)]
    p = tmp_path / name
    p.write_text(header + "".join(f"{a:g} {b:g} {c:g}\n" for a, b, c in rows))
    return p, z


@pytest.mark.parametrize("x_fastest", [True, False])
def test_xyz_grid_in_either_order(tmp_path, x_fastest):
    p, z = _xyz(tmp_path, "g.xyz", x_fastest)
    ds = _open(p, file_units="mm")
    assert ds.height.dims == ("y", "x") and ds.height.shape == (3, 5)
    np.testing.assert_array_equal(ds.height.values, z)
    assert physical_size(ds, "x") == pytest.approx(5 * 0.5) and physical_size(ds, "y") == pytest.approx(3 * 0.25)
    assert ds.height.attrs["units"] == "mm"
    with pytest.raises(ReaderError, match="do not pass physical_size"):
        _open(p, file_units="mm", physical_size=(1.0, 1.0))


def test_xyz_grid_with_unit_line_and_missing_point(tmp_path):
    p, z = _xyz(tmp_path, "g.txt", True, header="µm µm nm\n", nan=(1, 2))
    ds = _open(p)
    assert ds.height.attrs["units"] == "um"
    np.testing.assert_allclose(ds.height.values, z * 1e-3)
    assert bool(ds.mask[1, 2]) and int(ds.mask.sum()) == 1


def test_scattered_xyz_points_are_refused(tmp_path):
    rng = np.random.default_rng(0)
    p = tmp_path / "s.xyz"
    np.savetxt(p, rng.uniform(size=(40, 3)))
    with pytest.raises(ReaderError, match="scattered points"):
        _open(p, file_units="um")
    # a grid with a point missing is no grid either
    q, _ = _xyz(tmp_path, "g.xyz", True)
    q.write_text("".join(q.read_text().splitlines(keepends=True)[:-1]))
    with pytest.raises(ReaderError, match="complete grid"):
        _open(q, file_units="um")


def test_xyz_grid_with_uneven_axis_is_refused(tmp_path):
    p = tmp_path / "u.xyz"
    p.write_text("".join(f"{x:.1f} {y:.1f} 1\n" for y in (0, 1, 2) for x in (0, 1, 3)))
    with pytest.raises(ReaderError, match="not equally spaced"):
        _open(p, file_units="um")


_GWY = {"en": ("Channel", "Width", "Height", "Value units"), "de": ("Kanal", "Breite", "Höhe", "Value units"),
        "fr": ("Canal ", "Largeur ", "Hauteur ", "Unités "), "cs": ("Kanál", "Šířka", "Výška", "Jednotky hodnot"),
        "ja": ("チャネル", "幅", "高さ", "値の単位"),
        "xx": ("Chan", "W", "H", "Units")}  # an unknown translation: recognised by the lines' place and form


@pytest.mark.parametrize("lang", sorted(_GWY))
def test_gwyddion_export_in_any_language(tmp_path, lang):
    c, w, h, v = _GWY[lang]
    p = tmp_path / f"gwy-{lang}.txt"
    colon = "：" if lang == "ja" else ":"
    p.write_text(f"# {c}{colon} My Channel\n# {w}{colon} 12.34 µm\n# {h}{colon} 5678.9 nm\n# {v}{colon} m\n"
                 "1 1.5 3\n-2 -3 -6\n0 0 0\n9 9 9\n", encoding="utf-8")
    assert detect(p)[0].name == "gwyddion-text"
    ds = _open(p, units="m")
    assert ds.height.shape == (4, 3)
    assert physical_size(ds, "x") == pytest.approx(12.34e-6) and physical_size(ds, "y") == pytest.approx(5.6789e-6)
    np.testing.assert_array_equal(ds.height.values[1], [-2, -3, -6])
    assert ds.attrs["channel"] == "My Channel"


@pytest.mark.parametrize("encoding", ["utf-16", "utf-16-be"])
def test_utf16_csv_with_titled_columns(tmp_path, encoding):
    x = -99.958333 + np.arange(8) / 12
    text = "index,x in µm,y in µm\r\n" + "".join(f"{i},{a:.13g},{-1.42743285743491}\r\n" for i, a in enumerate(x))
    p = tmp_path / "c.csv"
    p.write_bytes((b"\xfe\xff" if encoding.endswith("be") else b"") + text.encode(encoding))
    ds = _open(p)
    assert ds.height.dims == ("x",) and ds.height.shape == (8,)
    assert ds.height.attrs["units"] == "um"
    assert spacing(ds) == pytest.approx(1 / 12)
    np.testing.assert_allclose(ds.height.values, -1.42743285743491)


def test_two_columns_with_unit_line_and_count_line(tmp_path):
    x = np.cumsum(np.random.default_rng(3).uniform(1, 2, 24)) + 13
    p = tmp_path / "xy.txt"
    p.write_text("µm µm\n23\n" + "".join(f"{a:16.7e},{np.sin(a):16.7e}\n" for a in x), encoding="utf-8")
    ds = _open(p)
    assert ds.height.attrs["units"] == "um" and ds.attrs["grid"] == "nonuniform"
    np.testing.assert_allclose(ds.x.values, x, rtol=1e-7)
    with pytest.raises(ReaderError, match="do not pass file_units"):
        _open(p, file_units="nm")
