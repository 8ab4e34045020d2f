"""On-disk result cache for analyses.

Results are keyed by the content checksum of the measurement (after
preprocessing: heights, mask, coordinates and the attributes analyses read),
the function's qualified name, its parameters and the xtopo version, and
stored as NetCDF files in a directory the user chooses (default: the user
cache directory). Writes are atomic (temp file + ``os.replace``), so two
processes writing the same key never leave a broken file: the last complete
write wins and both results are identical by construction.
"""

from __future__ import annotations

import hashlib
import json
import os

import numpy as np
import xarray as xr

from ._version import __version__
from .conventions import MEASUREMENT_ATTRS
from .io.netcdf import read_netcdf, to_netcdf

__all__ = ["Cache", "checksum", "default_directory"]


def default_directory() -> str:
    """``$XTOPO_CACHE_DIR`` or the platform's user cache directory for xtopo."""
    env = os.environ.get("XTOPO_CACHE_DIR")
    if env:
        return env
    from platformdirs import user_cache_dir

    return user_cache_dir("xtopo")


def _update_array(h, arr) -> None:
    a = np.ascontiguousarray(np.asarray(arr))
    h.update(str(a.dtype).encode())
    h.update(str(a.shape).encode())
    h.update(a.tobytes())


def checksum(ds) -> str:
    """SHA-256 of what an analysis of ``ds`` depends on: data, coordinates and measurement attrs.

    Computing it loads dask-backed data.
    """
    h = hashlib.sha256()
    items = ds.variables.items() if isinstance(ds, xr.Dataset) else [(ds.name, ds.variable)] + [
        (k, v.variable) for k, v in ds.coords.items()]
    for name, var in sorted(items, key=lambda kv: str(kv[0])):
        h.update(str(name).encode())
        h.update(str(var.dims).encode())
        h.update(json.dumps({k: str(var.attrs.get(k)) for k in ("units",)}).encode())
        _update_array(h, var.values)
    attrs = {k: str(ds.attrs.get(k)) for k in MEASUREMENT_ATTRS if k in ds.attrs}
    h.update(json.dumps(attrs, sort_keys=True).encode())
    return h.hexdigest()


def _key(func, data_sum: str, params: dict) -> str:
    name = f"{func.__module__}.{func.__qualname__}"
    blob = json.dumps({"f": name, "data": data_sum, "params": params, "version": __version__},
                      sort_keys=True, default=repr)
    return hashlib.sha256(blob.encode()).hexdigest()


class Cache:
    """A directory of cached analysis results.

    Parameters
    ----------
    directory : str or os.PathLike, optional
        Where results are stored (created on first write); default :func:`default_directory`.

    Examples
    --------
    >>> cache = Cache("/tmp/xtopo-cache")                  # doctest: +SKIP
    >>> psd = cache(xtopo.analysis.psd.psd, ds, kind="1d")  # computed and stored
    >>> psd = cache(xtopo.analysis.psd.psd, ds, kind="1d")  # read back
    """

    def __init__(self, directory=None):
        self.directory = os.fspath(directory) if directory is not None else default_directory()
        self.hits = 0
        self.misses = 0

    def path(self, func, ds, **params) -> str:
        """The file that holds (or will hold) ``func(ds, **params)``."""
        return os.path.join(self.directory, _key(func, checksum(ds), params) + ".nc")

    def __call__(self, func, ds, **params):
        """``func(ds, **params)``, from the cache when present, else computed and stored.

        DataArray results come back as DataArrays, Dataset results as Datasets.
        """
        path = self.path(func, ds, **params)
        if os.path.exists(path):
            try:
                stored = read_netcdf(path)
            except Exception:  # a damaged entry is recomputed, never trusted
                stored = None
            if stored is not None:
                self.hits += 1
                kind = stored.attrs.pop("xtopo_cache_kind", "Dataset")
                for key in ("Conventions", "xtopo_version", "date_created", "product_version"):
                    stored.attrs.pop(key, None)
                if kind == "DataArray":
                    name = stored.attrs.pop("xtopo_cache_name")
                    var = stored[name]
                    return var.rename(None) if name == "__xtopo_unnamed__" else var
                return stored
        self.misses += 1
        result = func(ds, **params)
        if hasattr(result, "compute"):
            result = result.compute()
        os.makedirs(self.directory, exist_ok=True)
        if isinstance(result, xr.DataArray):
            name = result.name if result.name is not None else "__xtopo_unnamed__"
            out = result.to_dataset(name=name)
            out.attrs = {"xtopo_cache_kind": "DataArray", "xtopo_cache_name": name}
        else:
            out = result.copy(deep=False)
            out.attrs = {**result.attrs, "xtopo_cache_kind": "Dataset"}
        to_netcdf(out, path)
        return result

    def clear(self) -> int:
        """Delete every cached result; return how many files were removed."""
        n = 0
        if os.path.isdir(self.directory):
            for f in os.listdir(self.directory):
                if f.endswith(".nc"):
                    os.unlink(os.path.join(self.directory, f))
                    n += 1
        return n
