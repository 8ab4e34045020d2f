"""Digital Metrology OmniSurf3D ``.os3d`` files.

Layout (little endian; Digital Metrology's published "OmniSurf3D file format", as read by
SurfaceTopography's ``OS3D.py`` and surfalize's ``os3d.py``): the magic ``"OmniSurf3D"``, major and
minor version (int32), an identification string and a measurement date/time string (each an int32
length and that many bytes), the points along x and y (int32), the spacing along x and y and the
origin (float64, µm), then ``ny × nx`` float32 heights in µm, row by row; values below -3e38 (the
most negative float32) mark invalid points. An optional preview image follows (ignored).
The size is ``N ×`` spacing.
"""

from __future__ import annotations

import numpy as np

from .._binary import BinaryReader
from ._common import channel_format, channel_info, measurement, parse_time, sniff_magic

_MAGIC = b"OmniSurf3D"
_INVALID = -3e38
_MAX_STRING = 1 << 16


def _string(r, what):
    n = r.unpack("i", f"{what} length")
    if not 0 <= n <= _MAX_STRING:
        raise r.error(f"implausible OS3D {what} length {n}")
    return r.read(n, what).decode("utf-8", errors="replace").strip("\0 ")


def _parse(path):
    r = BinaryReader.from_file(path, magic=_MAGIC, not_this="not an OmniSurf3D file (magic 'OmniSurf3D' missing)")
    major, minor = r.unpack("2i", "OS3D version", at=len(_MAGIC))
    ident, when = _string(r, "identification"), _string(r, "date/time")
    nx, ny = r.unpack("2i", "OS3D grid size")
    dx, dy, _x0, _y0 = r.unpack("4d", "OS3D spacing and origin")
    if nx <= 0 or ny <= 0 or not (dx > 0 and dy > 0):
        raise r.error(f"invalid OS3D grid: {nx} x {ny} points at {dx} x {dy} µm")
    info = channel_info(0, "Height", (ny, nx), (ny * dy, nx * dx), "um", "um", height=True)
    meta = {"identification": ident or None, "software_version": f"{major}.{minor}",
            "acquisition_time": parse_time(when, "%Y-%m-%d %H:%M:%S", "%Y-%m-%dT%H:%M:%S", "%m/%d/%Y %H:%M:%S",
                                           "%m/%d/%Y %I:%M:%S %p", "%d.%m.%Y %H:%M:%S")}
    return [info], r, meta


def _load(path, info, r, meta):
    ny, nx = info.shape
    z = r.array("<f4", nx * ny, "OS3D heights").astype(np.float64).reshape(ny, nx)
    mask = (z < _INVALID) | ~np.isfinite(z)
    return measurement(path, np.where(mask, np.nan, z), info, mask=mask, vendor="Digital Metrology", **meta)


channel_format("os3d", "Digital Metrology OmniSurf3D", (".os3d",), sniff_magic(_MAGIC), "OmniSurf3D", _parse, _load)
