"""Park Systems (PSIA) TIFF images (``.tiff``/``.tif``).

A TIFF whose first directory carries the private tags 50432 (magic number
``0x0E031301``), 50433 (version), 50434 (the height data) and 50435 (a
little-endian binary header).  Header fields used (byte offsets):

=====  ===========================================================
0      image type (int32; 0 = 2D map)
4      source (channel) name, 32 UTF-16 characters
68     image mode, 8 UTF-16 characters
100    x pixels, 104 y pixels (int32)
140    x size, 148 y size (float64, µm)
220    data gain, 228 z scale, 236 z offset (float64)
244    z unit, 8 UTF-16 characters
348    data type (int32; 0 int16, 1 int32, 2 float32), headers of at least 352 bytes
=====  ===========================================================

Heights are ``data gain · (z scale · raw + z offset)`` in the z unit (a z scale
of 0 means 1).  Older files without a data-type field hold int16 data.  The
standard TIFF image (a false-colour preview) is ignored.  Rows are kept in file order.
"""

from __future__ import annotations

import struct

from ...errors import ReaderError
from .._binary import read_bytes
from .._tiff import TiffFile, head_tags
from ._common import channel_format, channel_info, measurement, parse_time, value_unit

MAGIC = 0x0E031301
_DTYPES = {0: "<i2", 1: "<i4", 2: "<f4"}
#: header fields 0 to 260 (the layout above; ``x``: bytes skipped)
_HEADER = "<i64s16s16x2i32x2d64x3d16s"


def _sniff(head: bytes, path: str) -> bool:
    tag = head_tags(head).get(50432)
    return tag is not None and head[:2] == b"II" and struct.unpack("<I", tag[2])[0] == MAGIC


def _parse(path):
    data = read_bytes(path)
    tif = TiffFile(data, path)
    if not tif.ifds or tif.value(0, 50432) != MAGIC:
        raise ReaderError(path, "TIFF without the Park Systems magic tag 50432")
    raw_hdr = tif.raw(0, 50435) if tif.has(0, 50435) else b""
    if len(raw_hdr) < 276:
        raise ReaderError(path, f"Park header (tag 50435) is too short ({len(raw_hdr)} bytes)")
    typ, source, mode, nx, ny, lx, ly, gain, zscale, zoffset, zunit = struct.unpack_from(_HEADER, raw_hdr)
    if typ != 0:
        raise ReaderError(path, "Park file holds a line profile or spectroscopy, not a 2D image")
    source, mode, zunit = (s.decode("utf-16-le", errors="replace").split("\0", 1)[0].strip()
                           for s in (source, mode, zunit))
    hdr = dict(mode=mode, nx=nx, ny=ny, gain=gain, zscale=zscale, zoffset=zoffset,
               dtype=struct.unpack_from("<i", raw_hdr, 348)[0] if len(raw_hdr) >= 352 else 0)
    if nx < 1 or ny < 1:
        raise ReaderError(path, f"Park header gives {nx}x{ny} pixels")
    if hdr["dtype"] not in _DTYPES:
        raise ReaderError(path, f"unknown Park data type {hdr['dtype']}")
    info = channel_info(0, source or "Z Height", (ny, nx), (ly, lx), "um", value_unit(zunit) or "um")
    return [info], tif, hdr


def _load(path, info, tif, hdr):
    typ, count, off = tif.ifds[0].get(50434, (None, 0, -1))
    if off < 0:
        raise ReaderError(path, "Park data tag 50434 is missing or points beyond the end of the file")
    raw = tif.reader.array(_DTYPES[hdr["dtype"]], hdr["nx"] * hdr["ny"], what="Park height data", at=off)
    zscale = hdr["zscale"] or 1.0
    values = raw.reshape(hdr["ny"], hdr["nx"]).astype(float) * zscale + hdr["zoffset"]
    software = tif.value(0, 305)
    return measurement(
        path, values, info, height_scale=hdr["gain"],
        instrument=software if isinstance(software, str) and software else None,
        vendor="Park Systems",
        acquisition_time=parse_time(tif.value(0, 306, ""), "%Y:%m:%d %H:%M:%S"),
        imaging_mode=hdr["mode"] or None,
        data_gain=hdr["gain"],
    )


channel_format("park_tiff", "Park Systems (PSIA) TIFF image", (".tiff", ".tif"), _sniff, "Park TIFF", _parse, _load,
               priority=20)
