"""Readers for AFM/SPM instrument files (issue 4a): NanoScope, IBW, MI, NID, Park TIFF,
JPK, WSxM, Nanonis SXM and Gwyddion GWY, checked on the real files in ../shared/data/real.

Expected values are derived here from the file layouts (header fields read with a few
lines of independent parsing, raw integers with numpy) or from values the files' own
headers state; none is copied from another program's output.
"""

from __future__ import annotations

import re
import shutil
import struct
import warnings

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.errors import ReaderError, UnitsError, UnsupportedFormatError, XtopoError
from xtopo.io import open_topography
from xtopo.io.registry import detect, formats

pytestmark = pytest.mark.real_data


def _bytes(real_data, name):
    return (real_data / name).read_bytes()


def _header_text(data: bytes, end: bytes) -> str:
    return data[:data.index(end)].decode("latin-1")


def _field(text: str, pattern: str, group: int = 1) -> str:
    m = re.search(pattern, text, re.MULTILINE)
    assert m, f"pattern {pattern!r} not found in the header"
    return m.group(group)


def _check_grid(ds, shape, size, units):
    assert ds.height.shape == shape
    assert ds.x.attrs["units"] == units and ds.y.attrs["units"] == units
    assert ds.height.attrs["units"] == units
    ny, nx = shape
    assert float(ds.x.attrs["spacing"]) * nx == pytest.approx(size[1], rel=1e-9)
    assert float(ds.y.attrs["spacing"]) * ny == pytest.approx(size[0], rel=1e-9)


# --------------------------------------------------------------------------- NanoScope

def _nanoscope_expected(data: bytes, image: int, sens_key: str):
    """Heights (nm) of image section ``image``: raw / 2^(8 bpp) * Z scale hard value [V] * sensitivity [nm/V]."""
    text = _header_text(data, b"\\*File list end")
    sections = text.split("\\*Ciao image list")[1:]
    sec = sections[image]
    offset = int(_field(sec, r"\\Data offset: (\d+)"))
    bpp = int(_field(sec, r"\\Bytes/pixel: (\d+)"))
    nx = int(_field(sec, r"\\Samps/line: (\d+)"))
    ny = int(_field(sec, r"\\Number of lines: (\d+)"))
    hard = float(_field(sec, r"\\@2:Z scale: V \[[^\]]*\] \([^)]*\) ([-\d.eE+]+) V"))
    sens = float(_field(text, r"\\@" + re.escape(sens_key) + r": V ([-\d.eE+]+) nm/V"))
    raw = np.frombuffer(data, dtype="<i2" if bpp == 2 else "<i4", count=nx * ny, offset=offset)
    return raw.reshape(ny, nx) / 2.0 ** (8 * bpp) * hard * sens


@pytest.mark.parametrize("name, shape, size, units, image, sens, nm_per_unit", [
    ("di-1.di", (512, 512), (500.0, 500.0), "nm", 0, "Sens. Zsens", 1.0),
    ("di-3.di", (256, 256), (10.0, 10.0), "um", 0, "Sens. ZsensSens", 1e3),
    ("di-5.di", (512, 512), (1.0, 1.0), "um", 0, "Sens. ZsensSens", 1e3),
    ("old_bruker.002", (256, 256), (15.0, 15.0), "um", 0, "Sens. Zscan", 1e3),
])
def test_nanoscope(real_data, name, shape, size, units, image, sens, nm_per_unit):
    ds = open_topography(real_data / name, units=None)
    _check_grid(ds, shape, size, units)
    expected = _nanoscope_expected(_bytes(real_data, name), image, sens) / nm_per_unit
    np.testing.assert_allclose(ds.height.values, expected, rtol=1e-12, atol=0)
    assert ds.attrs["vendor"].startswith("Bruker")
    assert ds.attrs["source_format"] == "nanoscope"
    # plausible magnitudes: rms heights of a few nm to a few hundred nm on these scans
    rms_nm = float(ds.height.std()) * nm_per_unit
    assert 1.0 < rms_nm < 500.0


