"""Digital Surf Mountains documents (``.mnt``): an OLE compound file.

The stream ``ScopedContents`` starts with its remaining size (uint64) and holds
a tree of TLV entries ``tag:uint16 size:uint64 payload`` (little endian).  Text
payloads are a 0x04 marker byte followed by UTF-16 LE.  Path to the measured
surfaces: main (tag 1) → contents (0x2BD) → document (2) → objects (1), whose
entries carry an extra uint64 size prefix; each object has a class (1 → 1:
uint32 number), a body (2) and a GUID (3).  Only class 9012 (original
surface) holds heights: its body has a header (0xFFFF; 4: title) and a
measurement object (1, class 9062) whose body is: 0xFFFF → {0xFFFF grid →
{0xFFFF header → 0xFFFF → 1: name, 1: x axis, 2: y axis, 3: mask}, 1: height
array (class 9049), 2: height axis}.  A lateral axis is 0xFFFF → {0xFFFF
scale, 1: number of points (uint32)}; a scale is {1: step (float64), 2: unit,
3: display unit, 5: origin (float64, display unit)}; the height axis is
{0xFFFF scale, 1: min count, 2: max count}.  Arrays are {1: class, 2: {1:
count (uint32), 2: data}} with data = total bytes (uint64) + blocks of
``offset:uint64 n:uint32 compressed:uint32 zlib-stream`` (offset and n in
elements).  Heights are int32 counts, x fastest: ``h = count * step + origin``.
The optional mask (class 9056: {1: width, 2: height, 5: uint8 array}) has a
one-pixel border; 9 marks measured points.
"""

from __future__ import annotations

import struct
import zlib

import numpy as np

from ...conventions import length_factor, make_measurement, normalize_units
from ...errors import ReaderError
from .._binary import MAX_PIXELS
from .._ole import OLE_MAGIC, OleFile
from .._xml import child_text, parse_xml
from .._zip import MAX_RATIO
from ._common import ChannelInfo, channel_format

_SURFACE, _SURFACE_DATA, _MASK, _HEIGHTS = 9012, 9062, 9056, 9049
_MEASURED = 9
_HEAD = struct.Struct("<HQ")


def _sniff(head: bytes, path: str) -> bool:
    if not head.startswith(OLE_MAGIC):
        return False
    if "ScopedContents".encode("utf-16-le") in head:
        return True
    return OleFile(path).exists("ScopedContents")  # the directory may lie anywhere in the file: look it up


def _tlv(buf: bytes, prefixed: bool = False) -> list:
    """``[(tag, payload), ...]`` of a TLV buffer; stops at the first entry that does not fit."""
    out, pos, n = [], 0, len(buf)
    while True:
        if prefixed:
            pos += 8
        if pos + _HEAD.size > n:
            return out
        tag, size = _HEAD.unpack_from(buf, pos)
        pos += _HEAD.size
        if size > n - pos:
            return out
        out.append((tag, buf[pos:pos + size]))
        pos += size


def _get(buf, *tags):
    """Payload at the path ``tags`` (first match at each level), or ``None``."""
    for tag in tags:
        if buf is None:
            return None
        buf = next((p for t, p in _tlv(buf) if t == tag), None)
    return buf


def _num(buf, fmt):
    if buf is None or len(buf) != struct.calcsize(fmt):
        return None
    return struct.unpack(fmt, buf)[0]


def _text(buf):
    if not buf or buf[0] != 4 or (len(buf) - 1) % 2:
        return None
    return bytes(buf[1:]).decode("utf-16-le", errors="replace").rstrip("\0")


def _class(obj):
    return _num(_get(obj, 1, 1), "<I")


def _scale(path, buf):
    s = {"step": _num(_get(buf, 1), "<d"), "unit": _text(_get(buf, 2)), "display": _text(_get(buf, 3)),
         "origin": _num(_get(buf, 5), "<d")}
    if s["step"] is None or not s["unit"]:
        raise ReaderError(path, "incomplete axis definition in the Mountains document")
    return s


def _blocks(path, data, count, max_bytes):
    """Decompress a block array of ``count`` elements (bounded by ``max_bytes``)."""
    if data is None or len(data) < 8 or count <= 0:
        raise ReaderError(path, "missing or truncated data array in the Mountains document")
    nbytes = struct.unpack_from("<Q", data, 0)[0]
    if nbytes % count or nbytes // count not in (1, 2, 4, 8) or nbytes > max_bytes:
        raise ReaderError(path, f"data array of {nbytes} bytes does not fit {count} elements")
    if nbytes > MAX_RATIO * len(data) + (1 << 16):
        raise ReaderError(path, f"data array claims {nbytes} bytes from {len(data)} compressed bytes, more "
                                "than zlib can produce (corrupt file or decompression bomb)")
    esize = nbytes // count
    out = bytearray(nbytes)
    done, pos = 0, 8
    while pos < len(data):
        if pos + 16 > len(data):
            raise ReaderError(path, "truncated block header in a Mountains data array")
        offset, n, csize = struct.unpack_from("<QII", data, pos)
        pos += 16
        start, want = offset * esize, n * esize
        if start + want > nbytes or csize > len(data) - pos:
            raise ReaderError(path, "inconsistent block in a Mountains data array")
        d = zlib.decompressobj()
        block = d.decompress(bytes(data[pos:pos + csize]), want)  # capped: no zip bomb
        if len(block) != want:
            raise ReaderError(path, "a Mountains data block decompresses to the wrong size")
        out[start:start + want] = block
        done += want
        pos += csize
    if done != nbytes:
        raise ReaderError(path, f"Mountains data array has {done} of {nbytes} bytes")
    return bytes(out), esize


