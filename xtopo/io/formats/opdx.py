"""Bruker Vision64 OPDx files ("VCA DATA"; Dektak stylus profilers, Contour GT).

Layout (little endian; see Gwyddion's ``dektakvca.c``): the magic
``"VCA DATA\\x01\\x00\\x00\\x55"`` followed by a tree of items ``name type
payload`` where ``name`` is a uint32-length-prefixed UTF-8 string and ``type`` a
byte.  Containers (0x7D, 0x46, 0x47) hold a variable-length size (a byte
saying 1/2/4, then the size) and nested items terminated by type 0x7F, then two
bytes.  Scalars: 0x01 bool, 0x04/0x05 int16, 0x06/0x07 int32, 0x0A/0x0B int64,
0x0C float32, 0x0D float64.  0x12 string (varlen + UTF-8), 0x13 quantity
(varlen: float64 value, name, symbol), 0x18 unit (varlen: name, symbol, float64
value, 12 bytes), 0x15 time stamp (9 bytes), 0x0E type id / 0x40 double array /
0x42 string list (type name + varlen payload), 0x00/0x45 matrices, 0x7C
position data.  A line profile lives under ``/1D_Data/<channel>/``:
``NumPoints``, ``Extent`` (quantity: first-to-last distance), ``DataScale``
(quantity) and ``Array`` (float64 raw values after a 5-byte prefix);
``height = raw * DataScale``.  Areal maps live under ``/2D_Data/<channel>/``
with ``Dimension1/2Points``/``Extent`` and a float32 ``Matrix``.
"""

from __future__ import annotations

import re


from ...conventions import length_factor, make_measurement, normalize_units
from .._binary import BinaryReader, check_count
from ._common import ChannelInfo, channel_format, parse_time, sniff_magic

_MAGIC = b"VCA DATA\x01\x00\x00\x55"
_SCALARS = {0x01: "?", 0x04: "h", 0x05: "H", 0x06: "i", 0x07: "I", 0x0A: "q", 0x0B: "Q", 0x0C: "f", 0x0D: "d"}
_CONTAINERS = (0x7D, 0x46, 0x47)
_TERMINATOR = 0x7F
_MAX_DEPTH = 32
_ARRAY_PREFIX = 5


class _Quantity(tuple):
    """``(value, symbol)`` of a quantity or unit item."""


def _name(r):
    n = r.unpack("I", "item name length")
    return r.read(n, "item name").decode("utf-8", errors="replace")


def _varlen(r):
    width = r.unpack("B", "size width")
    if width not in (1, 2, 4):
        raise r.error(f"invalid OPDx size width {width} at offset {r.pos - 1}")
    return r.unpack({1: "B", 2: "H", 4: "I"}[width], "item size")


def _items(r, out, prefix, end, depth):
    if depth > _MAX_DEPTH:
        raise r.error("OPDx containers nested too deeply")
    while r.pos < end:
        name = _name(r)
        typ = r.unpack("B", "item type")
        path = f"{prefix}/{name}"
        if typ == _TERMINATOR:
            return
        if typ in _CONTAINERS:
            size = _varlen(r)
            stop = r.pos + size
            r.need(size, f"container {path}")
            _items(r, out, path, stop, depth + 1)
            r.seek(stop)
        elif typ in _SCALARS:
            out[path] = r.unpack(_SCALARS[typ], path)
        elif typ == 0x12:
            out[path] = r.read(_varlen(r), path).decode("utf-8", errors="replace")
        elif typ in (0x13, 0x18):  # quantity: value, name, symbol; unit: name, symbol, value
            size = _varlen(r)
            stop = r.pos + size
            value = r.unpack("d", path) if typ == 0x13 else None
            _name(r)
            symbol = _name(r)
            out[path] = _Quantity((r.unpack("d", path) if value is None else value, symbol))
            r.seek(stop)
        elif typ == 0x15:
            r.read(9, path)
        elif typ in (0x0E, 0x40, 0x42, 0x7C, 0x45, 0x00):
            _name(r)  # type name
            if typ == 0x00:
                r.unpack("I", path)
                _name(r)
            size = _varlen(r)
            r.need(size, path)
            out[path] = ("blob", r.pos, size)
            r.pos += size
        else:
            raise r.error(f"unknown OPDx item type 0x{typ:02x} at offset {r.pos - 1}")


def _parse(path):
    r = BinaryReader.from_file(path, magic=_MAGIC, not_this="not a Bruker OPDx file (magic 'VCA DATA' missing)")
    data = r.data
    r.seek(len(_MAGIC))
    tree = {}
    _items(r, tree, "", len(data), 0)
    profiles = _profiles(r, tree)
    infos = [ChannelInfo(i, name, (n,), (n * dx,), xu, xu) for i, (name, n, dx, xu, _s, _b) in enumerate(profiles)]
    return infos, r, tree, profiles


def _quantity(r, tree, key):
    q = tree.get(key)
    if not isinstance(q, _Quantity):
        raise r.error(f"OPDx file lacks the quantity {key!r}")
    return float(q[0]), normalize_units(q[1])


def _profiles(r, tree):
    """Channel descriptions of the 1D profiles (name, n, spacing, unit, scale, blob)."""
    out = []
    for key, val in tree.items():
        if key.startswith("/1D_Data/") and key.endswith("/Array") and isinstance(val, tuple) and val[0] == "blob":
            prefix = key[:-len("/Array")]
            n = int(tree.get(f"{prefix}/NumPoints", 0))
            extent, xu = _quantity(r, tree, f"{prefix}/Extent")
            scale, zu = _quantity(r, tree, f"{prefix}/DataScale")
            if n < 2 or not extent > 0:
                raise r.error(f"invalid OPDx profile {prefix}: {n} points over {extent} {xu}")
            # Extent is the distance from the first to the last point
            out.append((prefix.split("/")[2], n, extent / (n - 1), xu, scale * length_factor(zu, xu), val))
    return out


def _load(path, info, r, tree, profiles):
    name, n, dx, xu, scale, (_b, off, size) = profiles[info.index]
    check_count(path, n, 8, size - _ARRAY_PREFIX, f"OPDx profile {name!r}")
    z = r.array("f8", n, f"OPDx profile {name!r}", at=off + _ARRAY_PREFIX) * scale
    meta = {k.rsplit("/", 1)[-1]: v for k, v in tree.items() if k.startswith("/MetaData/") and isinstance(v, str)}
    when = parse_time(f"{meta.get('Date', '')} {meta.get('Time', '')}",
                      "%m/%d/%Y %H:%M:%S", "%m/%d/%Y %I:%M:%S %p", "%Y-%m-%d %H:%M:%S", "%d.%m.%Y %H:%M:%S")
    tip_radius = None
    m = re.search(r"Radius:\s*([0-9.]+)\s*(\S+)", meta.get("StylusType", ""))
    if m and float(m.group(1)) > 0:
        tip_radius = float(m.group(1)) * length_factor(normalize_units(m.group(2)), xu)
    return make_measurement(z, spacing=dx, units=xu, name=name, vendor="Bruker",
                            instrument=meta.get("InstrumentName") or "Bruker Dektak (Vision64)",
                            acquisition_time=when, tip_radius=tip_radius, original_units=xu)


channel_format("opdx", "Bruker Vision64 OPDx (Dektak) profile", (".opdx",), sniff_magic(_MAGIC), "Bruker OPDx", _parse,
               _load, empty="OPDx file holds no 1D profile (areal OPDx maps are not supported yet)")