def test_nanoscope_metadata_and_channels(real_data):
    ds = open_topography(real_data / "di-1.di")
    assert ds.attrs["instrument"] == "Dimension V"
    assert ds.attrs["acquisition_time"] == "2016-01-12T09:57:48"
    assert ds.height.attrs["units"] == "m"
    chans = formats()["nanoscope"].channels(str(real_data / "di-1.di"))
    assert [c.name for c in chans] == ["Height", "Height (retrace)", "Phase", "Amplitude Error"]
    assert [c.height_units for c in chans] == ["nm", "nm", "deg", "mV"]
    assert [c.is_height for c in chans] == [True, True, False, False]
    # di-3: the default channel is the first height channel, the tip radius (nm) comes from the header
    ds3 = open_topography(real_data / "di-3.di", units="nm")
    assert ds3.attrs["channel_id"] == "ZSensor"
    assert ds3.attrs["tip_radius"] == pytest.approx(9.5) and ds3.attrs["tip_radius_units"] == "nm"
    # a channel picked by name, the retrace height, has its own scale (329.995 V full range)
    retrace = open_topography(real_data / "di-3.di", channel="Height (retrace)", units="nm")
    expected = _nanoscope_expected(_bytes(real_data, "di-3.di"), 3, "Sens. Zsens")
    np.testing.assert_allclose(retrace.height.values, expected, rtol=1e-12)


def test_nanoscope_phase_channel_keeps_its_unit(real_data):
    fmt = formats()["nanoscope"]
    ds = fmt.read(str(real_data / "di-1.di"), channel="Phase")
    assert ds.height.attrs["units"] == "deg" and ds.height.attrs["quantity"] == "signal"
    # Z scale 359.9945 º over the int16 range, sensitivity 1 (no unit)
    raw = np.frombuffer(_bytes(real_data, "di-1.di"), "<i2", 512 * 512, 1089536)
    assert float(ds.height.mean()) == pytest.approx(raw.mean() / 65536 * 359.9945, rel=1e-9)
    # a phase map is not a topography: open_topography refuses it, naming the file and the unit
    with pytest.raises(UnsupportedFormatError, match=r"di-1\.di.*'deg'"):
        open_topography(real_data / "di-1.di", channel="Phase")


# --------------------------------------------------------------------------- IBW

def _ibw(data: bytes):
    hdr = struct.unpack_from("<hhiiii4i4iiii", data, 0)
    npnts, typ = struct.unpack_from("<ih", data, 64 + 12)
    ndim = struct.unpack_from("<4i", data, 64 + 68)
    sfa = struct.unpack_from("<4d", data, 64 + 84)
    note = data[64 + hdr[2] + hdr[3]:64 + hdr[2] + hdr[3] + hdr[4]].decode("latin-1")
    assert typ == 2  # float32 in both files
    values = np.frombuffer(data, "<f4", npnts, 384)
    return ndim, sfa, note, values


def test_ibw_asylum(real_data):
    data = _bytes(real_data, "spot_1-1000nm.ibw")
    ndim, sfa, note, values = _ibw(data)
    ds = open_topography(real_data / "spot_1-1000nm.ibw", units=None)
    _check_grid(ds, (256, 256), (256 * sfa[1], 256 * sfa[0]), "m")
    # the note's ScanSize spans the pixel centres: spacing = ScanSize / (N - 1)
    scan = float(_field(note, r"^ScanSize: ([-\d.eE+]+)"))
    assert float(ds.x.attrs["spacing"]) == pytest.approx(scan / 255, rel=1e-9)
    first = values[:256 * 256].reshape(256, 256)  # layer 0, x fastest
    np.testing.assert_allclose(ds.height.values, first, rtol=1e-7)
    assert ds.attrs["channel"] == "HeightTrace"
    assert ds.attrs["instrument"] == "Cypher"
    assert ds.attrs["acquisition_time"] == "2019-10-24T12:14:13"
    assert 1e-9 < float(ds.height.std()) < 1e-6
    chans = formats()["ibw"].channels(str(real_data / "spot_1-1000nm.ibw"))
    assert len(chans) == 8 and chans[4].name == "PhaseTrace" and chans[4].height_units == "deg"


