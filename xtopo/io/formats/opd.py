"""Wyko / Veeco / Bruker Vision OPD files (optical profilers).

Layout (little endian): a 2-byte prelude, then a directory of 24-byte entries
``name[16] type:int16 length:int32 attr:uint16``; the first entry is the
directory itself (its length is the directory size).  Block payloads follow
the directory in directory order, each ``length`` bytes long.  Array blocks
(type 3) start with ``nx, ny, itemsize`` (uint16) followed by the raster
stored column by column (x index outermost), bottom row first.  Heights are in
wavelengths: ``h[nm] = raw * Wavelength[nm] / Mult``; ``Pixel_size`` is in mm.
Float pixels ≥ 1e38 (int16 pixels ≥ 32766) are undefined.
"""

from __future__ import annotations

import struct

import numpy as np

from ...conventions import make_measurement
from .._binary import BinaryReader, read_bytes
from ._common import ChannelInfo, channel_format, clean_text, parse_time

_ENTRY = 24
_TYPE_ARRAY, _TYPE_TEXT, _TYPE_SHORT, _TYPE_FLOAT, _TYPE_DOUBLE, _TYPE_LONG = 3, 5, 6, 7, 8, 12
#: Array blocks that hold heights (others: Image, Intensity, SecArr_* are intensities).
_HEIGHT_ARRAYS = ("RAW DATA", "RAW_DATA", "OPD", "Raw", "SAMPLE_DATA")


def _sniff(head: bytes, path: str) -> bool:
    return head[2:11] == b"Directory"


def _parse(path):
    r = BinaryReader(read_bytes(path), path, "<")
    name, _typ, dirlen, _attr = r.unpack("16shlH", "directory entry", at=2)
    if clean_text(name) != "Directory" or dirlen <= 0 or dirlen % _ENTRY:
        raise r.error("not a Wyko OPD file (bad directory block)")
    n = dirlen // _ENTRY
    r.need(dirlen - _ENTRY, "OPD directory")
    entries = [r.unpack("16shlH", "directory entry") for _ in range(n - 1)]
    pos = 2 + dirlen
    meta, arrays = {}, []
    for raw_name, typ, length, _attr in entries:
        if length <= 0:
            continue
        name = clean_text(raw_name)
        if pos + length > len(r):
            raise r.error(f"block {name!r} ({length} bytes at offset {pos}) runs past the end of the file")
        if typ == _TYPE_ARRAY and name in _HEIGHT_ARRAYS:
            nx, ny, itemsize = r.unpack("3H", f"header of array {name!r}", at=pos)
            arrays.append((name, nx, ny, itemsize, pos + 6, length - 6))
        elif typ == _TYPE_TEXT:
            meta[name] = clean_text(r.data[pos:pos + min(length, 256)])
        elif typ in (_TYPE_SHORT, _TYPE_FLOAT, _TYPE_DOUBLE, _TYPE_LONG):
            # some files declare inconsistent types; decide on the block length (as Gwyddion's opdfile.c)
            fmt = {(_TYPE_SHORT, 2): "<h", (_TYPE_SHORT, 4): "<i", (_TYPE_FLOAT, 2): "<h",
                   (_TYPE_DOUBLE, 8): "<d", (_TYPE_LONG, 4): "<i"}.get((typ, length))
            if fmt is None and typ == _TYPE_FLOAT and length >= 4:
                fmt = "<f"
            if fmt is not None:
                meta[name] = struct.unpack_from(fmt, r.data, pos)[0]
        pos += length
    if "Wavelength" not in meta:
        raise r.error("no 'Wavelength' block: the height scale of this OPD file is unknown")
    px = meta.get("Pixel_size")
    aspect = meta.get("Aspect", 1.0) or 1.0
    infos = [ChannelInfo(i, name, (ny, nx), (ny * px * aspect, nx * px) if px and px > 0 else None, "mm", "nm", True)
             for i, (name, nx, ny, _isz, _off, _len) in enumerate(arrays)]
    return infos, r, meta, arrays


def _load(path, info, r, meta, arrays):
    name, nx, ny, itemsize, off, length = arrays[info.index]
    if itemsize not in (1, 2, 4):
        raise r.error(f"array {name!r} has unsupported item size {itemsize}")
    if nx * ny * itemsize > length:
        raise r.error(f"array {name!r} declares {nx}x{ny}x{itemsize} bytes but its block holds {length}")
    dtype = {1: "u1", 2: "<i2", 4: "<f4"}[itemsize]
    raw = r.array(dtype, nx * ny, f"array {name!r}", at=off).reshape(nx, ny)
    # stored x-major, bottom row first -> (y, x) with the top row first
    raw = raw.T[::-1, :].astype(np.float64)
    if itemsize == 1:
        undefined = np.zeros(raw.shape, bool)
    else:
        limit = 32766 if itemsize == 2 else 1e38
        undefined = ~np.isfinite(raw) | (raw >= limit)
    wavelength = float(meta["Wavelength"])
    mult = float(meta.get("Mult", 1) or 1)
    if info.size is None:
        raise r.error("no 'Pixel_size' block: the lateral calibration is unknown")
    heights_mm = np.where(undefined, np.nan, raw) * (wavelength / mult * 1e-6)  # nm -> mm
    date, time = meta.get("Date"), meta.get("Time")
    when = parse_time(f"{date} {time}", "%m/%d/%Y %H:%M:%S", "%m/%d/%y %H:%M:%S") if date and time else None
    return make_measurement(
        heights_mm, size=info.size, units="mm", mask=undefined, name=name,
        vendor="Veeco/Bruker (Wyko)", instrument="Wyko optical profiler",
        acquisition_time=when, wavelength=wavelength, wavelength_units="nm",
        magnification=meta.get("Magnification"), original_units="lateral mm, heights nm",
        channel=name)


channel_format("opd", "Wyko/Veeco Vision OPD optical profiler file", (".opd",), _sniff, "Wyko OPD", _parse, _load)
