"""xtopo: surface topography analysis and contact mechanics on xarray.

Importing xtopo registers the ``.topo`` accessors on DataArray, Dataset and DataTree.
"""

from ._version import __version__
from . import conventions, datasets, errors
from .conventions import make_measurement, validate
from .errors import (ChunkError, ContactError, ConvergenceWarning, GridError, MetadataWarning, ReaderError,
                     UndefinedValueWarning, UnitsError, UnsupportedFormatError, ValidationError, WriteError,
                     XtopoError)
from .io import open_topography, to_container, to_netcdf
from .twins import open_twin, twin
from . import cache
from . import io, preprocess
from . import batch  # issue 7: chunked Dask batch runs (distributed is imported lazily)
from . import accessors as _accessors  # noqa: F401  (registers .topo)

__all__ = [
    "__version__", "conventions", "datasets", "errors", "make_measurement", "validate",
    "open_topography", "to_netcdf", "twin", "open_twin", "to_container", "cache", "io", "preprocess", "batch",
    "XtopoError", "ReaderError", "UnsupportedFormatError", "UnitsError", "GridError", "ChunkError",
    "ValidationError", "ContactError", "WriteError", "ConvergenceWarning", "MetadataWarning", "UndefinedValueWarning",
]