def test_ibw_tiny_without_name(real_data):
    data = _bytes(real_data, "10x10-one_channel_without_name.ibw")
    ndim, sfa, note, values = _ibw(data)
    with pytest.warns(xtopo.MetadataWarning, match=r"10x10-one_channel_without_name\.ibw.*file_units="):
        ds = open_topography(real_data / "10x10-one_channel_without_name.ibw", units=None)
    _check_grid(ds, (10, 10), (10 * sfa[1], 10 * sfa[0]), "m")
    assert "units_assumed" in ds.attrs
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the caller said what the wave is in: no warning
        um = open_topography(real_data / "10x10-one_channel_without_name.ibw", units=None, file_units="um")
    _check_grid(um, (10, 10), (10 * sfa[1], 10 * sfa[0]), "um")
    assert "units_assumed" not in um.attrs
    np.testing.assert_array_equal(um.height.values, ds.height.values)
    with pytest.raises(xtopo.ReaderError, match="states its length unit"):
        open_topography(real_data / "spot_1-1000nm.ibw", file_units="um")
    assert float(ds.height.mean()) == pytest.approx(float(values.mean()), rel=1e-7)
    (info,) = formats()["ibw"].channels(str(real_data / "10x10-one_channel_without_name.ibw"))
    assert info.name  # named after the wave when the channel has no label


# --------------------------------------------------------------------------- MI

def test_mi(real_data):
    data = _bytes(real_data, "mi-1.mi")
    start = data.index(b"data          BINARY_32\n") + len(b"data          BINARY_32\n")
    text = data[:start].decode("latin-1")
    rng = float(_field(text, r"^bufferRange\s+([-\d.eE+]+)"))  # first buffer: Topography, in um
    assert _field(text, r"^bufferUnit\s+(\S+)") == "um"
    lx = float(_field(text, r"^xLength\s+([-\d.eE+]+)"))
    ds = open_topography(real_data / "mi-1.mi", units=None)
    _check_grid(ds, (256, 256), (lx, lx), "m")
    raw = np.frombuffer(data, "<i4", 256 * 256, start).reshape(256, 256)
    np.testing.assert_allclose(ds.height.values, raw / 2.0 ** 31 * rng * 1e-6, rtol=1e-12)
    assert ds.attrs["acquisition_time"] == "2014-02-18T15:00:51"
    chans = formats()["mi"].channels(str(real_data / "mi-1.mi"))
    assert [c.name for c in chans] == ["Topography", "Deflection", "Friction", "Friction (retrace)"]
    assert [c.height_units for c in chans] == ["um", "V", "V", "V"]


# --------------------------------------------------------------------------- NID

def test_nid(real_data):
    data = _bytes(real_data, "nid-1.nid")
    start = data.index(b"#!") + 2
    text = data[:start].decode("utf-8", errors="replace")
    sec = text[text.index("[DataSet-0:1]"):]
    vmin = float(_field(sec, r"^Dim2Min=(\S+)"))
    vrange = float(_field(sec, r"^Dim2Range=(\S+)"))
    size = float(_field(sec, r"^Dim0Range=(\S+)"))
    ds = open_topography(real_data / "nid-1.nid", units=None)
    assert ds.attrs["channel"] == "Z-Axis (Scan forward)"  # the first height channel
    _check_grid(ds, (256, 256), (size, size), "m")
    # second block (Gr0-Ch1); signed int32 spans [Dim2Min, Dim2Min + Dim2Range]
    raw = np.frombuffer(data, "<i4", 256 * 256, start + 256 * 256 * 4).reshape(256, 256)
    expected = vmin + (raw.astype(float) + 2.0 ** 31) / 2.0 ** 32 * vrange
    np.testing.assert_allclose(ds.height.values, expected, rtol=1e-12)
    chans = formats()["nid"].channels(str(real_data / "nid-1.nid"))
    assert len(chans) == 8 and chans[0].height_units == "N"


# --------------------------------------------------------------------------- TIFF based

def _tiff_tags(data: bytes, ifd_index: int = 0):
    e = "<" if data[:2] == b"II" else ">"
    off = struct.unpack_from(e + "I", data, 4)[0]
    for _ in range(ifd_index):
        n = struct.unpack_from(e + "H", data, off)[0]
        off = struct.unpack_from(e + "I", data, off + 2 + 12 * n)[0]
    n = struct.unpack_from(e + "H", data, off)[0]
    tags = {}
    for i in range(n):
        tag, typ, count, val = struct.unpack_from(e + "HHI4s", data, off + 2 + 12 * i)
        size = {1: 1, 2: 1, 3: 2, 4: 4, 7: 1, 8: 2, 9: 4, 11: 4, 12: 8}.get(typ, 1) * count
        pos = off + 2 + 12 * i + 8 if size <= 4 else struct.unpack(e + "I", val)[0]
        if typ == 12 and count == 1:
            tags[tag] = struct.unpack_from(e + "d", data, pos)[0]
        elif typ in (4, 9) and count == 1:
            tags[tag] = struct.unpack_from(e + ("I" if typ == 4 else "i"), data, pos)[0]
        elif typ == 2:
            tags[tag] = data[pos:pos + count].split(b"\0")[0].decode("latin-1")
        else:
            tags[tag] = (pos, size)
    return tags


