"""xarray backend entry point: ``xr.open_dataset(path, engine="xtopo")``."""

from __future__ import annotations

import os

from xarray.backends import BackendEntrypoint

from ..errors import XtopoError
from ..params import Text
from .open import open_topography
from .registry import detect


def _names(drop_variables) -> list:
    """``drop_variables`` (a variable name or names) as a list of str; 5 or an object was ignored."""
    if isinstance(drop_variables, str):
        return [drop_variables]
    try:
        names = list(drop_variables)
    except TypeError:
        raise XtopoError(f"drop_variables must be a variable name or a list of names, "
                         f"got {type(drop_variables).__name__}") from None
    return [Text().check(name, "drop_variables item") for name in names]


class XtopoBackendEntrypoint(BackendEntrypoint):
    """Opens any file :func:`xtopo.open_topography` can read."""

    description = "Surface topography files (AFM, profilometers, X3P, ...) via xtopo"
    url = "https://github.com/xtopo/xtopo"

    def open_dataset(self, filename_or_obj, *, drop_variables=None, channel=None, units="m", periodic=None,
                     format=None, physical_size=None, file_units=None, height_units=None):
        ds = open_topography(filename_or_obj, channel=channel, units=units, periodic=periodic, format=format,
                             physical_size=physical_size, file_units=file_units, height_units=height_units)
        if drop_variables is not None:
            ds = ds.drop_vars(_names(drop_variables), errors="ignore")
        return ds

    def guess_can_open(self, filename_or_obj):
        try:
            return bool(detect(os.fspath(filename_or_obj)))
        except Exception:
            return False