def _surfaces(path, ole):
    sc = ole.read_stream("ScopedContents")
    main = _get(sc[8:], 1)
    if main is None:
        raise ReaderError(path, "Mountains document without a main container")
    objects = _get(main, 0x2BD, 2, 1)
    out = []
    for tag, obj in _tlv(objects or b"", prefixed=True):
        if tag != 1 or _class(obj) != _SURFACE:
            continue
        body = _get(obj, 2)
        meas = _get(body, 1)
        if meas is None or _class(meas) != _SURFACE_DATA:
            continue
        m = _get(_get(meas, 2), 0xFFFF)
        grid = _get(m, 0xFFFF)
        xa, ya = _get(grid, 1, 0xFFFF), _get(grid, 2, 0xFFFF)
        heights, zaxis = _get(m, 1), _get(m, 2)
        if xa is None or ya is None or heights is None or zaxis is None or _class(heights) != _HEIGHTS:
            continue
        zs = _scale(path, _get(zaxis, 0xFFFF))
        unit = zs["display"] or zs["unit"]
        try:
            zu = normalize_units(unit)
        except Exception:
            continue  # not a height map (intensity, ...)
        xs, ys = _scale(path, _get(xa, 0xFFFF)), _scale(path, _get(ya, 0xFFFF))
        nx, ny = _num(_get(xa, 1), "<I"), _num(_get(ya, 1), "<I")
        if not nx or not ny or nx * ny > MAX_PIXELS:
            raise ReaderError(path, f"invalid Mountains grid {nx} x {ny}")
        dx = abs(xs["step"]) * length_factor(normalize_units(xs["unit"]), zu)
        dy = abs(ys["step"]) * length_factor(normalize_units(ys["unit"]), zu)
        name = _text(_get(grid, 0xFFFF, 0xFFFF, 1)) or _text(_get(body, 0xFFFF, 4)) or "Surface"
        out.append({"name": name, "nx": nx, "ny": ny, "dx": dx, "dy": dy, "units": zu,
                    "zscale": zs["step"] * length_factor(normalize_units(zs["unit"]), zu),
                    "zorigin": zs["origin"] or 0.0, "heights": _get(heights, 2), "mask": _get(grid, 3)})
    if not out:
        raise ReaderError(path, "the Mountains document holds no measured surface")
    return out


def _software(path, ole):
    if not ole.exists("XmlHeader"):
        return {}
    raw = ole.read_stream("XmlHeader")
    if raw[:3] != b"\xff\xfe\xff":  # MFC CArchive Unicode string: marker, then length
        return {}
    n, pos = raw[3], 4
    if n == 0xFF:
        n, pos = struct.unpack_from("<H", raw, 4)[0], 6
    root = parse_xml(raw[pos:pos + 2 * n].decode("utf-16-le", errors="replace").encode("utf-8"), path,
                     "Mountains XmlHeader")
    return {"software": child_text(root, "ProductName"), "software_build_date": child_text(root, "BuildDate")}


def _parse(path):
    ole = OleFile(path)
    if not ole.exists("ScopedContents"):
        raise ReaderError(path, "OLE file without a ScopedContents stream is not a Mountains document")
    surfaces = _surfaces(path, ole)
    infos = [ChannelInfo(i, s["name"], (s["ny"], s["nx"]), (s["ny"] * s["dy"], s["nx"] * s["dx"]), s["units"],
                         s["units"]) for i, s in enumerate(surfaces)]
    return infos, ole, surfaces


def _load(path, info, ole, surfaces):
    s = surfaces[info.index]
    nx, ny = s["nx"], s["ny"]
    count = _num(_get(s["heights"], 1), "<I")
    if count != nx * ny:
        raise ReaderError(path, f"Mountains height array has {count} values for a {nx} x {ny} grid")
    buf, esize = _blocks(path, _get(s["heights"], 2), count, 8 * count)
    if esize not in (2, 4):
        raise ReaderError(path, f"unsupported Mountains height size {esize} bytes")
    counts = np.frombuffer(buf, f"<i{esize}").reshape(ny, nx)
    z = counts * s["zscale"] + s["zorigin"]
    undefined = None
    if s["mask"] is not None and _class(s["mask"]) == _MASK:
        mbody = _get(s["mask"], 2)
        arr = _get(mbody, 5, 2)
        mcount = _num(_get(arr, 1), "<I")
        if mcount != (nx + 2) * (ny + 2):
            raise ReaderError(path, "Mountains mask does not match the grid")
        mbuf, _ = _blocks(path, _get(arr, 2), mcount, mcount)
        undefined = np.frombuffer(mbuf, np.uint8).reshape(ny + 2, nx + 2)[1:-1, 1:-1] != _MEASURED
    return make_measurement(z, spacing=(s["dy"], s["dx"]), units=s["units"], mask=undefined, name=s["name"],
                            vendor="Digital Surf", original_units=s["units"], **_software(path, ole))


channel_format("mnt", "Digital Surf Mountains document (OLE)", (".mnt",), _sniff, "Digital Surf Mountains", _parse,
               _load, priority=5)
