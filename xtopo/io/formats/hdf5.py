"""Generic HDF5 files (read with h5py): any 1D or 2D numeric dataset.

``channel`` is the dataset's path (``"group/heights"``) or its index among the 1D/2D numeric
datasets in file order (default: a dataset named ``heights``/``height``/... or the first).
A dataset attribute ``units`` or ``unit`` holding a length unit is used; otherwise pass
``file_units=``. The physical size always comes from ``physical_size=``. Shapes are checked
against the file size before reading (uncompressed data) or against 2 GiB (compressed).

Files written as NetCDF-4 are HDF5 too: the ``st-netcdf`` and ``netcdf`` readers are tried
first, this one last.
"""

from __future__ import annotations

import os

import numpy as np

from ...errors import ReaderError
from .._generic import check_array_bytes, container_format
from ._common import sniff_magic

__all__ = ["h5_datasets", "open_h5"]

_MAGIC = b"\x89HDF\r\n\x1a\n"
_H5_ERRORS = (OSError, KeyError, ValueError, TypeError, RuntimeError, IndexError)


def open_h5(path):
    """An ``h5py.File`` opened read-only; failures become :class:`ReaderError`."""
    try:
        import h5py
    except ImportError:
        raise ReaderError(path, "reading HDF5 needs h5py (pip install h5py)") from None
    try:
        return h5py.File(path, "r")
    except _H5_ERRORS as exc:
        raise ReaderError(path, f"not a readable HDF5 file: {exc}") from None


def h5_datasets(f, skip=("#refs#", "#subsystem#")):
    """``[(path, dataset)]`` of the numeric datasets of an open HDF5 file, in file order.

    Dimension scales (the axes of NetCDF-4 variables, often bare zeros) are coordinates, not heights.
    """
    import h5py

    out = []

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and not any(name.startswith(s) for s in skip) and not _is_scale(obj):
            if obj.dtype.kind in "biuf" and obj.shape is not None:
                out.append((name, obj))

    f.visititems(visit)
    return out


def _is_scale(dset) -> bool:
    """Whether ``dset`` is an HDF5 dimension scale (attribute ``CLASS = "DIMENSION_SCALE"``)."""
    value = dset.attrs.get("CLASS")
    return (value.decode("ascii", "replace") if isinstance(value, bytes) else str(value)) == "DIMENSION_SCALE"


def read_dataset(path, dset, what: str) -> np.ndarray:
    """All values of ``dset`` after checking its size against the file."""
    available = None if (dset.compression or dset.chunks) else os.path.getsize(path)
    check_array_bytes(path, dset.shape, dset.dtype.itemsize, available, what)
    try:
        return np.asarray(dset[()])
    except _H5_ERRORS as exc:
        raise ReaderError(path, f"cannot read dataset {what!r}: {exc}") from None


def _read(path, dset, name):
    return read_dataset(path, dset, name), dset.attrs


container_format("hdf5", "generic HDF5 file (one 1D/2D dataset)", (".h5", ".hdf5", ".hdf"), sniff_magic(_MAGIC), "HDF5",
                 open_h5, h5_datasets, _read, _H5_ERRORS, priority=-5)
