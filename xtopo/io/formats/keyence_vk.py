"""Keyence VK4 and VK6/VK7 files (VK-X laser scanning confocal microscopes).

Layout (little endian; facts from SurfaceTopography's ``VK.py``, surfalize's ``vk.py`` and Gwyddion's
``keyence.c``):

* ``VK4``: the magic ``"VK4_"``, 4 bytes of DLL version, 4 zero bytes; then an offset table of
  uint32 absolute offsets: measurement conditions, colour peak, colour + light, light (three),
  height (three), four thumbnails, assembly, line measure, line thickness, string data (and, in
  VK4, one more entry).
* Measurement conditions (uint32 fields at the first offset): size, year, month, day, hour, minute,
  second, minutes from UTC (int32), ... ``lens_mag`` (field 24, magnification × 10), ... ``x`` and
  ``y`` length per pixel (fields 42, 43, in pm) and the height per digit (field 44, in pm).
* An image (height or light) at its offset: ``width, height, bit depth (8/16/32), compression,
  byte size, palette min, palette max`` (uint32), a 768-byte palette, then ``height × width``
  unsigned integers of that depth, row by row. Heights are ``digit × height per digit`` pm; an
  absent image has offset 0.
* String data: uint32 character count and UTF-16 text of the title, then of the lens name.
* ``VK6``/``VK7``: a three-byte magic ``"VK6"``/``"VK7"`` and a zip archive whose member
  ``Vk4File`` holds VK4 content as above.

The size is ``N × pixel length`` (the pixel convention of SurfaceTopography and surfalize).
Channels: the height images (``Height``, ``Height 2``, ``Height 3``) and the laser intensity
(``Light``, a signal without length unit).
"""

from __future__ import annotations

import numpy as np

from ...errors import ReaderError
from .._binary import BinaryReader, read_bytes
from .._zip import open_zip
from ._common import channel_format, channel_info, iso_time, measurement, zip_member

_OFFSETS = ("conditions", "color_peak", "color_light", "light", "light2", "light3", "height", "height2",
            "height3", "thumb_color_peak", "thumb_color", "thumb_light", "thumb_height", "assemble",
            "line_measure", "line_thickness", "strings")
_IMAGES = (("height", "Height"), ("height2", "Height 2"), ("height3", "Height 3"), ("light", "Light"))
_DEPTHS = {8: "<u1", 16: "<u2", 32: "<u4"}
_PALETTE = 768


def _sniff_vk4(head: bytes, path: str) -> bool:
    return head.startswith(b"VK4_") and head[8:12] == b"\0\0\0\0"


def _sniff_vk67(head: bytes, path: str) -> bool:
    return head[:3] in (b"VK6", b"VK7") and b"PK\x03\x04" in head


def _vk4_bytes(path) -> bytes:
    data = read_bytes(path)
    if data[:3] in (b"VK6", b"VK7"):
        with open_zip(path, "Keyence VK6/VK7") as zf:
            data = zip_member(path, zf, "Vk4File", "Keyence VK6/VK7",
                              "the Keyence VK6/VK7 archive has no member 'Vk4File'")
    if not data.startswith(b"VK4_"):
        raise ReaderError(path, "not a Keyence VK4 file (magic 'VK4_' missing)")
    return data


def _image_header(r, offset, what):
    width, height, depth, _compression, nbytes = r.unpack("5I", f"{what} image header", at=offset)
    if depth not in _DEPTHS or width == 0 or height == 0:
        raise r.error(f"invalid Keyence {what} image: {width} x {height} pixels of {depth} bits")
    if nbytes != width * height * depth // 8:
        raise r.error(f"Keyence {what} image says {nbytes} bytes for {width} x {height} pixels of {depth} bits")
    return width, height, depth, offset + 28 + _PALETTE


def _utf16(r, what):
    n = r.unpack("I", f"{what} length")
    return r.read(2 * n, what).decode("utf-16-le", errors="replace").strip("\0 ")


def _parse(path):
    r = BinaryReader(_vk4_bytes(path), path, "<")
    offsets = dict(zip(_OFFSETS, r.unpack(f"{len(_OFFSETS)}I", "VK4 offset table", at=12)))
    cond = r.unpack("45I", "VK4 measurement conditions", at=offsets["conditions"])
    dx, dy, dz = cond[42], cond[43], cond[44]  # pm per pixel and per digit
    if not (dx > 0 and dy > 0 and dz > 0):
        raise r.error(f"invalid Keyence pixel size {dx} x {dy} pm or height step {dz} pm")
    infos, images = [], []
    for key, name in _IMAGES:
        if offsets[key]:
            nx, ny, depth, start = _image_header(r, offsets[key], name)
            is_height = key.startswith("height")
            infos.append(channel_info(len(infos), name, (ny, nx), (ny * dy, nx * dx), "pm", "pm" if is_height else "1",
                                      height=is_height))
            images.append((start, depth))
    if not infos:
        raise r.error("the Keyence file holds no height image")
    meta = {"acquisition_time": iso_time(*cond[1:7]), "objective_magnification": cond[24] / 10 or None,
            "scale_z": dz}
    if offsets["strings"]:
        r.seek(offsets["strings"])
        meta["title"] = _utf16(r, "title") or None
        meta["objective"] = _utf16(r, "lens name") or None
    return infos, r, images, meta, dz


def _load(path, info, r, images, meta, dz):
    start, depth = images[info.index]
    ny, nx = info.shape
    values = r.array(_DEPTHS[depth], nx * ny, f"Keyence {info.name} image", at=start).reshape(ny, nx)
    is_height = info.height_units == "pm"
    return measurement(path, values.astype(np.float64), info, height_scale=dz if is_height else 1.0, vendor="Keyence",
                       instrument="Keyence VK-X laser scanning confocal microscope",
                       acquisition_time=meta["acquisition_time"], objective=meta.get("objective"),
                       objective_magnification=meta["objective_magnification"],
                       title=meta.get("title"))


channel_format("vk4", "Keyence VK4 laser confocal microscope file", (".vk4",), _sniff_vk4, "Keyence VK", _parse, _load)
channel_format("vk6", "Keyence VK6/VK7 laser confocal microscope file (zip with VK4 content)", (".vk6", ".vk7"),
               _sniff_vk67, "Keyence VK", _parse, _load)