def test_park_tiff(real_data):
    data = _bytes(real_data, "example_ps.tiff")
    tags = _tiff_tags(data)
    assert tags[50432] == 0x0E031301
    hpos, _ = tags[50435]
    dpos, dsize = tags[50434]
    nx, ny = struct.unpack_from("<ii", data, hpos + 100)
    lx, ly = struct.unpack_from("<dd", data, hpos + 140)  # um
    gain, zscale, zoff = struct.unpack_from("<ddd", data, hpos + 220)
    zunit = data[hpos + 244:hpos + 260].decode("utf-16-le").split("\0")[0]
    assert zunit == "um" and dsize == nx * ny * 4
    ds = open_topography(real_data / "example_ps.tiff", units=None)
    _check_grid(ds, (ny, nx), (ly, lx), "um")
    raw = np.frombuffer(data, "<f4", nx * ny, dpos).reshape(ny, nx).astype(float)
    np.testing.assert_allclose(ds.height.values, gain * ((zscale or 1.0) * raw + zoff), rtol=1e-12)
    assert 1e-4 < float(ds.height.std()) < 0.1  # um: nm-scale roughness on a 1 um scan
    assert ds.attrs["channel"] == "Z Height" and ds.attrs["acquisition_time"] == "2022-10-15T17:07:06"


def test_jpk_qi(real_data):
    data = _bytes(real_data, "sample_0.jpk-qi-image")
    glob = _tiff_tags(data, 0)
    nx, ny, lx, ly = glob[32838], glob[32839], glob[32834], glob[32835]
    chans = formats()["jpk"].channels(str(real_data / "sample_0.jpk-qi-image"))
    names = [c.name for c in chans]
    assert {"Height", "Slope", "Adhesion", "Vertical Deflection", "Height (measured)"} <= set(names)
    k = names.index("Height")
    ds = open_topography(real_data / "sample_0.jpk-qi-image", channel="Height", units=None)
    _check_grid(ds, (ny, nx), (ly, lx), "m")
    tags = _tiff_tags(data, k + 1)  # directory 0 is the preview
    assert tags[32897] == "calibrated"
    # slots raw, volts, nominal, calibrated: the 4th at 0x8090 + 3 * 0x30 (name, unit, multiplier, offset)
    base = 0x8090 + 3 * 0x30
    assert tags[base] == "calibrated" and tags[base + 0x12] == "m"
    mult, off = tags[base + 0x14], tags[base + 0x15]
    strip0 = tags[273][0] if isinstance(tags[273], tuple) else tags[273]
    first = struct.unpack_from(">I", data, strip0)[0]  # strips are contiguous in this file
    raw = np.frombuffer(data, ">i4", nx * ny, first).reshape(ny, nx)
    np.testing.assert_allclose(ds.height.values, raw * mult + off, rtol=1e-12)
    # the calibrated height multiplier is the nominal one times the head calibration 0.776076
    text = data.decode("latin-1")
    cal = float(_field(text, r"height\.conversion\.calibrated\.scaling\.multiplier : (\S+)"))
    assert tags[0x8090 + 2 * 0x30] == "nominal"
    nominal = tags[0x8090 + 2 * 0x30 + 0x14]
    assert mult == pytest.approx(cal * nominal, rel=1e-6)
    assert ds.attrs["instrument"].startswith("JPK00733")


# --------------------------------------------------------------------------- WSxM

