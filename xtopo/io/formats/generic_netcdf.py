"""Generic NetCDF-3 files (classic and 64-bit offset, read with scipy): any 1D or 2D numeric variable.

The NetCDF counterpart of the generic HDF5 reader (which also reads NetCDF-4 files, being
HDF5): for files in neither xtopo's layout nor SurfaceTopography's. ``channel`` is the
variable's name or its index among the 1D/2D numeric variables in file order (default: one
named ``heights``/``height``/... or the first); coordinate variables (a 1D variable named
after its dimension) are axes, not heights. A variable attribute ``units``/``unit`` holding a
length unit is used; otherwise pass ``file_units=``. ``_FillValue``/``missing_value`` points
become missing data, ``scale_factor``/``add_offset`` are applied. The physical size always
comes from ``physical_size=``.
"""

from __future__ import annotations

import os

import numpy as np

from ...errors import ReaderError
from .._netcdf3 import check_netcdf3_header
from .._generic import check_array_bytes, container_format
from ._common import sniff_magic

_MAGIC = (b"CDF\x01", b"CDF\x02")  # classic, 64-bit offset (scipy reads no CDF-5)
_ERRORS = (OSError, ValueError, TypeError, KeyError, IndexError, OverflowError, MemoryError)


def _open(path):
    from scipy.io import netcdf_file

    check_netcdf3_header(path)  # sizes bounded by the file's before scipy allocates them
    try:
        return netcdf_file(path, "r", mmap=False, maskandscale=True)
    except _ERRORS as exc:
        raise ReaderError(path, f"not a readable NetCDF-3 file: {exc}") from None


def _variables(f):
    """``[(name, variable)]`` of the numeric variables that are not coordinate variables, in file order."""
    return [(name, var) for name, var in f.variables.items()
            if var.data.dtype.kind in "biuf" and tuple(var.dimensions) != (name,)]


def _read(path, var, name):
    """The variable's values (fill values as NaN, scale and offset applied) and its attributes."""
    check_array_bytes(path, var.shape, var.data.dtype.itemsize, os.path.getsize(path), name)
    return np.ma.filled(np.ma.asarray(var[:], dtype=float), np.nan), var._attributes


container_format("generic-netcdf", "generic NetCDF-3 file (one 1D/2D variable)", (".nc", ".cdf"), sniff_magic(*_MAGIC),
                 "NetCDF-3", _open, _variables, _read, _ERRORS, priority=-5)
