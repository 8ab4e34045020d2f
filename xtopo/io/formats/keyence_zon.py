"""Keyence ZON files (VR series one-shot 3D measuring macroscopes).

Layout (facts from Gwyddion's ``zonfile.c`` as read by SurfaceTopography's ``ZON.py`` and surfalize's
``zon.py``): an 8-byte header starting ``"KPK"`` (``KPK0``/``KPK1``), a BMP preview, then a zip
archive whose members are named by UUIDs; members may be compressed individually with zstd (they
then start with the zstd frame magic ``28 B5 2F FD``; reading those needs the ``zstandard`` package).

* ``686613b8-27b5-4a29-8ffc-438c2780873e``: XML ``XYCalibration/MeterPerPixel`` (pixel size, m) and
  ``ZCalibration/MeterPerUnit`` (height per digit, m);
* ``4cdb0c75-5706-48cc-a9a1-adf395d609ae``: the heights, a 16-byte header ``nx, ny, item size (4),
  row stride`` (uint32) then ``ny`` rows of int32 padded to the stride;
* ``9e7ca6dd-0e6a-4d7b-8986-f0a7b773c916`` (optional): a validity map, the same header with item
  size 1; a pixel is undefined where one of the two low bits is set (SurfaceTopography's rule;
  surfalize treats any nonzero value as undefined);
* ``cbc1d39b-...`` (device: ``DeviceModelName``, ``DeviceSerialId``) and ``1d35862b-...`` (scan:
  ``ScanDateTime``).

The size is ``N ×`` pixel size. XML is parsed without DTDs or entities; decompression is capped.
"""

from __future__ import annotations

import io

import numpy as np

from ...errors import ReaderError
from .._binary import BinaryReader, check_count
from .._xml import child_text, parse_xml
from .._zip import MAX_MEMBER, MAX_METADATA, open_zip
from ._common import channel_format, channel_info, measurement, parse_time, to_float, zip_member

_WHAT = "Keyence ZON"
_HEIGHT = "4cdb0c75-5706-48cc-a9a1-adf395d609ae"
_VALID = "9e7ca6dd-0e6a-4d7b-8986-f0a7b773c916"
_UNIT = "686613b8-27b5-4a29-8ffc-438c2780873e"
_DEVICE = "cbc1d39b-215f-4d56-a20e-cf8e5f570755"
_SCAN = "1d35862b-3b48-4df2-9235-833ef590b043"
_ZSTD = b"\x28\xb5\x2f\xfd"
_INVALID_BITS = 0x03


def _sniff(head: bytes, path: str) -> bool:
    return head[:3] == b"KPK" and head[8:10] == b"BM"


def _member(path, zf, name, optional=False, limit=MAX_MEMBER):
    if optional and name not in zf.namelist():
        return None
    data = zip_member(path, zf, name, _WHAT, f"the ZON archive lacks the member {name} (not a Keyence ZON measurement)",
                      limit=limit)
    if data.startswith(_ZSTD):
        try:
            import zstandard
        except ImportError:
            raise ReaderError(path, "the ZON members are zstd-compressed; reading them needs the zstandard "
                                    "package (pip install \"xtopo[io]\")") from None
        try:
            with zstandard.ZstdDecompressor().stream_reader(io.BytesIO(data)) as reader:
                data = reader.read(limit + 1)
        except zstandard.ZstdError as exc:
            raise ReaderError(path, f"ZON member {name} is not valid zstd data: {exc}") from None
        if len(data) > limit:
            raise ReaderError(path, f"ZON member {name} decompresses to more than {limit} bytes (zip bomb?)")
    return data.removeprefix(b"\xef\xbb\xbf")


def _xml(path, zf, name, optional=False):
    data = _member(path, zf, name, optional, limit=MAX_METADATA)
    return None if data is None else parse_xml(data, path, f"ZON member {name}")


def _raster(path, data, itemsize, dtype, what):
    r = BinaryReader(data, path, "<")
    nx, ny, size, stride = r.unpack("4I", f"{what} header")
    if size != itemsize or nx == 0 or ny == 0 or stride < nx * itemsize or stride % itemsize:
        raise r.error(f"invalid ZON {what}: {nx} x {ny} items of {size} bytes, rows of {stride} bytes")
    check_count(path, ny * (stride // itemsize), itemsize, len(data) - 16, f"ZON {what}")
    return r.array(dtype, ny * (stride // itemsize), f"ZON {what}").reshape(ny, stride // itemsize)[:, :nx]


def _parse(path):
    with open_zip(path, _WHAT) as zf:
        unit = _xml(path, zf, _UNIT)
        dxy = to_float(path, child_text(unit, "XYCalibration", "MeterPerPixel"), "XYCalibration/MeterPerPixel")
        dz = to_float(path, child_text(unit, "ZCalibration", "MeterPerUnit"), "ZCalibration/MeterPerUnit")
        if not (dxy > 0 and dz != 0):
            raise ReaderError(path, f"invalid ZON calibration: {dxy} m per pixel, {dz} m per unit")
        heights, valid = _member(path, zf, _HEIGHT), _member(path, zf, _VALID, optional=True)
        device, scan = _xml(path, zf, _DEVICE, optional=True), _xml(path, zf, _SCAN, optional=True)
    nx, ny = BinaryReader(heights, path, "<").unpack("2I", "ZON height header")
    info = channel_info(0, "Height", (ny, nx), (ny * dxy, nx * dxy), "m", "m", height=True)
    meta = {"instrument": child_text(device, "DeviceModelName"), "serial_number": child_text(device, "DeviceSerialId"),
            "acquisition_time": parse_time((child_text(scan, "ScanDateTime") or "")[:19], "%Y-%m-%dT%H:%M:%S",
                                           "%Y-%m-%d %H:%M:%S", "%Y/%m/%d %H:%M:%S")}
    return [info], heights, valid, dz, meta


def _load(path, info, heights, valid, dz, meta):
    z = _raster(path, heights, 4, "<i4", "height data").astype(np.float64)
    mask = None
    if valid is not None:
        bits = _raster(path, valid, 1, "u1", "validity map")
        if bits.shape != z.shape:
            raise ReaderError(path, f"the ZON validity map is {bits.shape}, the heights {z.shape}")
        mask = (bits & _INVALID_BITS) != 0
    return measurement(path, z, info, height_scale=dz, mask=mask, vendor="Keyence", **meta)


channel_format("zon", "Keyence ZON (VR series 3D macroscope)", (".zon",), _sniff, _WHAT, _parse, _load)
