"""Formats checked against files built from their published layout (no real sample is available to commit).

Each file is built as the published readers describe the format (Gwyddion, SurfaceTopography, surfalize); the
same file is read by SurfaceTopography and, where it reads the format, surfalize: the three readings agree on
sizes and heights, which checks xtopo's reading of the layout against two independent implementations.
"""

import io
import struct
import warnings
import zipfile

import numpy as np
import pytest

import xtopo
from xtopo.conventions import physical_size, spacing, validate
from xtopo.errors import XtopoError
from xtopo.io.registry import detect


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


# --------------------------------------------------------------------------- Keyence VK4 / VK6 / VK7

def _vk_image(values, depth):
    ny, nx = values.shape
    dt = {8: "<u1", 16: "<u2", 32: "<u4"}[depth]
    return (struct.pack("<7I", nx, ny, depth, 0, nx * ny * depth // 8, 0, 1000) + bytes(768)
            + values.astype(dt).tobytes())


def _vk4_bytes(height, light=None, dx=694000, dy=695000, dz=1000, depth=32, title="sample", lens="50x"):
    """A VK4 file as the published layout describes it (offset table, conditions, images, strings)."""
    head = b"VK4_" + bytes([1, 0, 0, 0]) + bytes(4)
    cond = [0] * 45
    cond[0] = 45 * 4
    cond[1:7] = [2024, 3, 14, 15, 9, 26]
    cond[24] = 500  # lens magnification x 10
    cond[42], cond[43], cond[44] = dx, dy, dz
    cond_b = struct.pack("<45I", *cond)
    strings = b"".join(struct.pack("<I", len(s)) + s.encode("utf-16-le") for s in (title, lens))
    table_size = 18 * 4
    pos = 12 + table_size
    blobs, offsets = [], dict.fromkeys(range(18), 0)
    for slot, blob in ((0, cond_b), (6, _vk_image(height, depth)), (3, None if light is None else
                                                                    _vk_image(light, 8)), (16, strings)):
        if blob is None:
            continue
        offsets[slot] = pos
        blobs.append(blob)
        pos += len(blob)
    return head + struct.pack("<18I", *(offsets[i] for i in range(18))) + b"".join(blobs)


def _vk_heights():
    rng = np.random.default_rng(4)
    return rng.integers(0, 2**20, size=(6, 9)), rng.integers(0, 255, size=(6, 9))


def test_keyence_vk4_from_layout(tmp_path):
    digits, light = _vk_heights()
    p = tmp_path / "a.vk4"
    p.write_bytes(_vk4_bytes(digits, light))
    assert detect(p)[0].name == "vk4"
    names = [c.name for c in xtopo.io.channels(p)]
    assert names == ["Height", "Light"]
    ds = xtopo.open_topography(p, units="um")
    assert ds.height.shape == (6, 9) and ds.height.attrs["units"] == "um"
    assert spacing(ds, "x") == pytest.approx(0.694) and spacing(ds, "y") == pytest.approx(0.695)
    np.testing.assert_allclose(ds.height.values, digits * 1e-3)  # 1000 pm per digit
    assert ds.attrs["vendor"] == "Keyence" and ds.attrs["objective"] == "50x"
    assert ds.attrs["objective_magnification"] == 50 and ds.attrs["acquisition_time"] == "2024-03-14T15:09:26"
    light_ds = xtopo.io.list_formats()["vk4"].read(p, channel="Light")
    np.testing.assert_array_equal(light_ds.height.values, light)
    with pytest.raises(xtopo.UnsupportedFormatError, match="not heights"):
        xtopo.open_topography(p, channel="Light")


@pytest.mark.parametrize("magic", [b"VK6", b"VK7"])
def test_keyence_vk6_vk7_wrap_vk4_content(tmp_path, magic):
    digits, _ = _vk_heights()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("Vk4File", _vk4_bytes(digits, depth=16 if magic == b"VK6" else 32, dz=10))
        zf.writestr("Properties", "<xml/>")
    p = tmp_path / ("a" + magic.decode().lower())
    p.write_bytes(magic + bytes(16) + buf.getvalue())
    assert detect(p)[0].name == "vk6"
    ds = xtopo.open_topography(p, units="nm")
    np.testing.assert_allclose(ds.height.values, digits.astype("u2" if magic == b"VK6" else "u4") * 1e-2)
    assert spacing(ds, "x") == pytest.approx(694.0)


def test_keyence_vk4_agrees_with_surfacetopography(tmp_path):
    digits, light = _vk_heights()
    p = tmp_path / "b.vk4"
    p.write_bytes(_vk4_bytes(digits, light))
    assert _same_as_surfacetopography(p, xtopo.open_topography(p, units="um"), "um") == digits.size
    assert _same_as_surfalize(p, xtopo.open_topography(p, units="um")) == digits.size


def _same_as_surfacetopography(path, ds, unit, valid=None, rtol=1e-12):
    """SurfaceTopography reads ``path`` with the sizes and (where ``valid``) the heights of ``ds`` (in ``unit``);
    returns the number of heights compared."""
    st = pytest.importorskip("SurfaceTopography")
    t = st.read_topography(str(path)).to_unit(unit)
    assert (physical_size(ds, "x"), physical_size(ds, "y")) == pytest.approx(t.physical_sizes)
    ok = np.ones(ds.height.shape, bool) if valid is None else valid
    np.testing.assert_allclose(ds.height.values[ok], t.heights().T[ok], rtol=rtol)
    return int(ok.sum())


def _same_as_surfalize(path, ds, valid=None):
    """surfalize (which reads in µm) reads ``path`` with the steps and (where ``valid``) heights of ``ds`` (in µm);
    returns the number of heights compared."""
    surfalize = pytest.importorskip("surfalize")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # surfalize's note on non-square pixels
        s = surfalize.Surface.load(str(path))
    assert (s.step_x, s.step_y) == pytest.approx((spacing(ds, "x"), spacing(ds, "y")), rel=1e-6)
    ok = np.ones(ds.height.shape, bool) if valid is None else valid
    np.testing.assert_allclose(ds.height.values[ok], s.data[ok], rtol=1e-6)
    return int(ok.sum())


def _fuzz(tmp_path, raw, fmt, name, n=60):
    """Truncations and random corruptions of ``raw`` end in a Dataset or an XtopoError naming the file; returns how
    many were refused (the empty file at least)."""
    rng = np.random.default_rng(len(raw))
    variants = [raw[:int(f * len(raw))] for f in np.linspace(0, 0.999, 15)]
    for _ in range(n):
        buf = bytearray(raw)
        pos = int(rng.integers(0, min(len(raw), 600))) if rng.random() < 0.6 else int(rng.integers(0, len(raw)))
        buf[pos:pos + 4] = rng.integers(0, 256, size=len(buf[pos:pos + 4]), dtype=np.uint8).tobytes()
        variants.append(bytes(buf))
    refused = 0
    for i, data in enumerate(variants):
        path = tmp_path / f"v{i}_{name}"
        path.write_bytes(data)
        try:
            ds = xtopo.io.list_formats()[fmt].read(path)
        except XtopoError as exc:
            assert path.name in str(exc)
            refused += 1
        else:
            validate(ds)
    return refused


def test_keyence_fuzz(tmp_path):
    digits, light = _vk_heights()
    raw = _vk4_bytes(digits, light)
    assert _fuzz(tmp_path, raw, "vk4", "f.vk4") > 0
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("Vk4File", raw)
    assert _fuzz(tmp_path, b"VK6" + buf.getvalue(), "vk6", "f.vk6") > 0


# --------------------------------------------------------------------------- Zygo DATX

def _datx(path, z, dx=1.2e-6, dy=1.3e-6, unit="nm", no_data=None):
    h5py = pytest.importorskip("h5py")
    conv = np.dtype([("Category", "S16"), ("BaseUnit", "S16"), ("Unit", "S16"), ("Parameters", "<f8", (4,))])
    with h5py.File(path, "w") as f:
        rows = [("Root", "Measurement", "{m}"), ("{m}", "Surface", "{s}"), ("{s}", "Path", "/Measurement/Surface")]
        f.create_dataset("MetaData", data=np.array(rows, dtype=[("Source", "S32"), ("Link", "S32"),
                                                                  ("Destination", "S32")]))
        d = f.create_dataset("Measurement/Surface", data=z)
        d.attrs["Unit"] = np.array([unit.encode()])
        d.attrs["X Converter"] = np.array([(b"LateralCat", b"Pixels", b"m", (0, dx, 0, 0))], dtype=conv)
        d.attrs["Y Converter"] = np.array([(b"LateralCat", b"Pixels", b"m", (0, dy, 0, 0))], dtype=conv)
        d.attrs["Z Converter"] = np.array([(b"HeightCat", unit.encode(), b"", (0, 0, 0, 0))], dtype=conv)
        if no_data is not None:
            d.attrs["No Data"] = np.array([no_data])
        f["Measurement"].attrs["Data Context.Data Attributes.System Type"] = np.array([b"NewView 9000"])


def test_zygo_datx_from_layout(tmp_path):
    z = np.random.default_rng(5).normal(size=(7, 11))
    z[2, 3] = 1e38
    p = tmp_path / "a.datx"
    _datx(p, z, no_data=1e38)
    assert detect(p)[0].name == "datx"
    (info,) = xtopo.io.channels(p)
    assert info.shape == (7, 11)
    ds = xtopo.open_topography(p, units="um")
    assert spacing(ds, "x") == pytest.approx(1.2) and spacing(ds, "y") == pytest.approx(1.3)
    assert bool(ds.mask[2, 3]) and int(ds.mask.sum()) == 1
    ok = ~ds.mask.values
    np.testing.assert_allclose(ds.height.values[ok], z[ok] * 1e-3)
    assert ds.attrs["vendor"] == "Zygo" and ds.attrs["instrument"] == "NewView 9000"
    _same_as_surfacetopography(p, ds, "um", valid=ok)


def test_zygo_datx_fuzz(tmp_path):
    p = tmp_path / "src.datx"
    _datx(p, np.arange(12.0).reshape(3, 4))
    assert _fuzz(tmp_path, p.read_bytes(), "datx", "f.datx", n=40) > 0


# --------------------------------------------------------------------------- Sensofar PLUX

def _plux_bytes(layers, dx=0.69, dy=0.7, device="S neox", date="2023-03-10T12:34:56"):
    ny, nx = layers[0].shape
    xml = (f"<xml><GENERAL><IMAGE_SIZE_X>{nx}</IMAGE_SIZE_X><IMAGE_SIZE_Y>{ny}</IMAGE_SIZE_Y>"
           f"<FOV_X>{dx}</FOV_X><FOV_Y>{dy}</FOV_Y><DATE>{date}</DATE></GENERAL>"
           f"<INFO><ITEM_0><NAME>Device</NAME><VALUE>{device}</VALUE></ITEM_0>"
           "<ITEM_1><NAME>Objective</NAME><VALUE>Nikon 50X</VALUE></ITEM_1></INFO>"
           + "".join(f"<LAYER_{i}><FILENAME_Z>LAYER_{i}.raw</FILENAME_Z></LAYER_{i}>" for i in range(len(layers)))
           + "</xml>")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("index.xml", xml)
        for i, z in enumerate(layers):
            zf.writestr(f"LAYER_{i}.raw", z.astype("<f4").tobytes())
        zf.writestr("recipe.txt", "<recipe/>")
    return buf.getvalue()


def test_sensofar_plux_from_layout(tmp_path):
    rng = np.random.default_rng(6)
    a, b = rng.normal(size=(5, 8)).astype("f4"), rng.normal(size=(5, 8)).astype("f4")
    a[1, 1] = np.nan
    p = tmp_path / "a.plux"
    p.write_bytes(_plux_bytes([a, b]))
    assert detect(p)[0].name == "plux"
    assert [c.name for c in xtopo.io.channels(p)] == ["Layer 0", "Layer 1"]
    ds = xtopo.open_topography(p, units="um")
    assert spacing(ds, "x") == pytest.approx(0.69) and spacing(ds, "y") == pytest.approx(0.7)
    np.testing.assert_array_equal(ds.height.values, a.astype(float))
    assert bool(ds.mask[1, 1]) and int(ds.mask.sum()) == 1
    assert ds.attrs["instrument"] == "S neox" and ds.attrs["objective"] == "Nikon 50X"
    assert ds.attrs["acquisition_time"] == "2023-03-10T12:34:56"
    np.testing.assert_array_equal(xtopo.open_topography(p, channel=1, units="um").height.values, b.astype(float))
    _same_as_surfacetopography(p, ds, "um", valid=~ds.mask.values)
    _same_as_surfalize(p, ds, valid=~ds.mask.values)


def test_sensofar_plux_refuses_entity_declarations(tmp_path):
    p = tmp_path / "x.plux"
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        zf.writestr("index.xml", '<!DOCTYPE x [<!ENTITY e SYSTEM "file:///etc/passwd">]><xml>&e;</xml>')
    p.write_bytes(buf.getvalue())
    with pytest.raises(xtopo.ReaderError, match="DTD or entity"):
        xtopo.io.list_formats()["plux"].read(p)


def test_sensofar_plux_fuzz(tmp_path):
    raw = _plux_bytes([np.arange(12.0).reshape(3, 4)])
    assert _fuzz(tmp_path, raw, "plux", "f.plux") > 0


# --------------------------------------------------------------------------- Olympus LEXT (TIFF)

def _tiff(pages, exif=None):
    """A little-endian TIFF: ``pages`` are ``(tags, image bytes)`` with tags ``{tag: (type, values)}``;
    ``exif`` (tags) becomes an EXIF directory that the first page points to (tag 34665)."""
    sizes = {1: 1, 2: 1, 3: 2, 4: 4, 7: 1, 11: 4}
    codes = {1: "B", 3: "H", 4: "I", 11: "f"}

    def enc(typ, val):
        if typ in (2, 7):
            return val
        return struct.pack("<" + codes[typ] * len(val), *val)

    out = bytearray(b"II*\x00" + bytes(4))
    dirs = [dict(tags) for tags, _ in pages]
    if exif is not None:
        dirs[0][34665] = (4, [0])
    data_offsets = []
    for _, img in pages:
        data_offsets.append(len(out))
        out += img
    for d, (_, img), off in zip(dirs, pages, data_offsets):
        d[273], d[279] = (4, [off]), (4, [len(img)])

    def write_dir(tags, link):
        while len(out) % 2:
            out.append(0)
        pos = len(out)
        items = sorted(tags.items())
        extra = pos + 2 + 12 * len(items) + 4
        entries, blobs = b"", b""
        for tag, (typ, val) in items:
            raw = enc(typ, val)
            count = len(raw) // sizes[typ]
            if len(raw) <= 4:
                entries += struct.pack("<HHI", tag, typ, count) + raw.ljust(4, b"\0")
            else:
                entries += struct.pack("<HHII", tag, typ, count, extra + len(blobs))
                blobs += raw + (b"\0" if len(raw) % 2 else b"")
        out.extend(struct.pack("<H", len(items)) + entries + struct.pack("<I", link) + blobs)
        return pos

    exif_pos = write_dir(exif, 0) if exif is not None else None
    if exif is not None:
        dirs[0][34665] = (4, [exif_pos])
    # directories are written last to first so that each knows the next one's offset
    link = 0
    for d in reversed(dirs):
        link = write_dir(d, link)
    out[4:8] = struct.pack("<I", link)
    return bytes(out)


def _lext_bytes(height, per=(125000.0, 126000.0, 1.0), cal=(1e6, 1e6, 0.5e6), invalid=None):
    ny, nx = height.shape
    xml = (f"<TiffTagDescData><HeightInfo><HeightDataPerPixelX>{per[0]}</HeightDataPerPixelX>"
           f"<HeightDataPerPixelY>{per[1]}</HeightDataPerPixelY><HeightDataPerPixelZ>{per[2]}"
           "</HeightDataPerPixelZ><HeightDataUnitX>1</HeightDataUnitX><HeightDataUnitY>1</HeightDataUnitY>"
           "<HeightDataUnitZ>1</HeightDataUnitZ></HeightInfo></TiffTagDescData>\0").encode()
    exif = {41995: (2, ("<ExifTagDescData><ImageCommonSettingsInfo>" + "".join(
        f"<MakerCalibrationValue{a}>{c:.0f}</MakerCalibrationValue{a}>" for a, c in zip("XYZ", cal))
        + "</ImageCommonSettingsInfo></ExifTagDescData>\0").encode())}  # ASCII, as the peers read it

    def image_tags(w, h, bits, desc, spp=1):
        return {256: (4, [w]), 257: (4, [h]), 258: (3, [bits] * spp), 259: (3, [1]), 262: (3, [1 if spp == 1 else 2]),
                270: (2, desc.encode() + b"\0"), 277: (3, [spp]), 278: (4, [h])}

    color = image_tags(nx, ny, 8, "x", spp=3)
    color[270] = (2, xml)
    color[306] = (2, b"2021:06:01 10:20:30\0")
    pages = [(color, bytes(3 * nx * ny)),
             (image_tags(nx, ny, 32, "HEIGHT"), height.astype("<u4").tobytes()),
             (image_tags(nx, ny, 16, "INTENSITY"), (height % 4096).astype("<u2").tobytes())]
    if invalid is not None:
        pages.append((image_tags(nx, ny, 1, "INVALID"), np.packbits(invalid, axis=1).tobytes()))
    return _tiff(pages, exif)


def test_olympus_lext_from_layout(tmp_path):
    rng = np.random.default_rng(8)
    digits = rng.integers(0, 2**24, size=(6, 10))
    invalid = np.zeros((6, 10), bool)
    invalid[2, 7] = True
    p = tmp_path / "a.lext"
    p.write_bytes(_lext_bytes(digits, invalid=invalid))
    assert detect(p)[0].name == "lext"
    assert [c.name for c in xtopo.io.channels(p)] == ["Height", "Intensity"]
    ds = xtopo.open_topography(p, units="um")
    assert spacing(ds, "x") == pytest.approx(0.125) and spacing(ds, "y") == pytest.approx(0.126)
    np.testing.assert_allclose(ds.height.values[~invalid], digits[~invalid] * 0.5e-6)  # 1 pm/digit x 0.5
    assert bool(ds.mask[2, 7]) and int(ds.mask.sum()) == 1
    assert ds.attrs["vendor"] == "Olympus" and ds.attrs["acquisition_time"] == "2021-06-01T10:20:30"
    _same_as_surfacetopography(p, ds, "um", valid=~invalid)
    _same_as_surfalize(p, ds, valid=~invalid)


def test_olympus_lext_fuzz(tmp_path):
    raw = _lext_bytes(np.arange(24).reshape(4, 6))
    assert _fuzz(tmp_path, raw, "lext", "f.lext") > 0


# --------------------------------------------------------------------------- OmniSurf3D (OS3D)

def _os3d_bytes(z, dx=0.5, dy=0.25, when="2022-05-04 11:12:13"):
    ny, nx = z.shape
    s = b"OmniSurf3D" + struct.pack("<2i", 1, 2)
    for text in (b"instrument X", when.encode()):
        s += struct.pack("<i", len(text)) + text
    s += struct.pack("<2i4d", nx, ny, dx, dy, 0.0, 0.0) + z.astype("<f4").tobytes() + b"\0"
    return s


def test_os3d_from_layout(tmp_path):
    z = np.random.default_rng(9).normal(size=(5, 7)).astype("f4")
    z[3, 4] = np.finfo("f4").min
    p = tmp_path / "a.os3d"
    p.write_bytes(_os3d_bytes(z))
    assert detect(p)[0].name == "os3d"
    (info,) = xtopo.io.channels(p)
    assert info.shape == (5, 7) and info.size == pytest.approx((1.25, 3.5))
    ds = xtopo.open_topography(p, units="um")
    assert spacing(ds, "x") == pytest.approx(0.5) and spacing(ds, "y") == pytest.approx(0.25)
    ok = np.ones(z.shape, bool)
    ok[3, 4] = False
    assert bool(ds.mask[3, 4]) and int(ds.mask.sum()) == 1
    np.testing.assert_array_equal(ds.height.values[ok], z[ok].astype(float))
    assert ds.attrs["acquisition_time"] == "2022-05-04T11:12:13"
    _same_as_surfacetopography(p, ds, "um", valid=ok)
    _same_as_surfalize(p, ds, valid=ok)


def test_os3d_fuzz(tmp_path):
    assert _fuzz(tmp_path, _os3d_bytes(np.arange(12.0).reshape(3, 4)), "os3d", "f.os3d") > 0


# --------------------------------------------------------------------------- NT-MDT

def _mdt_frame(raw, adc=0, steps=(10.0, 12.0, 0.5), units=(-1, -1, -1), zoff=3.0, var_size=40, typ=0, dots=0):
    ny, nx = raw.shape
    body = struct.pack("<ffhffhffh", 0.0, steps[0], units[0], 0.0, steps[1], units[1], zoff, steps[2], units[2])
    body += struct.pack("<BBHH", adc, 0, nx, ny) + bytes(var_size - 36)
    body += struct.pack("<4H", 0, nx, ny, dots) + (bytes(14 + 16 * dots) if dots else b"")
    body += raw.astype("<i2").tobytes()
    head = struct.pack("<IH", 22 + len(body), typ) + struct.pack(">H", 1) + struct.pack("<7H", 2020, 2, 3, 4, 5, 6,
                                                                                        var_size)
    return head + body


def _mdt_bytes(frames):
    return b"\x01\xb0\x93\xff" + struct.pack("<I", 0) + bytes(4) + struct.pack("<H", len(frames) - 1) + bytes(19) \
        + b"".join(frames)


def test_nt_mdt_from_layout(tmp_path):
    rng = np.random.default_rng(10)
    h, phase = rng.integers(-3000, 3000, size=(4, 6)), rng.integers(-3000, 3000, size=(4, 6))
    text = struct.pack("<IH", 30, 3) + bytes(24)  # a text frame (type 3): skipped
    p = tmp_path / "a.mdt"
    p.write_bytes(_mdt_bytes([_mdt_frame(h), text, _mdt_frame(phase, adc=11, units=(-1, -1, 5), dots=1)]))
    assert detect(p)[0].name == "mdt"
    chans = xtopo.io.channels(p)
    assert [c.name for c in chans] == ["Height"]  # the phase frame has no length unit in z
    ds = xtopo.open_topography(p, units="nm")
    assert spacing(ds, "x") == pytest.approx(10.0) and spacing(ds, "y") == pytest.approx(12.0)
    np.testing.assert_allclose(ds.height.values, h[::-1] * 0.5 + 3.0)  # bottom line first in the file
    assert ds.attrs["acquisition_time"] == "2020-02-03T04:05:06"
    _same_as_surfacetopography(p, ds, "nm", rtol=1e-6)


def test_nt_mdt_fuzz(tmp_path):
    raw = _mdt_bytes([_mdt_frame(np.arange(12).reshape(3, 4)), _mdt_frame(np.arange(6).reshape(2, 3), adc=1)])
    assert _fuzz(tmp_path, raw, "mdt", "f.mdt") > 0


# --------------------------------------------------------------------------- KLA Zeta ZMG

def _zmg_bytes(digits, dx=0.4, dy=0.5, dz=0.002, comment=b"a comment"):
    ny, nx = digits.shape
    head = bytearray(b"Zeta-Instruments".ljust(85, b"\0"))
    head += struct.pack("<2I", nx, ny) + bytes(4) + struct.pack("<3f", dx, dy, dz) + bytes(8)
    head += struct.pack("<I", len(comment)) + bytes(10) + b"recipe 1".ljust(68, b"\0") + bytes(6)
    assert len(head) == 205
    return bytes(head) + comment + digits.astype("<u2").tobytes()


def test_zeta_zmg_from_layout(tmp_path):
    digits = np.random.default_rng(11).integers(0, 65535, size=(5, 9))
    p = tmp_path / "a.zmg"
    p.write_bytes(_zmg_bytes(digits))
    assert detect(p)[0].name == "zmg"
    (info,) = xtopo.io.channels(p)
    assert info.shape == (5, 9)
    ds = xtopo.open_topography(p, units="um")
    assert spacing(ds, "x") == pytest.approx(0.4) and spacing(ds, "y") == pytest.approx(0.5)
    np.testing.assert_allclose(ds.height.values, digits * np.float32(0.002), rtol=1e-12)
    assert ds.attrs["recipe"] == "recipe 1" and ds.attrs["comment"] == "a comment"
    _same_as_surfacetopography(p, ds, "um", rtol=1e-6)
    _same_as_surfalize(p, ds, valid=digits < 32768)  # surfalize reads int16: equal below 2^15


def test_zeta_zmg_fuzz(tmp_path):
    assert _fuzz(tmp_path, _zmg_bytes(np.arange(12).reshape(3, 4)), "zmg", "f.zmg") > 0


# --------------------------------------------------------------------------- Keyence ZON

def _zon_bytes(digits, valid=None, dxy=2.5e-6, dz=1e-7, zstd=False, pad=3):
    ny, nx = digits.shape

    def raster(a, dtype, itemsize):
        stride = nx * itemsize + pad * itemsize
        rows = np.zeros((ny, stride // itemsize), dtype=dtype)
        rows[:, :nx] = a
        return struct.pack("<4I", nx, ny, itemsize, stride) + rows.tobytes()

    members = {
        "686613b8-27b5-4a29-8ffc-438c2780873e": (
            f"<Calibration><XYCalibration><MeterPerPixel>{dxy}</MeterPerPixel></XYCalibration>"
            f"<ZCalibration><MeterPerUnit>{dz}</MeterPerUnit></ZCalibration></Calibration>").encode(),
        "cbc1d39b-215f-4d56-a20e-cf8e5f570755": (b"\xef\xbb\xbf<DeviceInformations><DeviceModelName>VR-5000"
                                                 b"</DeviceModelName><DeviceSerialId>123</DeviceSerialId>"
                                                 b"</DeviceInformations>"),
        "1d35862b-3b48-4df2-9235-833ef590b043": b"<ScanInformations><ScanDateTime>2022-11-03T08:09:10.1234567"
                                                b"+01:00</ScanDateTime></ScanInformations>",
        "4cdb0c75-5706-48cc-a9a1-adf395d609ae": raster(digits, "<i4", 4),
    }
    if valid is not None:
        members["9e7ca6dd-0e6a-4d7b-8986-f0a7b773c916"] = raster(valid, "u1", 1)
    if zstd:
        zstandard = pytest.importorskip("zstandard")
        members = {k: zstandard.ZstdCompressor().compress(v) for k, v in members.items()}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for k, v in members.items():
            zf.writestr(k, v)
    bmp = b"BM" + struct.pack("<I", 20) + bytes(14)
    return b"KPK0" + bytes(4) + bmp + buf.getvalue()


@pytest.mark.parametrize("zstd", [False, True])
def test_keyence_zon_from_layout(tmp_path, zstd):
    rng = np.random.default_rng(12)
    digits = rng.integers(-10**6, 10**6, size=(4, 7))
    valid = np.zeros((4, 7), np.uint8)
    valid[1, 5] = 2
    valid[2, 2] = 4  # not one of the two low bits: a valid point
    p = tmp_path / "a.zon"
    p.write_bytes(_zon_bytes(digits, valid, zstd=zstd))
    assert detect(p)[0].name == "zon"
    (info,) = xtopo.io.channels(p)
    assert info.shape == (4, 7)
    ds = xtopo.open_topography(p, units="um")
    assert spacing(ds, "x") == pytest.approx(2.5) and spacing(ds, "y") == pytest.approx(2.5)
    assert bool(ds.mask[1, 5]) and int(ds.mask.sum()) == 1
    ok = ~ds.mask.values
    np.testing.assert_allclose(ds.height.values[ok], digits[ok] * 0.1)
    assert ds.attrs["instrument"] == "VR-5000" and ds.attrs["acquisition_time"] == "2022-11-03T08:09:10"
    if not zstd:
        _same_as_surfacetopography(p, ds, "um", valid=ok)
        _same_as_surfalize(p, ds, valid=valid == 0)  # surfalize also drops points with only higher bits set


def test_keyence_zon_fuzz(tmp_path):
    raw = _zon_bytes(np.arange(12).reshape(3, 4), np.zeros((3, 4), np.uint8))
    assert _fuzz(tmp_path, raw, "zon", "f.zon") > 0


# --------------------------------------------------------------------------- Olympus OIR / POIR

_OIR_NS = ('xmlns:lsmimage="urn:l" xmlns:commonimage="urn:ci" xmlns:base="urn:b" xmlns:commonphase="urn:cp" '
           'xmlns:commonparam="urn:cpa"')


def _oir_properties(nx, ny, channels, cal=(1.0, 1.0, 0.5)):
    chans = "".join(
        f'<commonphase:channel id="{uuid}"><commonphase:imageDefinition><commonphase:imageType>{kind}'
        f"</commonphase:imageType><commonphase:depth>2</commonphase:depth></commonphase:imageDefinition>"
        "<commonphase:length><commonparam:x>0.125</commonparam:x><commonparam:y>0.13</commonparam:y>"
        "<commonparam:z>0.002</commonparam:z></commonphase:length><commonphase:pixelUnit><commonphase:x>um"
        "</commonphase:x><commonphase:y>um</commonphase:y><commonphase:z>um</commonphase:z></commonphase:pixelUnit>"
        "</commonphase:channel>" for uuid, kind in channels)
    return (f'<?xml version="1.0" encoding="UTF-8"?><lsmimage:imageProperties {_OIR_NS}>'
            "<commonimage:general><base:creationDateTime>2023-01-02T03:04:05.678+01:00</base:creationDateTime>"
            "</commonimage:general><commonimage:microscope><base:name>OLS5000</base:name></commonimage:microscope>"
            f"<commonimage:imageInfo><commonimage:width>{nx}</commonimage:width><commonimage:height>{ny}"
            f"</commonimage:height><commonimage:phase><commonphase:group>{chans}</commonphase:group>"
            "</commonimage:phase></commonimage:imageInfo><commonimage:acquisition>"
            "<commonimage:microscopeConfiguration><commonimage:pixelCalibration>"
            + "".join(f"<commonparam:{a}>{c}</commonparam:{a}>" for a, c in zip("xyz", cal))
            + "</commonimage:pixelCalibration></commonimage:microscopeConfiguration></commonimage:acquisition>"
            "</lsmimage:imageProperties>")


def _oir_bytes(images, prefix="t001_0_1"):
    """An OIR file with one HEIGHT channel per image (uint16): a frame chunk (type 1) followed by three data blocks
    (the heights, then INTENSITY/INVALID planes to make three), then the metadata list (type 0), as the two
    published readers expect them (SurfaceTopography walks all chunks, surfalize the frame and its three blocks)."""
    def s(text):
        b = text.encode()
        return struct.pack("<I", len(b)) + b

    def block(typ, body, first=1):
        return struct.pack("<9I", typ, first, 1, 0, 0, 1, 1, 1, 1) + body

    ny, nx = images[0].shape
    uuids = [f"{i:08d}-aaaa-bbbb-cccc-dddddddddddd" for i in range(len(images))]
    others = [("int-0", "INTENSITY"), ("inv-0", "INVALID")][:max(0, 3 - len(images))]
    props = _oir_properties(nx, ny, [(u, "HEIGHT") for u in uuids] + others)
    frame = block(2, s(f"<frameProperties><imageDefinition><width>{nx}</width><height>{ny}</height><depth>2</depth>"
                       "</imageDefinition></frameProperties>"))
    blocks = (block(1, s("<version/>")) + block(2, s(props)) + block(3, s("<annotations/>"))
              + block(4, s("<overlays/>")) + block(5, struct.pack("<I", 1) + s("lut") + s("<lut/>"))
              + block(6, struct.pack("<I", 1) + s(prefix) + struct.pack("<I", 0))
              + block(7, struct.pack("<I", 1) + s(prefix) + struct.pack("<I", 0))
              + block(8, struct.pack("<I", len(uuids)) + b"".join(s(u) + struct.pack("<I", 0) for u in uuids))
              + block(14, s("<events/>")))
    out = bytearray(b"OLYMPUSRAWFORMAT" + struct.pack("<14I", 12, 0, 1, 2, 0, 0, 0, 0, 17, 0, 1, 0, 0, 0)
                    + b"UNKNOWN\0" + struct.pack("<4I", 1, 1, 0xFFFFFFFF, 0xFFFFFFFF))
    out += struct.pack("<ii", len(frame), 1) + frame
    planes = list(zip(uuids, images)) + [(u, np.full((ny, nx), 7)) for u, _ in others]
    for u, img in planes:
        raw = img.astype("<u2").tobytes()
        head = struct.pack("<2I", 0, len(raw)) + s(f"{prefix}_{u}_0")
        out += struct.pack("<ii", len(head), 3) + head + struct.pack("<2I", len(raw), 4) + raw
    out += struct.pack("<ii", len(blocks), 0) + blocks + struct.pack("<i", -1)
    return bytes(out)


def test_olympus_oir_from_layout(tmp_path):
    rng = np.random.default_rng(13)
    a, b = rng.integers(0, 65535, size=(5, 8)), rng.integers(0, 65535, size=(5, 8))
    p = tmp_path / "a.oir"
    p.write_bytes(_oir_bytes([a, b]))
    assert detect(p)[0].name == "oir"
    assert [c.name for c in xtopo.io.channels(p)] == ["Height", "Height 2"]
    ds = xtopo.open_topography(p, units="um")
    assert spacing(ds, "x") == pytest.approx(0.125) and spacing(ds, "y") == pytest.approx(0.13)
    np.testing.assert_allclose(ds.height.values, a * 0.001)  # 0.002 um per digit x calibration 0.5
    np.testing.assert_allclose(xtopo.open_topography(p, channel=1, units="um").height.values, b * 0.001)
    assert ds.attrs["instrument"] == "OLS5000" and ds.attrs["acquisition_time"] == "2023-01-02T03:04:05"
    _same_as_surfacetopography(p, ds, "um")
    _same_as_surfalize(p, ds)


def test_olympus_poir_lists_the_heights_of_every_member(tmp_path):
    rng = np.random.default_rng(14)
    a, b = rng.integers(0, 65535, size=(4, 6)), rng.integers(0, 65535, size=(4, 6))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("first.oir", _oir_bytes([a]))
        zf.writestr("second.oir", _oir_bytes([b]))
        zf.writestr("readme.txt", "not an OIR file")
    p = tmp_path / "a.poir"
    p.write_bytes(buf.getvalue())
    assert detect(p)[0].name == "poir"
    assert [c.name for c in xtopo.io.channels(p)] == ["first.oir: Height", "second.oir: Height"]
    np.testing.assert_allclose(xtopo.open_topography(p, channel=1, units="um").height.values, b * 0.001)


def test_olympus_oir_fuzz(tmp_path):
    raw = _oir_bytes([np.arange(12).reshape(3, 4)])
    assert _fuzz(tmp_path, raw, "oir", "f.oir") > 0
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("x.oir", raw)
    assert _fuzz(tmp_path, buf.getvalue(), "poir", "f.poir", n=30) > 0


def test_keyence_zon_refuses_a_zstd_bomb(tmp_path):
    zstandard = pytest.importorskip("zstandard")
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:  # 17 MiB of XML from a few hundred compressed bytes
        zf.writestr("686613b8-27b5-4a29-8ffc-438c2780873e", zstandard.ZstdCompressor().compress(b" " * (17 << 20)))
    p = tmp_path / "bomb.zon"
    p.write_bytes(b"KPK0" + bytes(4) + b"BM" + struct.pack("<I", 20) + bytes(14) + buf.getvalue())
    with pytest.raises(xtopo.ReaderError, match="decompresses to more than"):
        xtopo.io.list_formats()["zon"].read(p)
