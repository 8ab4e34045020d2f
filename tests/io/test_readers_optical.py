"""Readers for optical-profiler / areal formats (issue 4b), one test per real file.

Every expected value is derived in the test from the file's own bytes following
the documented layout (header fields, raw data and scale factors), never copied
from another program's output.
"""

from __future__ import annotations

import re
import struct
import zipfile

import numpy as np
import pytest

import xtopo
from xtopo.errors import XtopoError
from xtopo.io.registry import detect, formats

pytestmark = pytest.mark.real_data


def _open(real_data, name, **kw):
    return xtopo.open_topography(real_data / name, units=None, **kw)


def _check_grid(ds, shape, spacing, units):
    assert ds.height.shape == shape
    assert ds.height.attrs["units"] == units
    for dim in ("x", "y")[:len(shape)]:
        assert ds[dim].attrs["units"] == units
    sp = (spacing,) if len(shape) == 1 else spacing
    dims = ("x",) if len(shape) == 1 else ("y", "x")
    for dim, n, d in zip(dims, shape, sp):
        np.testing.assert_allclose(xtopo.conventions.physical_size(ds, dim), n * d, rtol=1e-9)


def _masked(ds):
    return int(ds["mask"].sum()) if "mask" in ds else 0


def test_detects_by_content_not_suffix(real_data, tmp_path):
    for name, fmt in [("opd-1.opd", "opd"), ("sur-3.sur", "sur"), ("metropro-1.dat", "metropro"),
                      ("frt-2.frt", "frt"), ("x3p-2.x3p", "x3p"), ("mnt-1.mnt", "mnt")]:
        alias = tmp_path / f"renamed_{fmt}.bin"
        alias.write_bytes((real_data / name).read_bytes())
        assert detect(alias)[0].name == fmt