@pytest.mark.parametrize("name", ["top-1.top", "stp-1.stp"])
def test_wsxm(real_data, name):
    data = _bytes(real_data, name)
    text = _header_text(data, b"[Header end]")
    start = int(_field(text, r"Image header size: (\d+)"))
    zamp = float(_field(text, r"Z Amplitude: ([-\d.eE+]+) nm"))
    ds = open_topography(real_data / name, units=None)
    _check_grid(ds, (256, 256), (600.0, 600.0), "nm")
    # the header's Z Amplitude is the height range of the image
    assert float(ds.height.max() - ds.height.min()) == pytest.approx(zamp, rel=1e-5)
    if name.endswith(".top"):
        raw = np.frombuffer(data, "<i2", 256 * 256, start).astype(float)
        vmax, vmin = (float(_field(text, rf"^\s*{k}: ([-\d.eE+]+)")) for k in ("Maximum", "Minimum"))
        expected = raw * zamp / (vmax - vmin)
    else:
        expected = np.frombuffer(data, "<f8", 256 * 256, start)
    assert float(ds.height.std()) == pytest.approx(float(expected.std()), rel=1e-12)


# --------------------------------------------------------------------------- Nanonis

def test_sxm(real_data):
    data = _bytes(real_data, "A151216.123306-02602.sxm")
    text = _header_text(data, b":SCANIT_END:")
    z_ctrl = float(_field(text, r":Z-Controller>Z \(m\):\s*\n\s*(\S+)"))
    lx, ly = (float(v) for v in _field(text, r":SCAN_RANGE:\s*\n\s*(.+)").split())
    ds = open_topography(real_data / "A151216.123306-02602.sxm", units=None)
    _check_grid(ds, (128, 128), (ly, lx), "m")
    # constant-height scan (Z controller OFF): the Z map is the controller's Z position
    np.testing.assert_allclose(ds.height.values, z_ctrl, rtol=1e-5)
    assert ds.attrs["acquisition_time"] == "2015-12-16T11:39:44"
    # phase (forward) is the 7th image (Z f/b, Input_4 f/b, Current f/b, Phase f): big-endian float32
    start = data.index(b"\x1a\x04", data.index(b":SCANIT_END:")) + 2
    phase = np.frombuffer(data, ">f4", 128 * 128, start + 6 * 128 * 128 * 4)
    ph = formats()["sxm"].read(str(real_data / "A151216.123306-02602.sxm"), channel="Phase (forward)")
    assert ph.height.attrs["units"] == "deg"
    assert float(ph.height.mean()) == pytest.approx(float(phase.mean()), rel=1e-6)
    chans = formats()["sxm"].channels(str(real_data / "A151216.123306-02602.sxm"))
    assert chans[4].name == "Current (forward)" and chans[4].height_units == "A"


# --------------------------------------------------------------------------- GWY

def _gwy_field(data: bytes, key: bytes):
    """xres, yres, xreal, yreal and the data of the GwyDataField stored under ``key``."""
    pos = data.index(key + b"\0o")
    out = {}
    for name, fmt in ((b"xres", "<i"), (b"yres", "<i"), (b"xreal", "<d"), (b"yreal", "<d")):
        p = data.index(name + b"\0" + (b"i" if fmt == "<i" else b"d"), pos) + len(name) + 2
        out[name.decode()] = struct.unpack_from(fmt, data, p)[0]
    p = data.index(b"data\0D", pos) + 6
    n = struct.unpack_from("<I", data, p)[0]
    out["data"] = np.frombuffer(data, "<f8", n, p + 4)
    return out


@pytest.mark.parametrize("name, key, units", [("test.gwy", b"/0/data", "m"),
                                              ("file_landscape.gwy", b"/3/data", "m")])
def test_gwy(real_data, name, key, units):
    f = _gwy_field(_bytes(real_data, name), key)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        ds = open_topography(real_data / name, units=None)
    assert any(issubclass(w.category, xtopo.MetadataWarning) for w in caught) == ("units_assumed" in ds.attrs)
    _check_grid(ds, (f["yres"], f["xres"]), (f["yreal"], f["xreal"]), units)
    np.testing.assert_array_equal(ds.height.values.ravel(), f["data"])
    if name == "file_landscape.gwy":
        assert ds.attrs["channel"] == "Left_Top_Right_Bottom"
        assert f["xres"] == 220 and f["yres"] == 170 and "units_assumed" not in ds.attrs
    else:
        assert "units_assumed" in ds.attrs


# --------------------------------------------------------------------------- detection and errors

