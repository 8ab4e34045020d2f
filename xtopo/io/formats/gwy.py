"""Gwyddion native files (``.gwy``): a serialized ``GwyContainer``.

Layout (Gwyddion user guide, "GWY file format"; all numbers little-endian):
the magic ``GWYP``, then one serialized object: its type name (NUL-terminated),
a uint32 byte size of its components, and the components.  A component is a
NUL-terminated name, a one-character type and a value: ``b``/``c`` one byte,
``i`` int32, ``q`` int64, ``d`` float64, ``s`` NUL-terminated string, ``o`` an
object; the upper-case letters are arrays of those, preceded by a uint32 count.

Image channels are ``GwyDataField`` objects stored under ``/<n>/data`` with the
title in ``/<n>/data/title``.  A data field holds ``xres``, ``yres``, ``xreal``,
``yreal`` (physical size, in the unit of ``si_unit_xy``), ``si_unit_xy`` and
``si_unit_z`` (``GwySIUnit`` objects with a ``unitstr``) and ``data``
(``xres·yres`` float64, row by row).  Gwyddion keeps values in base SI units;
a field with an empty lateral unit is read in ``file_units=`` if given, else in metres, flagged
``units_assumed`` with a :class:`~xtopo.errors.MetadataWarning`.
Rows are kept in file order (Gwyddion's first row is the top of the image).
"""

from __future__ import annotations

import re

import numpy as np

from ...errors import ReaderError
from .._binary import BinaryReader, check_count
from .._generic import stated_or_given
from ._common import channel_format, channel_info, length_unit, measurement, metres_assumed, sniff_magic, value_unit

_MAGIC = b"GWYP"
_MAX_DEPTH = 64
_SCALARS = {"b": ("<u1", 1), "c": ("<u1", 1), "i": ("<i4", 4), "q": ("<i8", 8), "d": ("<f8", 8)}


class _Parser:
    def __init__(self, r: BinaryReader):
        self.r, self.path = r, r.path

    def cstr(self, what: str) -> str:
        r = self.r
        end = r.data.find(b"\0", r.pos)
        if end < 0:
            raise r.error(f"unterminated string ({what}) at offset {r.pos}")
        s = r.data[r.pos:end].decode("utf-8", errors="replace")
        r.pos = end + 1
        return s

    def obj(self, depth: int = 0) -> tuple[str, dict]:
        if depth > _MAX_DEPTH:
            raise self.r.error(f"objects nested deeper than {_MAX_DEPTH} levels (corrupt)")
        name = self.cstr("object type name")
        size = self.r.unpack("I", "object size")
        end = self.r.pos + size
        if end > len(self.r):
            raise self.r.error(f"{name} object of {size} bytes extends beyond the end of the file (truncated)")
        comps = {}
        while self.r.pos < end:
            key = self.cstr(f"{name} component name")
            typ = self.r.read(1, "component type").decode("latin-1")
            comps[key] = self.value(typ, depth, f"{name}.{key}")
        if self.r.pos != end:
            raise self.r.error(f"{name} object components overrun its declared size")
        return name, comps

    def value(self, typ: str, depth: int, what: str):
        r = self.r
        if typ in _SCALARS:
            dt, size = _SCALARS[typ]
            return np.frombuffer(r.read(size, what), dtype=dt)[0].item()
        if typ == "s":
            return self.cstr(what)
        if typ == "o":
            return self.obj(depth + 1)
        low = typ.lower()
        if low in _SCALARS or low in "so":
            n = r.unpack("I", f"{what} array length")
            if low in _SCALARS:
                return r.array(_SCALARS[low][0], n, what)
            check_count(self.path, n, 1, len(r) - r.pos, what)
            return [self.cstr(what) if low == "s" else self.obj(depth + 1) for _ in range(n)]
        raise r.error(f"unknown component type {typ!r} in {what}")


def _unit(obj) -> str:
    if isinstance(obj, tuple) and len(obj) == 2 and isinstance(obj[1], dict):
        return str(obj[1].get("unitstr", "") or "")
    return ""


def _parse(path, file_units=None):
    not_this = "not a Gwyddion GWY file (no GWYP magic; the old GWYO format is not read)"
    p = _Parser(BinaryReader.from_file(path, magic=_MAGIC, not_this=not_this))
    p.r.seek(4)
    name, root = p.obj()
    if name != "GwyContainer":
        raise ReaderError(path, f"GWY top-level object is {name!r}, not a GwyContainer")
    keys = sorted((int(key.split("/")[1]), key) for key, val in root.items()
                  if re.fullmatch(r"/\d+/data", key) and isinstance(val, tuple) and val[0] == "GwyDataField")
    infos, fields = [], []
    for n, key in keys:
        f = root[key][1]
        nx, ny = f.get("xres"), f.get("yres")
        if not (isinstance(nx, int) and isinstance(ny, int) and nx > 0 and ny > 0):
            raise ReaderError(path, f"GWY field {key} has invalid size {nx!r} x {ny!r}")
        arr = f.get("data")
        if not isinstance(arr, np.ndarray) or arr.size != nx * ny:
            raise ReaderError(path, f"GWY field {key} holds {getattr(arr, 'size', 0)} values, not {nx}x{ny}")
        uxy, uz = value_unit(_unit(f.get("si_unit_xy"))), value_unit(_unit(f.get("si_unit_z")))
        lunit = length_unit(uxy)
        assumed = lunit is None
        lunit = stated_or_given(path, lunit, file_units, "file_units") or "m"
        zunit = uz if uz else (lunit if assumed else "")
        title = root.get(f"/{n}/data/title")
        title = title if isinstance(title, str) and title else f"channel {n}"
        lx, ly = float(f.get("xreal", nx)), float(f.get("yreal", ny))
        only = True if len(keys) == 1 else None  # a lone channel is the topography
        infos.append(channel_info(len(infos), title, (ny, nx), (ly, lx), lunit, zunit, height=only))
        fields.append(dict(key=key, number=n, data=arr, lunit=lunit, zunit=zunit, assumed=assumed,
                           meta=root.get(f"/{n}/meta")))
    if not infos:
        raise ReaderError(path, "the GWY file holds no image channel (/N/data)")
    return infos, fields


def _load(path, info, fields, file_units=None):
    f = fields[info.index]
    values = np.array(f["data"], dtype=np.float64).reshape(info.shape)
    attrs = dict(vendor="Gwyddion", gwy_key=f["key"])
    meta = f["meta"]
    if isinstance(meta, tuple) and isinstance(meta[1], dict):
        for k, v in meta[1].items():
            if isinstance(v, str) and len(attrs) < 64:
                attrs[f"meta_{re.sub(r'[^A-Za-z0-9_]+', '_', k).strip('_')}"] = v
    if f["assumed"] and file_units is None:
        attrs.update(metres_assumed(path, "Gwyddion data field"))
    return measurement(path, values, info, value_units=f["zunit"] or f["lunit"], **attrs)


channel_format("gwy", "Gwyddion native file (GwyContainer)", (".gwy",), sniff_magic(_MAGIC), "GWY", _parse, _load,
               options=("file_units",))
