"""FRT MicroProf files (``FRTM_GLIDERV1.00``/``1.01``; FRT optical profilometers).

Layout (little endian): magic ``"FRTM_GLIDERV"``, version text[4] ("1.00": block
sizes uint32, "1.01": uint64), block count (uint16), then tagged blocks
``tag:uint16 size:uint32/uint64 payload``.  Blocks used here: 0x0066 grid
``nx, ny, bits`` (uint32; bits 16 = uint16, 32 = int32), 0x0067 physical size
``Lx, Ly`` (float64, m), 0x006C ``meas_range`` (uint32) and the height scale
(float64, m per count), 0x0072 measurement start (POSIX time), 0x000B the
height raster (bottom row first, row by row), or, in newer files, 0x007D with
a sequence of images ``data_type, nx, ny, bits`` + raster (type bit 0x4 =
topography).  The count 1 marks undefined points.
"""

from __future__ import annotations

import numpy as np

from ...conventions import make_measurement
from .._binary import BinaryReader, check_count
from ._common import ChannelInfo, channel_format, sniff_magic, unix_time

_MAGIC = b"FRTM_GLIDERV"
_UNDEFINED = 1
_HEIGHT_TYPES = {0x0004: "Topography", 0x0080: "Thickness", 0x0800: "Sample thickness", 0x1000: "AFM"}


def _parse(path):
    r = BinaryReader.from_file(path, magic=_MAGIC, not_this="not an FRT MicroProf file")
    data = r.data
    version = data[12:16].decode("latin-1")
    if version not in ("1.00", "1.01"):
        raise r.error(f"unsupported FRT version {version!r}")
    nblocks = r.unpack("H", "block count", at=16)
    size_fmt = "I" if version == "1.00" else "Q"
    blocks = {}
    for _ in range(nblocks):
        if r.pos == len(r):
            break
        tag, size = r.unpack("H" + size_fmt, "block header")
        r.need(size, f"block 0x{tag:04x}")
        blocks.setdefault(tag, (r.pos, size))
        r.pos += size
    for tag in (0x66, 0x67, 0x6C):
        if tag not in blocks:
            raise r.error(f"FRT file lacks the block 0x{tag:04x} (grid, size or height scale)")
    lx, ly = r.unpack("2d", "FRT size block", at=blocks[0x67][0])
    images = _images(r, blocks)
    return [ChannelInfo(i, name, (ny, nx), (ly, lx), "m", "m")
            for i, (name, nx, ny, _b, _o, _s) in enumerate(images)], r, blocks, images


def _images(r, blocks):
    """(name, nx, ny, bits, offset) for every height raster in the file."""
    nx, ny, bits = r.unpack("3I", "FRT grid block", at=blocks[0x66][0])
    if 0x0B in blocks:
        return [("Topography", nx, ny, bits, blocks[0x0B][0], blocks[0x0B][1])]
    out = []
    if 0x7D in blocks:
        pos, size = blocks[0x7D]
        end, r.pos = pos + size, pos + 8
        while r.pos + 16 <= end:
            dtype, inx, iny, ibits = r.unpack("4I", "FRT image header")
            if ibits not in (16, 32):
                raise r.error(f"unsupported FRT image bit depth {ibits}")
            n = check_count(r.path, inx * iny, ibits // 8, end - r.pos, "FRT image")
            kind = dtype & 0xFFDF
            if kind in _HEIGHT_TYPES:
                side = "bottom" if dtype & 0x10000000 else "top"
                out.append((f"{_HEIGHT_TYPES[kind]} ({side} sensor) {((dtype & 0x0F000000) >> 24) + 1}",
                            inx, iny, ibits, r.pos, n * ibits // 8))
            r.pos += n * ibits // 8
    return out


def _load(path, info, r, blocks, images):
    name, nx, ny, bits, off, size = images[info.index]
    if bits not in (16, 32):
        raise r.error(f"unsupported FRT bit depth {bits}")
    check_count(path, nx * ny, bits // 8, size, f"FRT raster {name!r}")
    raw = r.array("u2" if bits == 16 else "i4", nx * ny, "FRT height data", at=off).reshape(ny, nx)[::-1]
    _range, scale = r.unpack("Id", "FRT height scale block", at=blocks[0x6C][0])
    undefined = raw == _UNDEFINED
    z = np.where(undefined, np.nan, raw.astype(np.float64) * scale)
    started = r.unpack("I", "FRT time block", at=blocks[0x72][0]) if 0x72 in blocks else 0
    return make_measurement(z, size=info.size, units="m", mask=undefined, name=name, vendor="FRT",
                            instrument="FRT MicroProf", acquisition_time=unix_time(started), original_units="m")


channel_format("frt", "FRT MicroProf optical profilometer data", (".frt",), sniff_magic(_MAGIC), "FRT MicroProf",
               _parse, _load)
