"""Nanonis (SPECS) scan files (``.sxm``).

Layout: a text header of ``:TAG:`` lines, each followed by its value lines, up to
``:SCANIT_END:``; then the two bytes ``0x1A 0x04`` and the data.  Tags used:

* ``:SCAN_PIXELS:`` ``nx ny``; ``:SCAN_RANGE:`` ``Lx Ly`` in metres;
* ``:SCANIT_TYPE:`` e.g. ``FLOAT MSBFIRST`` (big-endian float32);
* ``:SCAN_DIR:`` ``up`` or ``down``; ``:REC_DATE:`` ``dd.mm.yyyy``, ``:REC_TIME:``;
* ``:DATA_INFO:`` a tab-separated table ``Channel Name Unit Direction Calibration
  Offset``, one row per signal; ``Direction`` ``both`` stores a forward and a
  backward image, ``forward``/``backward`` one.

The images follow in table order (forward before backward), ``ny`` lines of ``nx``
values each, already in physical units; pixels not scanned are NaN (masked).
Backward images are stored in acquisition order and are mirrored in x here; for
``down`` scans the lines are reversed, so that ``y`` grows with the line's
position in both cases.
"""

from __future__ import annotations

import re

import numpy as np

from ...errors import ReaderError
from .._binary import BinaryReader, read_bytes
from ._common import channel_format, channel_info, measurement, parse_time, sniff_magic, to_float, to_int, value_unit

_END = b":SCANIT_END:"
_TYPES = {"FLOAT": "f4", "INT": "i4", "UINT": "u4", "DOUBLE": "f8"}


def _parse(path):
    data = read_bytes(path)
    end = data.find(_END, 0, 1 << 22)
    if end < 0:
        raise ReaderError(path, "Nanonis header has no ':SCANIT_END:' (truncated or not an SXM file)")
    mark = data.find(b"\x1a\x04", end)
    if mark < 0:
        raise ReaderError(path, "Nanonis data start marker 0x1A 0x04 is missing (truncated)")
    tags: dict[str, list[str]] = {}
    cur = None
    for line in re.split(r"\r\n|\n|\r", data[:end].decode("latin-1", errors="replace")):
        m = re.fullmatch(r":(.+):", line.strip())
        if m:
            cur = tags.setdefault(m.group(1), [])
        elif cur is not None and line.strip():
            cur.append(line)

    def one(tag):
        return " ".join(v.strip() for v in tags.get(tag, []))

    pix = one("SCAN_PIXELS").split()
    rng = one("SCAN_RANGE").split()
    if len(pix) < 2 or len(rng) < 2:
        raise ReaderError(path, "Nanonis header lacks SCAN_PIXELS or SCAN_RANGE")
    nx = to_int(path, pix[0], "SCAN_PIXELS x", minimum=1)
    ny = to_int(path, pix[1], "SCAN_PIXELS y", minimum=1)
    lx = to_float(path, rng[0], "SCAN_RANGE x")
    ly = to_float(path, rng[1], "SCAN_RANGE y")
    kind = one("SCANIT_TYPE").split()
    if not kind or kind[0].upper() not in _TYPES:
        raise ReaderError(path, f"unsupported Nanonis SCANIT_TYPE {one('SCANIT_TYPE')!r}")
    endian = "<" if len(kind) > 1 and kind[1].upper() == "LSBFIRST" else ">"
    dtype = endian + _TYPES[kind[0].upper()]
    rows = [r.strip().split("\t") for r in tags.get("DATA_INFO", [])]
    if not rows or rows[0][:2] != ["Channel", "Name"]:
        raise ReaderError(path, "Nanonis header lacks the DATA_INFO table")
    head = rows[0]
    infos, backward = [], []
    for row in rows[1:]:
        rec = dict(zip(head, (c.strip() for c in row)))
        sig = rec.get("Name", "")
        unit = value_unit(rec.get("Unit", ""))
        direction = rec.get("Direction", "both").lower()
        dirs = ["forward", "backward"] if direction == "both" else [direction]
        for d in dirs:
            name = f"{sig} ({d})"
            infos.append(channel_info(len(infos), name, (ny, nx), (ly, lx), "m", unit, hint=sig))
            backward.append(d == "backward")
    return infos, dict(data=data, start=mark + 2, dtype=dtype, nx=nx, ny=ny, backward=backward, one=one,
                       down=one("SCAN_DIR").lower() == "down")


def _load(path, info, p):
    i = info.index
    nx, ny = p["nx"], p["ny"]
    item = np.dtype(p["dtype"]).itemsize
    at = p["start"] + i * nx * ny * item
    values = BinaryReader(p["data"], path).array(p["dtype"], nx * ny, what=f"Nanonis channel {info.name!r}",
                                                 at=at).reshape(ny, nx)
    if p["backward"][i]:
        values = values[:, ::-1]
    if p["down"]:
        values = values[::-1, :]
    one = p["one"]
    attrs = dict(
        instrument=f"Nanonis {one('NanonisMain>SW Version')}".strip() if one("NanonisMain>SW Version") else None,
        vendor="SPECS Nanonis",
        acquisition_time=parse_time(f"{one('REC_DATE')} {one('REC_TIME')}", "%d.%m.%Y %H:%M:%S"),
        bias_V=to_float(path, one("BIAS"), "BIAS", default=float("nan")),
        scan_direction=one("SCAN_DIR") or None,
        comment=one("COMMENT") or None,
    )
    attrs = {k: v for k, v in attrs.items() if not (isinstance(v, float) and np.isnan(v))}
    return measurement(path, np.ascontiguousarray(values), info, **attrs)


channel_format("sxm", "Nanonis scan (.sxm)", (".sxm",), sniff_magic(b":NANONIS_VERSION:"), "Nanonis SXM", _parse, _load)
