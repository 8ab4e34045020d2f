"""Text-format readers on the real files: expected values come from each file's own header/text."""

import re

import numpy as np
import pytest

import xtopo
from xtopo.io.registry import detect

pytestmark = pytest.mark.real_data


def _lines(path, encoding="utf-8"):
    return path.read_text(encoding=encoding).splitlines()


def test_gwyddion_matrix_3(real_data):
    path = real_data / "matrix-3.txt"
    assert detect(path)[0].name == "gwyddion-text"
    lines = _lines(path)
    # header: "# Width: 10.00 µm", "# Height: 10.00 µm", "# Value units: m"
    assert lines[1] == "# Width: 10.00 µm" and lines[2] == "# Height: 10.00 µm" and lines[3] == "# Value units: m"
    rows = [ln.split() for ln in lines[4:] if ln.strip()]
    ds = xtopo.open_topography(path)
    assert ds.height.dims == ("y", "x")
    assert ds.height.shape == (len(rows), len(rows[0])) == (256, 256)
    assert ds.x.attrs["units"] == ds.y.attrs["units"] == ds.height.attrs["units"] == "m"
    assert xtopo.conventions.physical_size(ds, "x") == pytest.approx(10.00e-6)
    assert xtopo.conventions.physical_size(ds, "y") == pytest.approx(10.00e-6)
    assert ds.attrs["channel"] == "ZSensor"
    # values are in m (Value units), row i of the file is y index i
    assert float(ds.height[0, 0]) == pytest.approx(float(rows[0][0]))
    assert float(ds.height[-1, -1]) == pytest.approx(float(rows[-1][-1]))
    assert float(ds.height.mean()) == pytest.approx(np.mean([float(t) for r in rows for t in r]), rel=1e-12)
    assert ds.height.attrs["units"] == "m"


def test_dhm_matrix_4(real_data):
    path = real_data / "matrix-4.txt"
    assert detect(path)[0].name == "dhm-text"
    lines = _lines(path)
    assert lines[0] == "h=305 w=75" and lines[1] == "pixel size=3.69862e-007 m"
    assert lines[2] == "data unit=rad" and lines[3] == "height conversion factor (-> m)=2.91818e-008"
    ds = xtopo.open_topography(path)
    assert ds.height.shape == (305, 75)  # h rows (y) × w columns (x)
    assert xtopo.conventions.spacing(ds, "x") == pytest.approx(3.69862e-7)
    assert xtopo.conventions.physical_size(ds, "y") == pytest.approx(305 * 3.69862e-7)
    assert xtopo.conventions.physical_size(ds, "x") == pytest.approx(75 * 3.69862e-7)
    assert ds.height.attrs["units"] == "m"
    first = [float(t) for t in lines[4].split()]
    np.testing.assert_allclose(ds.height[0].values, np.array(first) * 2.91818e-8, rtol=1e-12)
    assert float(ds.height.max()) == pytest.approx(
        max(float(t) for ln in lines[4:] for t in ln.split()) * 2.91818e-8)


def test_dektak_csv(real_data):
    path = real_data / "dektak-1.csv"
    assert detect(path)[0].name == "dektak-csv"
    lines = _lines(path, "latin-1")
    assert "Length,1500.0 um" in lines and "Resolution,0.156 um/sample" in lines
    assert "Stylus,Radius: 2.5 µm" in lines
    start = lines.index("Lateral um,Raw Micrometer,")
    data = [ln.split(",")[:2] for ln in lines[start + 1:] if ln.strip()]
    ds = xtopo.open_topography(path, units="um")
    assert ds.height.dims == ("x",) and ds.height.shape == (len(data),)
    assert "grid" not in ds.attrs  # positions printed to 0.1 um lie on a uniform grid
    assert ds.height.attrs["units"] == ds.x.attrs["units"] == "um"
    assert xtopo.conventions.physical_size(ds) == pytest.approx(1500.0, rel=1e-4)
    assert xtopo.conventions.spacing(ds) == pytest.approx(0.156, abs=5e-4)
    assert ds.attrs["tip_radius"] == pytest.approx(2.5) and ds.attrs["tip_radius_units"] == "um"
    assert float(ds.height[0]) == pytest.approx(float(data[0][1]))
    # "Analytical Results": Ra 0.00525 um, Rq 0.01143 um between the cursors at 468 um and 733 um
    # (Dektak levels the profile with a straight line)
    x, h = ds.x.values, ds.height.values
    sel = (x >= 468.0) & (x <= 733.0)
    resid = h[sel] - np.polyval(np.polyfit(x[sel], h[sel], 1), x[sel])
    assert np.sqrt(np.mean(resid ** 2)) == pytest.approx(0.01143, abs=2e-5)
    assert np.mean(np.abs(resid)) == pytest.approx(0.00525, abs=2e-5)


