"""numpy ``.npy`` arrays and ``.npz`` archives (never unpickled).

A 2D array is an area scan with rows along ``y``, a 1D array a uniform line scan. The files
store neither physical size nor unit: pass ``physical_size=`` and ``file_units=`` to
:func:`xtopo.open_topography`. In an ``.npz`` archive ``channel`` picks the array by name or
index (default: ``heights``/``height``/... or the first array). Array headers are checked
against the bytes present before anything is allocated.
"""

from __future__ import annotations

import contextlib
import os
import tokenize
import zipfile

import numpy as np
from numpy.lib import format as npformat

from ...errors import ReaderError
from .._generic import channel_infos, check_array_bytes, generic_measurement, pick_array, single_channel
from ..registry import READ_OPTIONS, Format, register
from ._common import sniff_magic

__all__ = ["read_npy", "read_npz"]

_MAGIC = b"\x93NUMPY"


def _header(path, f, what):
    try:
        version = npformat.read_magic(f)
        if version == (1, 0):
            shape, fortran, dtype = npformat.read_array_header_1_0(f)
        elif version in ((2, 0), (3, 0)):
            shape, fortran, dtype = npformat.read_array_header_2_0(f)
        else:
            raise ValueError(f"unsupported .npy version {version}")
    except (ValueError, OSError, EOFError, SyntaxError, TypeError, tokenize.TokenError) as exc:
        raise ReaderError(path, f"invalid .npy header of {what}: {exc}") from None
    if dtype.hasobject or dtype.kind not in "biuf":
        raise ReaderError(path, f"{what} has dtype {dtype}; only numeric arrays are read (no pickles)")
    return shape, fortran, dtype


def _read_stream(path, f, available: int, what: str) -> np.ndarray:
    start = f.tell()
    shape, fortran, dtype = _header(path, f, what)
    check_array_bytes(path, shape, dtype.itemsize, available - (f.tell() - start), what)
    n = int(np.prod(shape))
    raw = f.read(n * dtype.itemsize)
    if len(raw) != n * dtype.itemsize:
        raise ReaderError(path, f"{what} is truncated: {len(raw)} of {n * dtype.itemsize} bytes")
    arr = np.frombuffer(raw, dtype=dtype, count=n)
    return arr.reshape(shape[::-1]).T if fortran else arr.reshape(shape)


def read_npy(path, *, channel=None, physical_size=None, file_units=None, height_units=None):
    """Read a ``.npy`` array (see the module docstring)."""
    single_channel(path, channel)  # a .npy file holds one array
    with open(path, "rb") as f:
        arr = _read_stream(path, f, os.path.getsize(path), "the array")
    return generic_measurement(path, arr, physical_size=physical_size, file_units=file_units,
                               height_units=height_units)


def _npz_entries(path, zf):
    out = []
    for info in zf.infolist():
        if info.filename.endswith(".npy"):
            with zf.open(info) as f:
                shape = _header(path, f, info.filename)[0]
            out.append((info.filename[:-4], shape))
    return out


@contextlib.contextmanager
def _npz(path):
    """The open archive; a broken archive, or member, is a :class:`ReaderError`."""
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise ReaderError(path, f"not a valid .npz (zip) archive: {exc}") from None
    with zf:
        try:
            yield zf
        except (zipfile.BadZipFile, EOFError, OSError, NotImplementedError) as exc:
            raise ReaderError(path, f"corrupt .npz archive: {exc}") from None


def read_npz(path, *, channel=None, physical_size=None, file_units=None, height_units=None):
    """Read one array of an ``.npz`` archive (see the module docstring)."""
    with _npz(path) as zf:
        _, name = pick_array(path, _npz_entries(path, zf), channel)
        info = zf.getinfo(name + ".npy")
        with zf.open(info) as f:
            arr = _read_stream(path, f, info.file_size, name)
    return generic_measurement(path, arr, physical_size=physical_size, file_units=file_units,
                               height_units=height_units, channel=name)


def _channels_npy(path, **options):
    with open(path, "rb") as f:
        return channel_infos(path, [("array", _header(path, f, "the array")[0])], **options)


def _channels_npz(path, **options):
    with _npz(path) as zf:
        return channel_infos(path, _npz_entries(path, zf), **options)


def _sniff_npz(head: bytes, path: str) -> bool:
    # first local file header: name length at offset 26, name at 30
    if not head.startswith(b"PK\x03\x04") or len(head) < 30:
        return False
    n = int.from_bytes(head[26:28], "little")
    return head[30:30 + n].endswith(b".npy")


register(Format("npy", "numpy .npy array", (".npy",), sniff_magic(_MAGIC), read_npy, channels=_channels_npy,
                priority=10, options=READ_OPTIONS))
register(Format("npz", "numpy .npz archive of arrays", (".npz",), _sniff_npz, read_npz, channels=_channels_npz,
                priority=10, options=READ_OPTIONS))
