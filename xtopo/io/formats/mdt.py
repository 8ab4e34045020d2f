"""NT-MDT ``.mdt`` files (Solver / Ntegra AFMs, Nova software): a container of frames.

Layout (little endian; facts from Gwyddion's ``nt-mdt.c`` and SurfaceTopography's ``MDT.py``):

* File header (33 bytes): magic ``01 B0 93 FF``, frame data size (uint32), 4 reserved bytes, the
  index of the last frame (uint16), 18 reserved bytes and one unused byte.
* Each frame: a 22-byte header ``size`` (uint32, the whole frame), ``type`` (uint16; 0 = scanned
  data), version (big-endian uint16), year, month, day, hour, minute, second, ``var_size`` (uint16);
  the body fills the rest of ``size``.
* A scanned-data frame: axis scales ``offset, step`` (float32) and unit code (int16) for x, y, z;
  scan variables ``adc_index`` (uint8: 0 Height, 1 DFL, 2 Lateral F, ...), mode (uint8), points in
  x and y (uint16); the rest of ``var_size`` (36 bytes parsed); then the frame mode ``mode, nx, ny,
  n_dots`` (uint16; the raster size), ``14 + 16 n_dots`` bytes of dots if any, and ``ny × nx``
  int16 values, the bottom line first (rows are flipped so that the first row is the top line, as
  Gwyddion shows it). Values are ``raw × z step + z offset`` in the z unit (a zero step: raw).
  Unit codes: -5 m, -4 cm, -3 mm, -2 µm, -1 nm, 0 Å.

Spectroscopy, text and multidimensional (MDA) frames are skipped. The size is ``N × |step|``.
"""

from __future__ import annotations

import math

import numpy as np

from .._binary import BinaryReader, check_count
from ._common import channel_format, channel_info, iso_time, measurement, sniff_magic

_MAGIC = b"\x01\xb0\x93\xff"
_HEADER = 33
_FRAME_HEADER = 22
_SCANNED = 0
_PARSED_VARS = 36
_UNITS = {-5: "m", -4: "cm", -3: "mm", -2: "um", -1: "nm", 0: "angstrom"}
_SIGNALS = ("Height", "DFL", "Lateral F", "Bias V", "Current", "FB-Out", "MAG", "MAG*Sin", "MAG*Cos", "RMS",
            "CalcMag", "Phase1", "Phase2", "CalcPhase", "Ex1", "Ex2", "HvX", "HvY", "Snap Back")


def _frames(path):
    r = BinaryReader.from_file(path, magic=_MAGIC, not_this="not an NT-MDT file (magic 01 B0 93 FF missing)")
    last = r.unpack("H", "MDT frame count", at=12)
    pos = _HEADER
    out = []
    for _ in range(last + 1):
        size, typ = r.unpack("IH", "MDT frame header", at=pos)
        if size < _FRAME_HEADER or pos + size > len(r):
            raise r.error(f"MDT frame at offset {pos} declares {size} bytes; the file has {len(r) - pos} left")
        if typ == _SCANNED:
            frame = _scanned(r, pos, size)
            if frame is not None:
                out.append(frame)
        pos += size
    seen, infos = set(), []
    for i, (name, shape, size, xu, zu, *_rest) in enumerate(out):
        label = name if name.lower() not in seen else f"{name} #{i}"
        seen.add(label.lower())
        infos.append(channel_info(i, label, shape, size, xu, zu, hint=name))
    return infos, r, out


def _scanned(r, pos, size):
    """``(name, shape, size, xy unit, z unit, z step, z offset, data offset, date)`` or None if not a height map."""
    date = iso_time(*r.unpack("6H", "MDT frame date", at=pos + 8))
    var_size = r.unpack("H", "MDT variables size", at=pos + 20)
    if var_size < _PARSED_VARS:
        raise r.error(f"MDT scanned frame at offset {pos}: variables section of {var_size} bytes is too short")
    scales = r.unpack("ffhffhffh", "MDT axis scales", at=pos + _FRAME_HEADER)
    adc = r.unpack("B", "MDT ADC index", at=pos + _FRAME_HEADER + 30)
    _mode, nx, ny, dots = r.unpack("4H", "MDT frame mode", at=pos + _FRAME_HEADER + var_size)
    if dots:
        r.seek(r.pos + 14 + 16 * dots)
    start = r.pos
    xu, zu = _UNITS.get(scales[2]), _UNITS.get(scales[8])
    if xu is None or zu is None or nx == 0 or ny == 0:
        return None
    check_count(r.path, nx * ny, 2, pos + size - start, f"MDT frame at offset {pos}")
    dx, dy = abs(scales[1]), abs(scales[4])
    if not (math.isfinite(dx) and math.isfinite(dy) and dx > 0 and dy > 0):
        raise r.error(f"MDT scanned frame at offset {pos} has an invalid step {dx} x {dy}")
    zstep = scales[7] if math.isfinite(scales[7]) and scales[7] != 0 else 1.0
    zoff = scales[6] if math.isfinite(scales[6]) else 0.0
    name = _SIGNALS[adc] if adc < len(_SIGNALS) else f"ADC {adc}"
    return name, (ny, nx), (ny * dy, nx * dx), xu, zu, zstep, zoff, start, date


def _load(path, info, r, frames):
    _name, (ny, nx), size, xu, zu, zstep, zoff, start, date = frames[info.index]
    raw = r.array("<i2", nx * ny, f"MDT frame {info.name!r}", at=start).reshape(ny, nx)[::-1]
    values = raw.astype(np.float64) * zstep + zoff
    return measurement(path, values, info, vendor="NT-MDT", acquisition_time=date,
                       instrument="NT-MDT scanning probe microscope")


channel_format("mdt", "NT-MDT scanning probe microscope file (scanned frames)", (".mdt",), sniff_magic(_MAGIC),
               "NT-MDT", _frames, _load,
               empty="the MDT file holds no scanned height image (only spectroscopy, text or MDA frames)")