MY_FILES = ["di-1.di", "di-3.di", "di-5.di", "old_bruker.002", "spot_1-1000nm.ibw",
            "10x10-one_channel_without_name.ibw", "mi-1.mi", "nid-1.nid", "example_ps.tiff",
            "sample_0.jpk-qi-image", "stp-1.stp", "top-1.top", "A151216.123306-02602.sxm",
            "test.gwy", "file_landscape.gwy"]
EXPECTED_FORMAT = {".di": "nanoscope", ".002": "nanoscope", ".ibw": "ibw", ".mi": "mi", ".nid": "nid",
                   ".tiff": "park_tiff", ".jpk-qi-image": "jpk", ".stp": "wsxm", ".top": "wsxm",
                   ".sxm": "sxm", ".gwy": "gwy"}


def _fmt_for(name):
    return next(v for k, v in EXPECTED_FORMAT.items() if name.endswith(k))


@pytest.mark.parametrize("name", MY_FILES)
def test_detection_by_content_with_wrong_suffix(real_data, tmp_path, name):
    target = tmp_path / "renamed.dat"
    shutil.copyfile(real_data / name, target)
    assert detect(str(target))[0].name == _fmt_for(name)
    ds = open_topography(target)
    assert ds.height.attrs["units"] == "m" and ds.attrs["source_format"] == _fmt_for(name)
    chans = formats()[_fmt_for(name)].channels(str(target))
    assert chans and all(c.shape == chans[0].shape for c in chans)
    assert any(c.is_height for c in chans)


def test_unknown_channel_names_the_choices(real_data):
    with pytest.raises(UnsupportedFormatError, match="Height"):
        open_topography(real_data / "di-1.di", channel="no such channel")
    with pytest.raises(UnsupportedFormatError, match="out of range"):
        open_topography(real_data / "mi-1.mi", channel=17)


def test_units_conversion_keeps_values(real_data):
    nm = open_topography(real_data / "top-1.top", units=None)
    m = open_topography(real_data / "top-1.top")
    np.testing.assert_allclose(m.height.values * 1e9, nm.height.values, rtol=1e-12)
    np.testing.assert_allclose(m.x.values * 1e9, nm.x.values, rtol=1e-12)
    assert m.x.attrs["units"] == "m" and nm.x.attrs["units"] == "nm"


# --------------------------------------------------------------------------- hostile input (smoke)

def check_hostile_read(path, payload: bytes, tmp_path, tag):
    bad = tmp_path / f"{tag}{path.suffix}"
    bad.write_bytes(payload)
    try:
        ds = open_topography(bad)
        assert isinstance(ds, xr.Dataset)
    except XtopoError as exc:
        assert bad.name in str(exc), f"error does not name the file: {exc!r}"


@pytest.mark.parametrize("name", MY_FILES)
def test_hostile_input_smoke(real_data, tmp_path, name):
    path = real_data / name
    data = path.read_bytes()
    rng = np.random.default_rng(sum(map(ord, name)))
    check_hostile_read(path, b"", tmp_path, "empty")
    # truncations: inside the header and inside the data
    for k, cut in enumerate(sorted(set(np.linspace(1, len(data) - 1, 10).astype(int).tolist()))):
        check_hostile_read(path, data[:cut], tmp_path, f"trunc{k}")
    # random byte corruptions, biased to the header where the size fields are
    head = min(len(data), 8192)
    for k in range(20):
        buf = bytearray(data)
        for pos in rng.integers(0, head, size=rng.integers(1, 8)):
            buf[pos] = rng.integers(0, 256)
        check_hostile_read(path, bytes(buf), tmp_path, f"corrupt{k}")


def test_hostile_size_fields(real_data, tmp_path):
    """Huge size fields are refused before allocating."""
    data = _bytes(real_data, "di-1.di").replace(b"\\Samps/line: 512", b"\\Samps/line: 9999999999")
    bad = tmp_path / "huge.di"
    bad.write_bytes(data)
    with pytest.raises(ReaderError, match="huge.di"):
        open_topography(bad)
    gwy = bytearray(_bytes(real_data, "test.gwy"))
    p = gwy.index(b"data\0D") + 6
    gwy[p:p + 4] = struct.pack("<I", 0xFFFFFFF0)
    bad = tmp_path / "huge.gwy"
    bad.write_bytes(bytes(gwy))
    with pytest.raises(ReaderError, match="huge.gwy"):
        open_topography(bad)


def test_units_error_is_xtopo_error():
    assert issubclass(UnitsError, XtopoError)
