"""X3P archives are untrusted: traversal names, zip bombs and XML entities are refused."""

from __future__ import annotations

import struct
import zipfile

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.errors import ReaderError, XtopoError
from xtopo.io.registry import formats

MAIN = """<?xml version="1.0" encoding="UTF-8"?>{doctype}
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2">
  <Record1><Revision>ISO5436 - 2000</Revision><FeatureType>{feature}</FeatureType>
    <Axes>
      <CX><AxisType>I</AxisType><DataType>D</DataType><Increment>{dx}</Increment><Offset>0</Offset></CX>
      <CY><AxisType>I</AxisType><DataType>D</DataType><Increment>{dy}</Increment><Offset>0</Offset></CY>
      <CZ><AxisType>A</AxisType><DataType>{dtype}</DataType>{zscale}</CZ>
    </Axes></Record1>
  <Record2><Date>2021-03-04T05:06:07</Date><Instrument><Manufacturer>ACME{entity}</Manufacturer>
    <Model>Profiler</Model><Serial>42</Serial><Version>1</Version></Instrument></Record2>
  <Record3><MatrixDimension><SizeX>{nx}</SizeX><SizeY>{ny}</SizeY><SizeZ>1</SizeZ></MatrixDimension>
    {data}</Record3>
</p:ISO5436_2>"""


def _main(nx=3, ny=2, dx=1e-6, dy=2e-6, dtype="D", zscale="", doctype="", entity="", feature="SUR",
          link="bindata/data.bin", datalist=None):
    data = (f"<DataList>{''.join(f'<Datum>{v}</Datum>' for v in datalist)}</DataList>" if datalist is not None
            else f"<DataLink><PointDataLink>{link}</PointDataLink></DataLink>")
    return MAIN.format(nx=nx, ny=ny, dx=dx, dy=dy, dtype=dtype, zscale=zscale, doctype=doctype, entity=entity,
                       feature=feature, data=data).encode()


def _zip(path, members, compress=zipfile.ZIP_DEFLATED):
    with zipfile.ZipFile(path, "w", compress) as zf:
        for name, data in members.items():
            zf.writestr(zipfile.ZipInfo(name), data, compress_type=compress)
    return path


def _patch_declared_size(path, member, size):
    """Overwrite the uncompressed size of ``member`` in the local and central headers."""
    raw = bytearray(path.read_bytes())
    name = member.encode()
    central = raw.index(b"PK\x01\x02")  # first central directory record
    while True:
        n, = struct.unpack_from("<H", raw, central + 28)
        if raw[central + 46:central + 46 + n] == name:
            struct.pack_into("<I", raw, central + 24, size)
            local, = struct.unpack_from("<I", raw, central + 42)
            struct.pack_into("<I", raw, local + 22, size)
            break
        m, k = struct.unpack_from("<HH", raw, central + 30)
        central += 46 + n + m + k
    path.write_bytes(bytes(raw))


def _read(path):
    return formats()["x3p"].read(path)


def test_crafted_x3p_reads_back(tmp_path):
    z = np.arange(6, dtype="<f8") * 1e-7
    p = _zip(tmp_path / "ok.x3p", {"main.xml": _main(), "bindata/data.bin": z.tobytes()})
    ds = xtopo.open_topography(p)
    xr.testing.assert_allclose(ds.height, xr.DataArray(z.reshape(2, 3), dims=("y", "x"), coords=ds.height.coords,
                                                       attrs=ds.height.attrs))
    assert ds.attrs["vendor"] == "ACME" and ds.attrs["acquisition_time"] == "2021-03-04T05:06:07"
    np.testing.assert_allclose([xtopo.conventions.spacing(ds, "x"), xtopo.conventions.spacing(ds, "y")],
                               [1e-6, 2e-6])


def test_inline_datalist_and_profile(tmp_path):
    p = _zip(tmp_path / "prf.x3p", {"main.xml": _main(nx=4, ny=1, feature="PRF", datalist=[1e-6, 2e-6, "", 4e-6])})
    ds = _read(p)
    assert ds.height.dims == ("x",)
    assert ds["mask"].values.tolist() == [False, False, True, False]