def test_hfm(real_data):
    path = real_data / "hfm-1.hfm"
    assert detect(path)[0].name == "hfm"
    lines = _lines(path)
    assert lines[:2] == ["X;Y;valid", "[mm];[mm];[1/0]"]
    rows = [ln.split(";") for ln in lines[2:] if ln.strip()]
    n_invalid = sum(r[2] == "0" for r in rows)
    ds = xtopo.open_topography(path, units="mm")
    assert ds.height.shape == (len(rows),) == (9600,)
    assert ds.height.attrs["units"] == "mm"
    assert xtopo.conventions.spacing(ds) == pytest.approx(float(rows[1][0]) - float(rows[0][0]))
    assert xtopo.conventions.physical_size(ds) == pytest.approx(4.8, rel=1e-9)
    n_masked = int(ds.mask.sum()) if "mask" in ds else 0
    assert n_masked == n_invalid
    assert float(ds.height[0]) == pytest.approx(float(rows[0][1]))
    valid = [float(r[1]) for r in rows if r[2] == "1"]
    assert float(ds.topo.height.mean()) == pytest.approx(np.mean(valid), rel=1e-12)


def test_two_column_text_opdx_3(real_data):
    path = real_data / "opdx-3.txt"
    assert detect(path)[0].name == "text"
    rows = [ln.split() for ln in _lines(path) if ln.strip()]
    with pytest.raises(xtopo.errors.ReaderError, match="file_units"):
        xtopo.open_topography(path)  # the file states no unit
    ds = xtopo.open_topography(path, file_units="m")
    assert ds.height.shape == (len(rows),) == (3001,)
    assert "grid" not in ds.attrs
    assert xtopo.conventions.spacing(ds) == pytest.approx(float(rows[1][0]), rel=1e-7)
    assert xtopo.conventions.physical_size(ds) == pytest.approx(3001 * float(rows[1][0]), rel=1e-7)
    assert ds.height.attrs["units"] == "m"
    assert float(ds.height[0]) == pytest.approx(float(rows[0][1]))
    assert float(ds.height.std()) == pytest.approx(np.std([float(r[1]) for r in rows]), rel=1e-12)


def test_sdf_ascii(real_data):
    path = real_data / "sdf-1.sdf"
    assert detect(path)[0].name == "sdf"
    text = path.read_text()
    hdr = dict(re.findall(r"^(\w+) = (\S+)$", text, re.M))
    assert hdr["NumPoints"] == "7" and hdr["NumProfiles"] == "4" and hdr["Xscale"] == "1.0E-6"
    ds = xtopo.open_topography(path)
    assert ds.height.shape == (4, 7)  # NumProfiles (y) × NumPoints (x)
    assert xtopo.conventions.physical_size(ds, "x") == pytest.approx(7e-6)
    assert xtopo.conventions.physical_size(ds, "y") == pytest.approx(4e-6)
    assert ds.height.attrs["units"] == "m"
    values = np.array(text.split("*")[1].split(), dtype=float).reshape(4, 7)
    np.testing.assert_allclose(ds.height.values, values * 1e-6, rtol=1e-12)  # Zscale = 1.0E-6 m
    assert ds.attrs["sdf_manufacid"] == "ISOTC213"


def test_channels_single_entry(real_data):
    for name in ("matrix-3.txt", "matrix-4.txt", "dektak-1.csv", "hfm-1.hfm", "sdf-1.sdf"):
        (info,) = xtopo.io.channels(real_data / name)
        ds = xtopo.open_topography(real_data / name, units=None)
        assert info.shape == ds.height.shape
        assert info.units == ds.height.attrs["units"]
        for channel in (0.0, False, 1):  # 0.0 and False were taken as 0 by the dektak, hfm and sdf readers
            with pytest.raises(xtopo.UnsupportedFormatError, match=re.escape(f"channel {channel!r} does not exist")):
                xtopo.open_topography(real_data / name, channel=channel)


def test_corrupt_first_data_row_is_an_error_not_a_header(real_data, tmp_path):
    """A non-number in the first row of matrix-3.txt made the row a header line: 255 of 256 rows
    were read without a word."""
    lines = _lines(real_data / "matrix-3.txt")
    row = lines[4].split("\t")
    row[3] = "abc"
    lines[4] = "\t".join(row)
    path = tmp_path / "matrix-3.txt"
    path.write_text("\n".join(lines), encoding="utf-8")
    with pytest.raises(xtopo.ReaderError, match=r"matrix-3.txt: .*first data row.*'abc'"):
        xtopo.open_topography(path)
    plain = tmp_path / "plain.txt"  # the same without the Gwyddion header
    plain.write_text("x y z\n1 foo 3\n4 5 6\n7 8 9\n", encoding="utf-8")
    with pytest.raises(xtopo.ReaderError, match="plain.txt: .*'foo'"):
        xtopo.open_topography(plain, file_units="m", physical_size=(1, 1))


def test_truncated_dektak_csv_is_an_error(real_data, tmp_path):
    """dektak-1.csv cut in half was read as a 5006-point profile (Length,1500.0 um in its header)."""
    raw = (real_data / "dektak-1.csv").read_bytes()
    path = tmp_path / "dektak-1.csv"
    path.write_bytes(raw[:len(raw) // 2])
    with pytest.raises(xtopo.ReaderError, match=r"dektak-1.csv: .*1500 um scan length.*truncated"):
        xtopo.open_topography(path)
