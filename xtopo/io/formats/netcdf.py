"""xtopo's own NetCDF layout (NetCDF-3 classic and NetCDF-4/HDF5)."""

from __future__ import annotations

from ...errors import ReaderError, UnsupportedFormatError
from ..netcdf import is_contact_result, read_netcdf
from ._common import pick_channel, sniff_magic
from ..registry import Format, register


def _read(path, *, channel=None):
    pick_channel(path, ["height"], channel)  # the one channel: 0, "height" or None (anything else was ignored)
    ds = read_netcdf(path)
    if "height" not in ds:
        if is_contact_result(ds):  # a ReaderError: the advice wins over the other readers' refusals
            raise ReaderError(path, "this file holds a contact result, not a measurement; read it with "
                                    "xtopo.open_contact")

        raise UnsupportedFormatError(path, "NetCDF file without a 'height' variable is not an xtopo measurement")
    return ds


register(Format("netcdf", "xtopo NetCDF measurement", (".nc", ".nc4", ".h5", ".hdf5"),
                sniff_magic(b"CDF", b"\x89HDF\r\n\x1a\n"), _read, priority=-1))
