"""Agilent / Molecular Imaging PicoView images (``.mi``).

Layout: a text header of lines ``key value`` with the key in the first 14
characters (``fileType Image``, ``xPixels``, ``yPixels``, ``xLength``/``yLength`` in
metres, ``dateAcquired``), then one block per buffer (channel) starting with
``bufferLabel`` and holding ``direction``, ``bufferRange`` and ``bufferUnit``.  The
header ends with ``data BINARY`` (int16) or ``data BINARY_32`` (int32) and a newline;
the buffers follow one after the other, ``yPixels`` rows of ``xPixels`` values each,
little-endian.  A raw value maps to ``raw / 2^(bits-1) · bufferRange`` in
``bufferUnit`` (the full signed range spans ``±bufferRange``).

Rows are kept in file order (``y`` grows with the row number in the file).
"""

from __future__ import annotations

import re

from ...errors import ReaderError
from .._binary import BinaryReader, read_bytes
from ._common import (channel_format, channel_info, measurement, parse_time, sniff_magic, to_float, to_int, unique_name,
                      value_unit)

_DATA_RE = re.compile(rb"\ndata {2,}(BINARY_32|BINARY|ASCII\w*)\r?\n")


def _parse(path):
    data = read_bytes(path)
    m = _DATA_RE.search(data, 0, 1 << 22)
    if not m:
        raise ReaderError(path, "MI header has no 'data BINARY' line (truncated or not an MI image)")
    kind = m.group(1).decode()
    if kind.startswith("ASCII"):
        raise ReaderError(path, "ASCII MI data are not supported; export the image as binary")
    text = data[:m.start()].decode("latin-1", errors="replace")
    glob: dict[str, str] = {}
    buffers: list[dict[str, str]] = []
    for line in re.split(r"\r\n|\n|\r", text):
        key, value = line[:14].strip(), line[14:].strip()
        if not key:
            continue
        if key == "bufferLabel":
            buffers.append({})
        (buffers[-1] if buffers else glob).setdefault(key, value)
    if glob.get("fileType", "").lower() != "image":
        raise ReaderError(path, f"MI file type {glob.get('fileType')!r} is not an image (spectroscopy is not read)")
    nx = to_int(path, glob.get("xPixels"), "xPixels", minimum=1)
    ny = to_int(path, glob.get("yPixels"), "yPixels", minimum=1)
    lx = to_float(path, glob.get("xLength"), "xLength")
    ly = to_float(path, glob.get("yLength"), "yLength")
    bits = 32 if kind == "BINARY_32" else 16
    infos, scales = [], []
    seen = set()
    for i, b in enumerate(buffers):
        label = b.get("bufferLabel") or f"buffer {i}"
        if b.get("direction", "").lower() == "retrace":
            label += " (retrace)"
        name = unique_name(label, seen)
        unit = value_unit(b.get("bufferUnit", ""))
        rng = to_float(path, b.get("bufferRange"), f"bufferRange of buffer {i}")
        infos.append(channel_info(i, name, (ny, nx), (ly, lx), "m", unit))
        scales.append(rng / float(1 << (bits - 1)))
    return infos, dict(data=data, start=m.end(), bits=bits, glob=glob, scales=scales, nx=nx, ny=ny)


def _load(path, info, p):
    i = info.index
    nx, ny = p["nx"], p["ny"]
    item = p["bits"] // 8
    r = BinaryReader(p["data"], path)
    raw = r.array("<i4" if item == 4 else "<i2", nx * ny, what=f"MI buffer {info.name!r}",
                  at=min(p["start"] + i * nx * ny * item, len(p["data"]))).reshape(ny, nx)
    scale = p["scales"][i]
    g = p["glob"]
    return measurement(
        path, raw, info, height_scale=scale,
        instrument=f"Agilent / Molecular Imaging AFM ({g['version']})" if g.get("version") else None,
        vendor="Agilent Technologies (Molecular Imaging)",
        acquisition_time=parse_time(g.get("dateAcquired", ""), "%a %b %d %H:%M:%S %Y"),
        imaging_mode=g.get("mode") or None,
    )


channel_format("mi", "Agilent / Molecular Imaging PicoView image (.mi)", (".mi",),
               sniff_magic(b"fileType      Image", b"fileType      Spectroscopy"), "MI", _parse, _load)