@pytest.mark.parametrize("name", ["../evil.bin", "/etc/evil.bin", "bindata/../../evil.bin", "C:/evil.bin"])
def test_traversal_member_names_refused(tmp_path, name):
    p = _zip(tmp_path / "trav.x3p", {"main.xml": _main(), "bindata/data.bin": bytes(48), name: b"x"})
    with pytest.raises(ReaderError, match="traversal") as err:
        _read(p)
    assert "trav.x3p" in str(err.value)


def test_traversal_in_data_link_refused(tmp_path):
    p = _zip(tmp_path / "link.x3p", {"main.xml": _main(link="../../etc/passwd"), "bindata/data.bin": bytes(48)})
    with pytest.raises(ReaderError, match="traversal"):
        _read(p)


def test_zip_bomb_declared_size_refused(tmp_path):
    # main.xml asks for 20000 x 20000 doubles (3.2 GB); the member claims ~4 GB from a few bytes
    p = _zip(tmp_path / "bomb.x3p", {"main.xml": _main(nx=20000, ny=20000), "bindata/data.bin": bytes(1000)})
    _patch_declared_size(p, "bindata/data.bin", 0xFFFFFFF0)
    with pytest.raises(ReaderError, match="bomb"):  # refused from the declared sizes, before inflating
        _read(p)


def test_zip_bomb_ratio_refused(tmp_path):
    # a consistent header (64 MB of doubles) but the member claims it from 1000 stored bytes
    p = _zip(tmp_path / "ratio.x3p", {"main.xml": _main(nx=4096, ny=2048), "bindata/data.bin": bytes(1000)})
    _patch_declared_size(p, "bindata/data.bin", 4096 * 2048 * 8)
    with pytest.raises(ReaderError, match="bomb"):
        _read(p)


def test_main_xml_bomb_refused(tmp_path):
    p = _zip(tmp_path / "xmlbomb.x3p", {"main.xml": _main(), "bindata/data.bin": bytes(48)})
    _patch_declared_size(p, "main.xml", 0x7FFFFFFF)
    with pytest.raises(ReaderError, match="bomb"):
        _read(p)


def test_size_mismatch_refused(tmp_path):
    p = _zip(tmp_path / "short.x3p", {"main.xml": _main(), "bindata/data.bin": bytes(40)})
    with pytest.raises(ReaderError, match="implies"):
        _read(p)


@pytest.mark.parametrize("doctype, entity", [
    ('<!DOCTYPE r [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>', "&xxe;"),
    ('<!DOCTYPE r [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">]>', "&b;"),
    ('<!DOCTYPE r SYSTEM "http://example.invalid/x.dtd">', ""),
])
def test_xml_entities_and_dtds_refused(tmp_path, doctype, entity):
    p = _zip(tmp_path / "xxe.x3p", {"main.xml": _main(doctype=doctype, entity=entity),
                                    "bindata/data.bin": bytes(48)})
    with pytest.raises(ReaderError, match="DTD or entity"):
        xtopo.open_topography(p)


def test_not_a_zip_and_no_main_xml(tmp_path):
    p = _zip(tmp_path / "nomain.x3p", {"readme.txt": b"hello"})
    with pytest.raises(XtopoError):
        xtopo.open_topography(p, format="x3p")
    q = tmp_path / "junk.x3p"
    q.write_bytes(b"PK\x03\x04" + bytes(100))
    with pytest.raises(XtopoError):
        xtopo.open_topography(q, format="x3p")


def test_x3p_written_in_memory_roundtrip_int32_scale(tmp_path):
    counts = np.array([[0, 10, 20], [30, 40, 50]], dtype="<i4")
    p = _zip(tmp_path / "int.x3p", {"main.xml": _main(dtype="L", zscale="<Increment>1e-9</Increment>"
                                                                          "<Offset>1e-6</Offset>"),
                                    "bindata/data.bin": counts.tobytes()}, compress=zipfile.ZIP_STORED)
    ds = _read(p)
    np.testing.assert_allclose(ds.height.values, counts * 1e-9 + 1e-6)