def test_opd(real_data):
    raw = (real_data / "opd-1.opd").read_bytes()
    # directory entries: name[16] type:int16 length:int32 attr:uint16, after a 2-byte prelude
    dirlen = struct.unpack_from("<l", raw, 20)[0]
    pos, blocks = 2 + dirlen, {}
    for i in range(1, dirlen // 24):
        name, typ, length, _ = struct.unpack_from("<16shlH", raw, 2 + 24 * i)
        blocks[name.split(b"\0")[0].decode("latin-1")] = (typ, pos, length)
        pos += max(length, 0)
    wl = struct.unpack_from("<f", raw, blocks["Wavelength"][1])[0]
    px = struct.unpack_from("<f", raw, blocks["Pixel_size"][1])[0]
    off = blocks["Raw"][1]
    nx, ny, itemsize = struct.unpack_from("<3H", raw, off)
    assert itemsize == 4
    data = np.frombuffer(raw, "<f4", nx * ny, off + 6)
    good = data < 1e38
    ds = _open(real_data, "opd-1.opd")
    _check_grid(ds, (ny, nx), (px, px), "mm")
    assert _masked(ds) == int((~good).sum()) > 0
    np.testing.assert_allclose(float(ds.height.mean()), data[good].astype(float).mean() * wl * 1e-6, rtol=1e-9)
    assert ds.attrs["acquisition_time"].startswith("2015-07-07T16:19:48")
    assert ds.attrs["wavelength"] == pytest.approx(wl)


def test_opdx_profile_matches_independent_text_export(real_data):
    ds = _open(real_data, "opdx-3.opdx")
    txt = np.loadtxt(real_data / "opdx-3.txt")  # x, height in metres
    assert ds.height.dims == ("x",) and ds.height.shape == (len(txt),)
    assert ds.height.attrs["units"] == "um" and ds.x.attrs["units"] == "um"
    np.testing.assert_allclose(ds.height.values, txt[:, 1] * 1e6, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(ds.x.values, txt[:, 0] * 1e6, rtol=1e-6, atol=1e-6)
    raw = (real_data / "opdx-3.opdx").read_bytes()
    assert b"Radius: 2 \xce\xbcm" in raw
    assert ds.attrs["tip_radius"] == 2.0 and ds.attrs["tip_radius_units"] == "um"
    assert ds.attrs["instrument"] == "Dektak Profiler"


def _x3p_main(path):
    with zipfile.ZipFile(path) as zf:
        name = min((n for n in zf.namelist() if n.endswith("main.xml") and not n.startswith("__MACOSX")), key=len)
        xml = zf.read(name).decode()
        base = name[:-len("main.xml")]
        return xml, zf.read(base + "bindata/data.bin"), (zf.read(base + "bindata/valid.bin")
                                                         if base + "bindata/valid.bin" in zf.namelist() else None)


def _tag(xml, axis, tag):
    m = re.search(rf"<{axis}>.*?<{tag}>([^<]*)</{tag}>", xml, re.S)
    return m.group(1) if m else None


@pytest.mark.parametrize("name", ["x3p-2.x3p", "KautschukInfiniteFocus.x3p", "sample-land.x3p"])
def test_x3p_float(real_data, name):
    xml, data, _ = _x3p_main(real_data / name)
    nx, ny = (int(re.search(rf"<{k}>(\d+)</{k}>", xml).group(1)) for k in ("SizeX", "SizeY"))
    dx, dy = float(_tag(xml, "CX", "Increment")), float(_tag(xml, "CY", "Increment"))
    dtype = {"F": "<f4", "D": "<f8"}[_tag(xml, "CZ", "DataType")]
    z = np.frombuffer(data, dtype).astype(float)
    ds = _open(real_data, name)
    _check_grid(ds, (ny, nx), (dy, dx), "m")
    ok = np.isfinite(z)  # NaN (and Inf, written by the Alicona export) mark invalid points
    assert _masked(ds) == int((~ok).sum())
    np.testing.assert_allclose(float(ds.height.mean()), z[ok].mean(), rtol=1e-6)
    row = np.where(ok[:nx], z[:nx], np.nan)
    np.testing.assert_allclose(ds.height.values[0], row, rtol=1e-12)  # x fastest


def test_x3p_int16_with_increment_offset_and_valid_mask(real_data):
    xml, data, valid = _x3p_main(real_data / "ISO5436-sample4_bin.x3p")
    assert _tag(xml, "CZ", "DataType") == "I"
    inc, off = float(_tag(xml, "CZ", "Increment")), float(_tag(xml, "CZ", "Offset"))
    counts = np.frombuffer(data, "<i2").astype(float)
    ok = np.unpackbits(np.frombuffer(valid, np.uint8), bitorder="little")[:16].astype(bool)
    ds = _open(real_data, "ISO5436-sample4_bin.x3p")
    d = float(_tag(xml, "CX", "Increment"))
    _check_grid(ds, (4, 4), (d, d), "m")
    assert _masked(ds) == int((~ok).sum()) == 1
    np.testing.assert_allclose(float(ds.height.mean()), (counts[ok] * inc + off).mean(), rtol=1e-12)
    assert ds.attrs["vendor"] == "NanoFocus AG"
    assert ds.attrs["acquisition_time"].startswith("2007-04-30T13:58:02")


def test_sur(real_data):
    raw = (real_data / "sur-3.sur").read_bytes()
    assert raw[:12] == b"DIGITAL SURF"
    special, = struct.unpack_from("<H", raw, 86)  # offsets of the 512-byte header
    bits, zmin, _zmax, nx, ny = struct.unpack_from("<H2i2i", raw, 98)
    dx, dy, dz = struct.unpack_from("<3f", raw, 120)
    units = [raw[180 + 16 * i:196 + 16 * i].split(b"\0")[0].strip() for i in range(3)]
    assert units == [b"nm", b"nm", b"m"] and bits == 32 and special == 1
    zoff, = struct.unpack_from("<f", raw, 474)
    counts = np.frombuffer(raw, "<i4", nx * ny, 512)
    ok = counts != zmin - 2
    ds = _open(real_data, "sur-3.sur")
    _check_grid(ds, (ny, nx), (dy * 1e-9, dx * 1e-9), "m")
    assert _masked(ds) == int((~ok).sum()) > 0
    np.testing.assert_allclose(float(ds.height.max()), counts[ok].max() * dz + zoff, rtol=1e-9)
    assert ds.attrs["acquisition_time"] == "2023-06-22T10:08:53"


def test_plu(real_data):
    raw = (real_data / "plu-1.plu").read_bytes()
    rows, cols = struct.unpack_from("<2I", raw, 388)
    mx, my = struct.unpack_from("<2f", raw, 404)
    z = np.frombuffer(raw, "<f4", rows * cols, 508).astype(float)
    ds = _open(real_data, "plu-1.plu")
    _check_grid(ds, (rows, cols), (my, mx), "um")
    good = z != 1000001
    np.testing.assert_allclose(float(ds.height.std()), z[good].std(), rtol=1e-9)
    assert ds.attrs["acquisition_time"] == "2023-03-10T16:35:59" and ds.attrs["vendor"] == "Sensofar"


def test_metropro(real_data):
    raw = (real_data / "metropro-1.dat").read_bytes()
    hsize, = struct.unpack_from(">I", raw, 6)
    acw, ach, buckets = struct.unpack_from(">3H", raw, 52)
    nx, ny = struct.unpack_from(">2H", raw, 68)
    s, wl, _na, obl, _mag, res = struct.unpack_from(">6f", raw, 164)
    phase_res, = struct.unpack_from(">h", raw, 218)
    r = {0: 4096, 1: 32768, 2: 131072}[phase_res]
    counts = np.frombuffer(raw, ">i4", nx * ny, hsize + 2 * acw * ach * buckets)
    ok = counts < 2147483640
    ds = _open(real_data, "metropro-1.dat")
    _check_grid(ds, (ny, nx), (res, res), "m")
    assert _masked(ds) == int((~ok).sum())
    np.testing.assert_allclose(float(ds.height.std()), (counts[ok] * (s * obl * wl / r)).std(), rtol=1e-9)
    assert ds.attrs["wavelength"] == pytest.approx(wl)


def test_al3d(real_data):
    raw = (real_data / "al3d-1.al3d").read_bytes()
    tags = {m.group(1).decode(): m.group(2).decode()
            for m in re.finditer(rb"([A-Za-z]+)\0+([ -~]+?)\0*\r\n", raw[:2000])}
    nx, ny = int(tags["Cols"]), int(tags["Rows"])
    z = np.frombuffer(raw, "<f4", nx * ny, int(tags["DepthImageOffset"])).astype(float)  # 200*4 is a multiple of 8
    ds = _open(real_data, "al3d-1.al3d")
    _check_grid(ds, (ny, nx), (float(tags["PixelSizeYMeter"]), float(tags["PixelSizeXMeter"])), "m")
    np.testing.assert_allclose(float(ds.height.mean()), z.mean(), rtol=1e-9)
    assert ds.attrs["software"] == tags["CreatingApplication"]


def test_frt(real_data):
    raw = (real_data / "frt-2.frt").read_bytes()
    assert raw[:16] == b"FRTM_GLIDERV1.00"
    n, = struct.unpack_from("<H", raw, 16)
    pos, blocks = 18, {}
    for _ in range(n):
        tag, size = struct.unpack_from("<HI", raw, pos)
        blocks[tag] = (pos + 6, size)
        pos += 6 + size
    nx, ny, bits = struct.unpack_from("<3I", raw, blocks[0x66][0])
    lx, ly = struct.unpack_from("<2d", raw, blocks[0x67][0])
    scale, = struct.unpack_from("<d", raw, blocks[0x6C][0] + 4)
    counts = np.frombuffer(raw, "<u2" if bits == 16 else "<i4", nx * ny, blocks[0x0B][0])
    ok = counts != 1
    ds = _open(real_data, "frt-2.frt")
    _check_grid(ds, (ny, nx), (ly / ny, lx / nx), "m")
    assert _masked(ds) == int((~ok).sum()) > 0
    np.testing.assert_allclose(float(ds.height.mean()), counts[ok].mean() * scale, rtol=1e-9)
    # first stored row is the bottom line of the image
    np.testing.assert_allclose(ds.height.values[-1, ok[:nx]], counts[:nx][ok[:nx]] * scale)


def test_tmd(real_data):
    raw = (real_data / "tmd-1.tmd").read_bytes()
    start = raw.index(b"\0", 32) + 1
    nx, ny, lx, ly = struct.unpack_from("<2I2f", raw, start)
    z = np.frombuffer(raw, "<f4", nx * ny, start + 24).astype(float)
    ds = _open(real_data, "tmd-1.tmd")
    _check_grid(ds, (ny, nx), (ly / ny, lx / nx), "mm")
    np.testing.assert_allclose(float(ds.height.std()), z.std(), rtol=1e-6)  # float32 data


def test_nms(real_data):
    raw = (real_data / "nms-1.nms").read_bytes()
    n_low, n_high, f_low, f_high = struct.unpack_from("<2i2d", raw, 8)
    nx, ny, dx, dy = struct.unpack_from("<2i2d", raw, 1368)
    counts = np.frombuffer(raw, "<u2", nx * ny, 3468).astype(float)
    ds = _open(real_data, "nms-1.nms")
    _check_grid(ds, (ny, nx), (dy * 1e-3, dx * 1e-3), "um")
    np.testing.assert_allclose(float(ds.height.min()), f_low + (f_high - f_low) * (counts.min() - n_low)
                               / (n_high - n_low), rtol=1e-9)
    assert 0 < float(ds.height.max()) - float(ds.height.min()) <= f_high - f_low + 1e-9
    assert ds.attrs["acquisition_time"].startswith("2022-02-09T13:25")


def test_bcrf(real_data):
    raw = (real_data / "bcrf-1.bcrf").read_bytes()
    header = dict(re.findall(r"(\w+) = (\S+)", raw[:4096].decode("utf-16-le")))
    nx, ny = int(header["xpixels"]), int(header["ypixels"])
    assert (header["xunit"], header["zunit"]) == ("nm", "um")
    ds = _open(real_data, "bcrf-1.bcrf")
    # x/ylength is the scan range from the first to the last pixel: (n - 1) spacings
    _check_grid(ds, (ny, nx), (float(header["ylength"]) * 1e-3 / (ny - 1), float(header["xlength"]) * 1e-3 / (nx - 1)),
                "um")
    np.testing.assert_allclose(float(ds.height.min()), float(header["zmin"]), rtol=1e-6)  # stated in the header
    z = np.frombuffer(raw, "<f4", nx * ny, 2 * int(header["headersize"]))
    assert _masked(ds) == int((z > 1.7e38).sum())


def test_mnt_matches_the_bcrf_export_of_the_same_measurement(real_data):
    ds = _open(real_data, "mnt-1.mnt")
    bcr = _open(real_data, "bcrf-1.bcrf")  # an independent export (different format, different writer)
    assert ds.height.shape == bcr.height.shape == (600, 960)
    assert ds.height.attrs["units"] == "um"
    for dim in ("x", "y"):
        np.testing.assert_allclose(xtopo.conventions.spacing(ds, dim), xtopo.conventions.spacing(bcr, dim), rtol=1e-6)
    np.testing.assert_allclose(ds.height.values, bcr.height.values, rtol=0, atol=1e-6)  # µm; float32 in the BCRF
    assert ds.attrs["vendor"] == "Digital Surf" and ds.attrs["title"]


def test_ole_reader_matches_olefile(real_data):
    olefile = pytest.importorskip("olefile")
    from xtopo.io._ole import OleFile

    ours, ref = OleFile(real_data / "mnt-1.mnt"), olefile.OleFileIO(str(real_data / "mnt-1.mnt"))
    try:
        assert sorted(ours.listdir()) == sorted("/".join(p) for p in ref.listdir())
        for name in ours.listdir():
            assert ours.read_stream(name) == ref.openstream(name).read()
    finally:
        ref.close()


@pytest.mark.parametrize("name", ["opd-1.opd", "sur-3.sur", "plu-1.plu", "x3p-2.x3p", "frt-2.frt", "mnt-1.mnt"])
def test_channels_api(real_data, name):
    fmt = detect(real_data / name)[0]
    infos = fmt.channels(real_data / name)
    ds = _open(real_data, name, channel=0)
    assert infos and infos[0].shape == ds.height.shape
    assert infos[0].units == ds.height.attrs["units"]
    with pytest.raises(XtopoError, match="channel"):
        fmt.read(real_data / name, channel=99)


def test_all_optical_formats_registered():
    names = set(formats())
    assert {"opd", "opdx", "x3p", "sur", "mnt", "plu", "metropro", "al3d", "frt", "tmd", "nms", "bcr"} <= names


def test_plu_with_zero_columns_is_an_error(real_data, tmp_path):
    """plu-1.plu with its layer's column count (offset 504) zeroed was read as an empty 576 x 0 measurement."""
    raw = bytearray((real_data / "plu-1.plu").read_bytes())
    raw[504:508] = struct.pack("<I", 0)
    path = tmp_path / "plu-1.plu"
    path.write_bytes(bytes(raw))
    with pytest.raises(XtopoError, match=r"plu-1.plu: .*no points"):
        xtopo.open_topography(path)


def test_netcdf_with_empty_height_is_an_error(tmp_path):
    import xarray as xr

    path = tmp_path / "empty-height.nc"
    xr.Dataset({"height": (("y", "x"), np.zeros((3, 0)), {"units": "m"})},
               coords={"x": ("x", np.zeros(0), {"units": "m"}), "y": ("y", np.arange(3.0), {"units": "m"})}
               ).to_netcdf(path)
    with pytest.raises(XtopoError, match=r"empty-height.nc: .*no points"):
        xtopo.open_topography(path)


@pytest.mark.parametrize("name, offset, value, problem", [
    ("bcrf-1.bcrf", 114, b"\0\0\0\0", "9 x 600 grid needs"),  # xpixels "960" cut to "9"
    ("bcrf-1.bcrf", 142, b"\0\0\0\0", "960 x 6 grid needs"),  # ypixels "600" cut to "6"
    ("al3d-1.al3d", 142, b"\0\0\0\0", "296 x 2 depth image"),  # Cols "200" cut to "2"
    ("al3d-1.al3d", 714, b"\0\0\0\0", "2 x 200 depth image"),  # Rows "296" cut to "2"
    ("metropro-1.dat", 68, struct.pack(">H", 9), "9 x 480 phase grid"),  # cn_width 640 -> 9
])
def test_corrupt_grid_size_is_an_error_not_a_smaller_image(real_data, tmp_path, name, offset, value, problem):
    """A corrupt row/column count used to read a small corner of the data (e.g. 600 x 9 of a 600 x 960 BCRF)
    as a valid measurement; the stored data size (file size, texture offset, size field) now must agree."""
    raw = bytearray((real_data / name).read_bytes())
    raw[offset:offset + len(value)] = value
    path = tmp_path / name
    path.write_bytes(bytes(raw))
    with pytest.raises(XtopoError, match=f"{re.escape(name)}: .*{problem}"):
        xtopo.open_topography(path)
