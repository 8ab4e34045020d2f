"""NanoFocus µsurf NMS files (confocal microscopes, header version ``OM_MS_2.0``).

Layout (little endian, 3468-byte header): data type (int32, 2 = uint16) at 0,
dimension type (int32, 1 = area) at 4, raw range ``n_low, n_high`` (int32) at 8
and the matching heights ``f_low, f_high`` (float64, µm) at 16, the version
string at 32, the channel title at 52, the acquisition time (ISO text) at 1076,
``nx, ny`` (int32) at 1368, spacings ``dx, dy`` (float64, nm) at 1376 and an
intensity flag (int32) at 1416.  The uint16 raster follows at 3468, row by row,
then (if flagged) a uint8 intensity image; zero intensity marks a pixel
without a valid height.  ``h = f_low + (f_high - f_low) (raw - n_low) / (n_high - n_low)``.
"""

from __future__ import annotations

import numpy as np

from ...conventions import make_measurement
from .._binary import BinaryReader, read_bytes
from ._common import ChannelInfo, channel_format, clean_text, parse_time

_HEADER = 3468
_VERSION = b"OM_MS_2.0"


def _sniff(head: bytes, path: str) -> bool:
    return head[32:32 + len(_VERSION)] == _VERSION and head[:4] == b"\x02\0\0\0"


def _parse(path):
    data = read_bytes(path)
    r = BinaryReader(data, path, "<")
    if data[32:32 + len(_VERSION)] != _VERSION:
        raise r.error("not a NanoFocus NMS file (version 'OM_MS_2.0' missing)")
    dtype, dimtype, n_low, n_high, f_low, f_high = r.unpack("4i2d", "NMS header", at=0)
    if dtype != 2 or dimtype != 1:
        raise r.error(f"unsupported NMS data type {dtype} / dimension type {dimtype} (uint16 area expected)")
    if n_high == n_low:
        raise r.error("NMS raw range is empty (n_low == n_high)")
    nx, ny, dx, dy = r.unpack("2i2d", "NMS grid", at=1368)
    has_intensity = r.unpack("i", "NMS intensity flag", at=1416)
    if nx <= 0 or ny <= 0 or not (dx > 0 and dy > 0):
        raise r.error(f"invalid NMS grid {nx} x {ny} with spacing {dx} x {dy} nm")
    title = clean_text(data[52:52 + 64])
    when = parse_time(clean_text(data[1076:1096]), "%Y-%m-%dT%H:%M:%S", "%Y-%m-%dT%H:%M")
    h = dict(n_low=n_low, n_high=n_high, f_low=f_low, f_high=f_high, dx=dx * 1e-3, dy=dy * 1e-3,
             has_intensity=has_intensity > 0, time=when)
    return [ChannelInfo(0, title or "Height", (ny, nx), (ny * h["dy"], nx * h["dx"]), "um", "um")], r, h


def _load(path, info, r, h):
    n = info.shape[0] * info.shape[1]
    raw = r.array("u2", n, "NMS height data", at=_HEADER).astype(np.float64)
    z = h["f_low"] + (h["f_high"] - h["f_low"]) * (raw - h["n_low"]) / (h["n_high"] - h["n_low"])
    undefined = np.zeros(n, bool)
    if h["has_intensity"]:
        undefined = r.array("u1", n, "NMS intensity image", at=_HEADER + 2 * n) == 0
    return make_measurement(z.reshape(info.shape), spacing=(h["dy"], h["dx"]), units="um",
                            mask=undefined.reshape(info.shape), name=info.name, vendor="NanoFocus",
                            instrument="NanoFocus µsurf confocal microscope", acquisition_time=h["time"],
                            original_units="lateral nm, heights um")


channel_format("nms", "NanoFocus µsurf NMS confocal image", (".nms",), _sniff, "NanoFocus NMS", _parse, _load)
