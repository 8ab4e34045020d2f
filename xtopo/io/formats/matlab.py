"""MATLAB ``.mat`` files: v5/v7 (scipy.io) and v7.3 (HDF5, via h5py).

Each numeric 1D/2D variable is a channel (``channel`` = name or index; default a variable
named ``heights``/``height``/... or the first). A matrix's rows are ``y``. MAT files store no
physical size or unit: pass ``physical_size=`` and ``file_units=``. v7.3 files store arrays
column-major; they are transposed back to MATLAB's row/column order.
"""

from __future__ import annotations

import numpy as np

from ...errors import ReaderError
from .._generic import channel_infos, generic_measurement, pick_array
from ..registry import READ_OPTIONS, Format, register
from ._common import sniff_magic
from .hdf5 import h5_datasets, open_h5, read_dataset

__all__ = ["read_matlab"]

_NUMERIC = {"double", "single", "int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64", "logical"}
_ERRORS = (ValueError, TypeError, OSError, EOFError, KeyError, IndexError, OverflowError, AttributeError,
           UnicodeDecodeError, NotImplementedError)


def _mat_errors() -> tuple:
    """The exceptions scipy.io raises on a malformed MAT file."""
    from scipy.io.matlab import MatReadError

    return _ERRORS + (MatReadError,)


def _is_v73(path) -> bool:
    with open(path, "rb") as f:
        head = f.read(520)
    return head.startswith(b"MATLAB 7.3") or head[512:520] == b"\x89HDF\r\n\x1a\n"


def _squeeze_shape(shape):
    s = tuple(int(v) for v in shape if int(v) != 1)
    return s if s else tuple(int(v) for v in shape)


def _entries_v5(path):
    import scipy.io

    try:
        info = scipy.io.whosmat(path)
    except _mat_errors() as exc:
        raise ReaderError(path, f"not a readable MATLAB file: {exc}") from None
    return [(name, _squeeze_shape(shape)) for name, shape, cls in info if cls in _NUMERIC]


def _read_v5(path, channel):
    import scipy.io

    _, name = pick_array(path, _entries_v5(path), channel)
    try:
        arr = scipy.io.loadmat(path, variable_names=[name], squeeze_me=True, mat_dtype=False)[name]
    except _mat_errors() as exc:
        raise ReaderError(path, f"cannot read variable {name!r}: {exc}") from None
    return name, np.asarray(arr)


def _entries_v73(path, f):
    return [(n, _squeeze_shape(d.shape[::-1])) for n, d in h5_datasets(f)]


def _read_v73(path, channel):
    with open_h5(path) as f:
        _, name = pick_array(path, _entries_v73(path, f), channel)
        arr = read_dataset(path, dict(h5_datasets(f))[name], name)
    return name, np.squeeze(arr.T) if arr.ndim > 1 else arr


def read_matlab(path, *, channel=None, physical_size=None, file_units=None, height_units=None):
    """Read one variable of a MAT file (see the module docstring)."""
    name, arr = (_read_v73 if _is_v73(path) else _read_v5)(path, channel)
    if arr.dtype == bool:
        arr = arr.astype(np.uint8)
    return generic_measurement(path, arr, physical_size=physical_size, file_units=file_units,
                               height_units=height_units, channel=name)


def _channels(path, **options):
    if _is_v73(path):
        with open_h5(path) as f:
            return channel_infos(path, _entries_v73(path, f), **options)
    return channel_infos(path, _entries_v5(path), **options)


register(Format("matlab", "MATLAB .mat file (v5/v7, v7.3)", (".mat",), sniff_magic(b"MATLAB"), read_matlab,
                channels=_channels, priority=10, options=READ_OPTIONS))
