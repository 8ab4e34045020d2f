"""ISO 25178-72 X3P files (formerly ISO 5436-2): a zip archive with ``main.xml``.

``main.xml`` (namespace ``http://www.opengps.eu/2008/ISO5436_2``) holds
``Record1`` (revision, feature type ``SUR``/``PRF``, axes ``CX``/``CY``/``CZ``
with ``AxisType`` I(ncremental)/A(bsolute), ``DataType`` I=int16, L=int32,
F=float32, D=float64, ``Increment`` and ``Offset`` in metres), ``Record2``
(date, creator, instrument manufacturer/model/serial/version, probing
system), ``Record3`` (``MatrixDimension`` ``SizeX/SizeY/SizeZ`` and either a
``DataLink`` to a little-endian binary member ``PointDataLink`` plus an
optional ``ValidPointsLink`` bit mask (one bit per point, LSB first, 1 =
valid), or an inline ``DataList`` of ``<Datum>`` values).  Points are stored
with x fastest.  Height ``= raw * CZ.Increment + CZ.Offset`` in metres; NaN
marks invalid float points.

The archive is untrusted input: member names with absolute paths or ``..``
components are refused, each member's declared size is checked against what
the header needs and against the compressed size (zip bombs), decompression
is capped, and ``main.xml`` is parsed without DTDs or entities.
"""

from __future__ import annotations

import datetime as _dt
import posixpath
import zipfile

import numpy as np

from ...conventions import make_measurement
from ...errors import ReaderError
from .._binary import MAX_PIXELS
from .._xml import child, child_text, local_name, parse_xml
from .._zip import MAX_METADATA, open_zip, read_member, unsafe_name
from ._common import ChannelInfo, channel_format, zip_member

_DTYPES = {"I": "<i2", "L": "<i4", "F": "<f4", "D": "<f8"}


def _sniff(head: bytes, path: str) -> bool:
    if not head.startswith(b"PK\x03\x04"):
        return False
    if b"main.xml" in head:
        return True
    with zipfile.ZipFile(path) as zf:
        return any(posixpath.basename(n) == "main.xml" for n in zf.namelist())


def _linked(path, zf, base, rec3, key, expected):
    """Bytes of the member that ``DataLink/<key>`` names (relative to main.xml), or ``None`` without one."""
    link = child_text(rec3, "DataLink", key)
    if link is None:
        return None
    if unsafe_name(link):
        raise ReaderError(path, f"X3P {key} {link!r} leaves the archive (path traversal)")
    name = posixpath.join(base, link.replace("\\", "/"))
    return zip_member(path, zf, name, "X3P", f"the X3P archive lacks the member {name!r} named in main.xml",
                      expected=expected, expected_from="main.xml")


def _float(text, default):
    return default if text is None else float(text)


def _header(path, root):
    rec1, rec3 = child(root, "Record1"), child(root, "Record3")
    if rec1 is None or rec3 is None:
        raise ReaderError(path, "X3P main.xml lacks Record1 or Record3")
    axes = {}
    for ax in ("CX", "CY", "CZ"):
        a = child(rec1, "Axes", ax)
        if a is None:
            raise ReaderError(path, f"X3P main.xml lacks the axis {ax}")
        axes[ax] = {"type": child_text(a, "AxisType", default="I"), "dtype": child_text(a, "DataType"),
                    "inc": _float(child_text(a, "Increment"), 1.0), "off": _float(child_text(a, "Offset"), 0.0)}
    for ax in ("CX", "CY"):
        if axes[ax]["type"] != "I":
            raise ReaderError(path, f"X3P axis {ax} is absolute (AxisType A); only gridded (incremental) "
                                    "lateral axes are supported")
    if axes["CZ"]["dtype"] not in _DTYPES:
        raise ReaderError(path, f"X3P CZ DataType {axes['CZ']['dtype']!r} is not one of I, L, F, D")
    nx, ny, nz = (int(child_text(rec3, "MatrixDimension", k, default="1")) for k in ("SizeX", "SizeY", "SizeZ"))
    if nz != 1:
        raise ReaderError(path, f"X3P SizeZ = {nz}: volumetric (multi-layer) data are not supported")
    if nx <= 0 or ny <= 0 or nx * ny > MAX_PIXELS:
        raise ReaderError(path, f"implausible X3P matrix dimension {nx} x {ny}")
    if not (axes["CX"]["inc"] > 0 and axes["CY"]["inc"] > 0):
        raise ReaderError(path, "X3P lateral increments must be positive")
    return axes, nx, ny, rec3


