"""xtopo: surface topography analysis and contact mechanics on xarray.

Importing xtopo registers the ``.topo`` accessors on DataArray, Dataset and DataTree.

Startup (issue 26): the submodules and their heavy dependencies (scipy, numba, dask, holoviews,
netCDF4) are imported on first use — the names below resolve lazily (:func:`__getattr__`, PEP 562);
registering the accessors imports xarray only. The ``xtopo`` command registers them after parsing
its arguments, so that ``xtopo --version``/``--help`` import neither xarray nor numpy.
"""

import importlib
import os
import sys

from ._version import __version__
from .errors import (ChunkError, ContactError, ConvergenceWarning, GridError, MetadataWarning, ReaderError,
                     UndefinedValueWarning, UnitsError, UnsupportedFormatError, ValidationError, WriteError,
                     XtopoError)

__all__ = [
    "__version__", "conventions", "datasets", "errors", "make_measurement", "validate",
    "open_topography", "open_contact", "to_netcdf", "twin", "open_twin", "to_container", "cache", "io", "preprocess",
    "batch",
    "XtopoError", "ReaderError", "UnsupportedFormatError", "UnitsError", "GridError", "ChunkError",
    "ValidationError", "ContactError", "WriteError", "ConvergenceWarning", "MetadataWarning", "UndefinedValueWarning",
]

#: public functions → their module, and the submodules listed by ``dir(xtopo)``: imported on first access
_FUNCTIONS = {"make_measurement": ".conventions", "validate": ".conventions", "open_topography": ".io",
              "open_contact": ".io", "to_netcdf": ".io", "to_container": ".io", "twin": ".twins", "open_twin": ".twins"}
_MODULES = ("conventions", "datasets", "cache", "io", "preprocess", "batch", "contact", "analysis", "plot",
            "stitching", "twins", "accessors")


def __getattr__(name):
    module = _FUNCTIONS.get(name, f".{name}")  # any submodule: xtopo.summary, xtopo.report, ...
    try:
        value = importlib.import_module(module, __name__)
    except ModuleNotFoundError as exc:
        if exc.name != f"{__name__}{module}":
            raise
        raise AttributeError(f"module 'xtopo' has no attribute {name!r}") from None
    return getattr(value, name) if name in _FUNCTIONS else value


def __dir__():
    return sorted(set(globals()) | set(_FUNCTIONS) | set(_MODULES))


def _command_line() -> bool:
    """Whether this process is the ``xtopo`` command (script or ``python -m xtopo``): it registers the
    accessors itself once its arguments are parsed, so ``--version``/``--help`` import no xarray."""
    argv = getattr(sys, "orig_argv", [])
    script = os.path.basename(sys.argv[0] if sys.argv else "")
    return script in ("xtopo", "xtopo.exe") or argv[1:3] in (["-m", "xtopo"], ["-m", "xtopo.cli"])


if not _command_line():
    from . import accessors as _accessors  # noqa: F401, E402  (registers .topo; imports xarray)
