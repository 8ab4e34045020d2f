"""Optional dependencies: the extras of pyproject.toml that install them, and one clear error when missing.

The core install reads, analyses and writes (numpy, scipy, xarray, numba, pint, h5netcdf); Dask,
the figures and the report, pyFFTW and netCDF4 come with extras.
"""

from __future__ import annotations

import importlib

from .errors import XtopoError

__all__ = ["require", "EXTRAS"]

#: top-level module → the extra (``pip install "xtopo[extra]"``) that installs it
EXTRAS = {"dask": "dask", "distributed": "dask", "holoviews": "plot", "bokeh": "plot", "matplotlib": "plot",
          "pyfftw": "fftw", "netCDF4": "io", "zstandard": "io"}


def require(module: str, what: str):
    """``module`` imported, or an :class:`~xtopo.errors.XtopoError` saying that ``what`` needs the extra
    that installs it (a module missing inside an installed package is not hidden)."""
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        top = (exc.name or module).split(".")[0]
        if top not in EXTRAS:
            raise
        raise XtopoError(f"{what} needs {top}, which is not installed: pip install \"xtopo[{EXTRAS[top]}]\"") \
            from None