def _parse(path):
    with open_zip(path, "X3P") as zf:
        mains = sorted((n for n in zf.namelist() if posixpath.basename(n) == "main.xml"
                        and not n.startswith("__MACOSX/")), key=lambda n: (n.count("/"), n))
        if not mains:
            raise ReaderError(path, "the zip archive has no main.xml, so it is not an X3P file")
        root = parse_xml(read_member(path, zf, zf.getinfo(mains[0]), "X3P", limit=MAX_METADATA), path, "X3P main.xml")
    base = posixpath.dirname(mains[0])
    axes, nx, ny, rec3 = _header(path, root)
    if ny == 1:
        return [ChannelInfo(0, "Height", (nx,), (nx * axes["CX"]["inc"],), "m", "m")], base, root, axes, nx, ny, rec3
    size = (ny * axes["CY"]["inc"], nx * axes["CX"]["inc"])
    return [ChannelInfo(0, "Height", (ny, nx), size, "m", "m")], base, root, axes, nx, ny, rec3


def _iso(text):
    if not text:
        return None
    try:
        t = _dt.datetime.fromisoformat(text.strip())
    except ValueError:
        return text.strip()
    return None if t.year <= 1970 else t.isoformat()


def _known(text):
    return None if text in (None, "", "unknown", "not available") else text


def _load(path, info, base, root, axes, nx, ny, rec3):
    with open_zip(path, "X3P") as zf:
        dtype = np.dtype(_DTYPES[axes["CZ"]["dtype"]])
        n = nx * ny
        points = _linked(path, zf, base, rec3, "PointDataLink", n * dtype.itemsize)
        bits = _linked(path, zf, base, rec3, "ValidPointsLink", (n + 7) // 8) if points is not None else None
        valid = None if bits is None else np.unpackbits(np.frombuffer(bits, np.uint8), bitorder="little")[:n] != 0
        if points is not None:
            raw = np.frombuffer(points, dtype=dtype)
        else:
            dlist = child(rec3, "DataList")
            if dlist is None:
                raise ReaderError(path, "X3P Record3 has neither a DataLink nor a DataList")
            data = [d.text for d in dlist if local_name(d.tag) == "Datum"]
            if len(data) != n:
                raise ReaderError(path, f"X3P DataList has {len(data)} points, expected {nx} x {ny}")
            raw = np.array([np.nan if not (t or "").strip() else float(t.split(";")[-1]) for t in data])
        z = raw.astype(np.float64) * axes["CZ"]["inc"] + axes["CZ"]["off"]
        undefined = ~np.isfinite(z) if valid is None else (~valid | ~np.isfinite(z))
    rec2 = child(root, "Record2")
    inst = child(rec2, "Instrument")
    manu, model = _known(child_text(inst, "Manufacturer")), _known(child_text(inst, "Model"))
    shape = (ny, nx) if ny > 1 else (nx,)
    sp = (axes["CY"]["inc"], axes["CX"]["inc"]) if ny > 1 else axes["CX"]["inc"]
    return make_measurement(
        z.reshape(shape), spacing=sp, units="m", mask=undefined.reshape(shape), vendor=manu,
        instrument=" ".join(t for t in (manu, model) if t) or None,
        instrument_serial=_known(child_text(inst, "Serial")),
        instrument_version=_known(child_text(inst, "Version")),
        acquisition_time=_iso(child_text(rec2, "Date")), creator=child_text(rec2, "Creator"),
        probing_system=_known(child_text(rec2, "ProbingSystem", "Type")), comment=child_text(rec2, "Comment"),
        x_offset=axes["CX"]["off"], y_offset=axes["CY"]["off"], original_units="m")


channel_format("x3p", "ISO 25178-72 X3P (zip + main.xml)", (".x3p",), _sniff, "X3P", _parse, _load, priority=5)
