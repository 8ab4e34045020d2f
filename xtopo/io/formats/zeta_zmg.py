"""KLA Zeta ``.zmg`` files (Zeta Instruments / KLA optical profilers).

Layout (little endian; facts from Gwyddion's ``zmgfile.c`` as read by SurfaceTopography's
``ZMG.py``, and surfalize's ``zmg.py``): the magic ``"Zeta-Instruments"`` (16 bytes); at offset 85 the
points along x and y (uint32), 4 reserved bytes, the steps along x, y (µm per pixel) and z (µm per
digit, float32), 8 reserved bytes, the size of a comment (uint32), 84 bytes more header (the recipe
name among them) — 205 bytes in all — then the comment and ``ny × nx`` 16-bit heights, row by row.
Gwyddion and SurfaceTopography read the heights as unsigned, surfalize as signed integers; xtopo
follows Gwyddion (the two differ only for raw values of 32768 and more). The size is ``N ×`` step.
"""

from __future__ import annotations

import numpy as np

from .._binary import BinaryReader
from ._common import channel_format, channel_info, clean_text, measurement, sniff_magic

_MAGIC = b"Zeta-Instruments"
_HEADER = 205


def _parse(path):
    r = BinaryReader.from_file(path, magic=_MAGIC, not_this="not a KLA Zeta ZMG file (magic missing)")
    nx, ny = r.unpack("2I", "ZMG grid size", at=85)
    dx, dy, dz = r.unpack("3f", "ZMG steps", at=97)
    comment_size = r.unpack("I", "ZMG comment size", at=117)
    recipe = clean_text(r.read(68, "ZMG recipe name", at=131))
    if nx == 0 or ny == 0 or not (dx > 0 and dy > 0 and np.isfinite(dz) and dz != 0):
        raise r.error(f"invalid ZMG grid: {nx} x {ny} points, steps {dx} x {dy} x {dz} µm")
    comment = r.read(comment_size, "ZMG comment", at=_HEADER).decode("latin-1", errors="replace").strip("\0 ")
    info = channel_info(0, "Height", (ny, nx), (ny * dy, nx * dx), "um", "um", height=True)
    return [info], r, dz, {"recipe": recipe or None, "comment": comment or None}


def _load(path, info, r, dz, meta):
    ny, nx = info.shape
    z = r.array("<u2", nx * ny, "ZMG heights").reshape(ny, nx).astype(np.float64)
    return measurement(path, z, info, height_scale=dz, vendor="KLA", instrument="KLA Zeta optical profiler", **meta)


channel_format("zmg", "KLA Zeta optical profiler file", (".zmg",), sniff_magic(_MAGIC), "KLA Zeta ZMG", _parse, _load)
