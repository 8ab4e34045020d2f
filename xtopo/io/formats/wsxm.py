"""WSxM images (Nanotec Electronica / UAM): ``.top``, ``.stp``, ``.ch1``, ``.cur``, ...

Layout: a text header that starts ``WSxM file copyright ...`` / ``SxM Image file`` /
``Image header size: N`` (N = header bytes, the data start), with ``[Section]``
blocks of indented ``Key: value`` lines, ending with ``[Header end]``.  Fields used
(``[General Info]`` and ``[Control]``):

* ``Number of columns`` (x pixels), ``Number of rows`` (y pixels);
* ``X Amplitude``/``Y Amplitude`` with unit (physical size);
* ``Z Amplitude`` with unit: the height range of the image;
* ``Image Data Type`` (``short`` when absent, ``integer``, ``float``, ``double``);
* ``[Miscellaneous] Maximum``/``Minimum``: the extreme stored values.

Stored values are little-endian.  Floating-point data are heights in the unit of
``Z Amplitude``; integer data are scaled so that the stored range maps to the
height range: ``height = raw · Z Amplitude / (Maximum − Minimum)``.
Rows are kept in file order (the first is the bottom of the image, as in the NanoScope, MI, NID,
IBW, Park and JPK readers); within a row the values are stored right to left, so ``x`` is
reversed here (Gwyddion's ``wsxmfile.c`` and SurfaceTopography rotate the stored image by 180°).
"""

from __future__ import annotations

import re

from ...errors import ReaderError
from .._binary import BinaryReader, read_bytes
from ._common import (channel_format, channel_info, length_unit, measurement, to_float, to_int, unit_factor,
                      value_unit)

_DTYPES = {"short": "<i2", "integer": "<i4", "int": "<i4", "float": "<f4", "double": "<f8",
           "unsigned char": "u1", "char": "i1"}
_SIZE_RE = re.compile(r"^\s*([-+]?[\d.]+(?:[eE][-+]?\d+)?)\s*(\S*)\s*$")


def _sniff(head: bytes, path: str) -> bool:
    return head.startswith(b"WSxM file copyright") and b"SxM Image file" in head[:200]


def _quantity(path, text, what):
    m = _SIZE_RE.match(text or "")
    if not m:
        raise ReaderError(path, f"cannot parse WSxM {what} {text!r}")
    return to_float(path, m.group(1), what), value_unit(m.group(2))


def _parse(path):
    data = read_bytes(path)
    m = re.search(rb"Image header size:\s*(\d+)", data[:512])
    if not m:
        raise ReaderError(path, "WSxM file without 'Image header size'")
    start = to_int(path, m.group(1).decode(), "Image header size")
    if start > len(data):
        raise ReaderError(path, f"WSxM header size {start} exceeds the file size {len(data)} (truncated)")
    text = data[:start].decode("latin-1", errors="replace")
    if "[Header end]" not in text:
        raise ReaderError(path, "WSxM header has no '[Header end]' line (truncated or corrupt)")
    fields: dict[str, str] = {}
    section = ""
    for line in re.split(r"\r\n|\n|\r", text):
        s = line.strip()
        if s.startswith("[") and s.endswith("]"):
            section = s[1:-1]
            continue
        key, sep, val = s.partition(": ")
        if sep:
            fields.setdefault(f"{section}/{key.strip()}", val.strip())
    nx = to_int(path, fields.get("General Info/Number of columns"), "Number of columns", minimum=1)
    ny = to_int(path, fields.get("General Info/Number of rows"), "Number of rows", minimum=1)
    lx, ux = _quantity(path, fields.get("Control/X Amplitude"), "X Amplitude")
    ly, uy = _quantity(path, fields.get("Control/Y Amplitude"), "Y Amplitude")
    for axis, unit in (("X", ux), ("Y", uy)):
        if length_unit(unit) is None:
            raise ReaderError(path, f"WSxM {axis} Amplitude unit {unit!r} is not a length")
    lunit = length_unit(ux)
    ly *= unit_factor(length_unit(uy), lunit)
    zamp, zunit = _quantity(path, fields.get("General Info/Z Amplitude"), "Z Amplitude")
    kind = fields.get("General Info/Image Data Type", "short").lower()
    if kind not in _DTYPES:
        raise ReaderError(path, f"unsupported WSxM Image Data Type {kind!r}")
    name = fields.get("General Info/Acquisition channel") or "Topography"
    info = channel_info(0, name, (ny, nx), (ly, lx), lunit, zunit)
    if _DTYPES[kind][-2] == "f":
        scale = 1.0
    else:
        vmax = to_float(path, fields.get("Miscellaneous/Maximum"), "Maximum")
        vmin = to_float(path, fields.get("Miscellaneous/Minimum"), "Minimum")
        if vmax == vmin:
            raise ReaderError(path, "WSxM Maximum equals Minimum: the integer height scale is undefined")
        scale = zamp / (vmax - vmin)
    return [info], data, start, _DTYPES[kind], scale, fields


def _load(path, info, data, start, dtype, scale, fields):
    ny, nx = info.shape
    raw = BinaryReader(data, path).array(dtype, nx * ny, what="WSxM image data", at=start).reshape(ny, nx)
    raw = raw[:, ::-1]  # rows are stored right to left
    return measurement(
        path, raw, info, height_scale=scale,
        instrument=fields.get("General Info/Head type") or fields.get("Head Settings/Head Name"),
        vendor="Nanotec Electronica (WSxM)",
        acquisition_date=fields.get("General Info/Acquisition time"),
        software_version=fields.get("Miscellaneous/Saved with version"),
        comment=fields.get("Miscellaneous/Comments") or None,
    )


channel_format("wsxm", "WSxM image (Nanotec Electronica)", (".top", ".stp", ".ch1", ".ch2", ".cur"), _sniff, "WSxM",
               _parse, _load)
