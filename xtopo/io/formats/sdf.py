"""ISO 25178-71 / Surfstand SDF: ASCII (``aISO-1.0``, ``aBCR-1.0``) and binary (``bISO-1.0``, ``bBCR-1.0``).

ASCII files hold ``Key = value`` header lines up to a line ``*``, then
``NumPoints × NumProfiles`` values (profile after profile), then ``*`` and an optional
trailer. Binary files have a fixed 81-byte little-endian header (8-byte version,
``ManufacID`` 10 s, ``CreateDate`` 12 s, ``ModDate`` 12 s, ``NumPoints`` and ``NumProfiles``
uint16, ``Xscale``, ``Yscale``, ``Zscale``, ``Zresolution`` float64, ``Compression``,
``DataType``, ``CheckType`` uint8) followed by the values. Scales are in metres:
``x = i·Xscale``, ``z = value·Zscale``. ``DataType``: 0 uint8, 1 uint16, 2 uint32, 3 float32,
4 int8, 5 int16, 6 int32, 7 float64; 16/32-bit integers mark missing points with their
extreme value (minimum for signed, maximum for unsigned), ASCII files with ``BAD``.
"""

from __future__ import annotations

import numpy as np

from ...conventions import make_measurement
from ...errors import ReaderError, UnsupportedFormatError
from .._binary import BinaryReader, read_bytes
from .._generic import single_channel
from .._text import header_value, parse_table
from ..registry import Format, register
from ._common import clean_text, sniff_magic

__all__ = ["read_sdf"]

_MAGICS_ASCII = (b"aISO-1.0", b"aBCR-1.0")
_MAGICS_BINARY = (b"bISO-1.0", b"bBCR-1.0")
_DTYPES = {0: "u1", 1: "<u2", 2: "<u4", 3: "<f4", 4: "i1", 5: "<i2", 6: "<i4", 7: "<f8"}
_INVALID = {1: 2**16 - 1, 2: 2**32 - 1, 5: -(2**15), 6: -(2**31)}
#: the binary header fields after the version (then Compression, DataType, CheckType)
_BINARY_HEADER = ("ManufacID", "CreateDate", "ModDate", "NumPoints", "NumProfiles", "Xscale", "Yscale", "Zscale",
                  "Zresolution")


def _measurement(path, values, header, npts, nprof, dtype_code):
    xs, ys, zs = (header_value(path, header, k) for k in ("Xscale", "Yscale", "Zscale"))
    if xs <= 0 or ys <= 0 or zs == 0:
        raise ReaderError(path, f"scales must be positive (Xscale={xs}, Yscale={ys}, Zscale={zs})")
    z = np.asarray(values, dtype=float).reshape(nprof, npts)
    mask = ~np.isfinite(z)
    if dtype_code in _INVALID:
        mask |= np.asarray(values).reshape(nprof, npts) == _INVALID[dtype_code]
    attrs = {k: str(header[k]).strip() or None for k in ("ManufacID", "CreateDate", "ModDate") if k in header}
    return make_measurement(np.where(mask, np.nan, z) * zs, size=(nprof * ys, npts * xs), units="m",
                            mask=mask if mask.any() else None, sdf_datatype=int(dtype_code),
                            **{f"sdf_{k.lower()}": v for k, v in attrs.items()})


def _dims(path, header):
    npts = header_value(path, header, "NumPoints", int)
    nprof = header_value(path, header, "NumProfiles", int)
    if npts < 1 or nprof < 1:
        raise ReaderError(path, f"NumPoints={npts} and NumProfiles={nprof} must be positive")
    return npts, nprof


def _read_ascii(path, data: bytes):
    lines = data.decode("latin-1").splitlines()
    i, end = ([k for k, ln in enumerate(lines[1:], 1) if ln.strip() == "*"] + [len(lines)] * 2)[:2]  # the two '*'
    if i >= len(lines):
        raise ReaderError(path, "header is not terminated by a '*' line")
    header = {key.strip(): value.strip() for key, sep, value in (ln.partition("=") for ln in lines[1:i]) if sep}
    npts, nprof = _dims(path, header)
    code = header_value(path, header, "DataType", int) if "DataType" in header else 7
    if code not in _DTYPES:
        raise ReaderError(path, f"unknown DataType {code}")
    body = " ".join(lines[i + 1:end]).replace("BAD", "nan").split()
    if len(body) != npts * nprof:
        raise ReaderError(path, f"header promises {npts}×{nprof} = {npts * nprof} values, found {len(body)}")
    values = parse_table(path, [" ".join(body)], what="height data").ravel()
    return _measurement(path, values, header, npts, nprof, code)


def _read_binary(path, data: bytes):
    r = BinaryReader(data, path, "<")
    *fields, compression, code, _check = r.unpack("10s12s12s2H4d3B", "SDF header", at=8)
    header = dict(zip(_BINARY_HEADER, fields))
    header.update({k: clean_text(header[k]) for k in _BINARY_HEADER[:3]})
    if compression != 0:
        raise UnsupportedFormatError(path, f"compressed SDF (Compression={compression}) is not supported")
    if code not in _DTYPES:
        raise ReaderError(path, f"unknown DataType {code}")
    npts, nprof = _dims(path, header)
    values = r.array(_DTYPES[code], npts * nprof, "height data")
    return _measurement(path, values, header, npts, nprof, code)


def read_sdf(path, *, channel=None):
    """Read an SDF file (ASCII or binary; see the module docstring)."""
    single_channel(path, channel)
    data = read_bytes(path)
    if data[:8] in _MAGICS_ASCII:
        return _read_ascii(path, data)
    if data[:8] in _MAGICS_BINARY:
        return _read_binary(path, data)
    raise UnsupportedFormatError(path, "not an SDF file (expected aISO-1.0, bISO-1.0, aBCR-1.0 or bBCR-1.0)")


register(Format("sdf", "ISO 25178-71 / Surfstand SDF (ASCII or binary)", (".sdf",),
                sniff_magic(*_MAGICS_ASCII, *_MAGICS_BINARY), read_sdf, priority=20))
