"""On-disk store of a batch run: one NetCDF file per chunk plus a JSON manifest.

A chunk file is written atomically (temp file + ``os.replace``) by whoever computed
it, so a run that dies midway leaves only complete chunk files behind. Each file
carries the key of its inputs (measurement fingerprints, parameters, function,
xtopo version) in its attrs; a restarted run reuses a chunk only when the key
matches and no item of it failed. The manifest (written by :mod:`xtopo.batch._engine`)
says which chunk files make up the batch, how they are assembled into its result and
which items of that result failed.
"""

from __future__ import annotations

import hashlib
import json
import os
import threading

import xarray as xr

from .._checks import make_directory
from .._optional import require
from .._tokens import callable_token
from .._version import __version__
from ..cache import checksum
from ..errors import XtopoError
from ..io.netcdf import PROVENANCE_KEYS, atomic_write, read_netcdf, to_netcdf

__all__ = ["Store", "chunk_key", "fingerprint", "func_name", "IO_LOCK"]

#: Serialises file I/O of batch tasks that share a process (threads scheduler, multi-threaded
#: workers). xarray's locks do not exclude an h5netcdf read (HDF5 lock) from a netCDF4 write
#: (netCDF-C lock), and HDF5 is not thread-safe: concurrent ones crashed the process (SIGBUS).
IO_LOCK = threading.RLock()

KEY_ATTR = "xtopo_batch_key"
FAILED_ATTR = "xtopo_batch_failed"
MANIFEST = "manifest.json"


def func_name(func) -> str:
    """A stable description of ``func`` (a function or a ``functools.partial`` of one)."""
    inner = getattr(func, "func", None)
    if inner is not None and hasattr(func, "keywords"):
        args = json.dumps({"args": func.args, "kw": func.keywords}, sort_keys=True, default=repr)
        return f"{func_name(inner)}{args}"
    return f"{getattr(func, '__module__', '?')}.{getattr(func, '__qualname__', repr(func))}"


def fingerprint(source) -> str:
    """Identity of one measurement: content checksum of a Dataset, or path + size + mtime of a file.

    Files are not read on the client (workers read them); a changed file changes its
    size or modification time, and with it the key of every chunk that uses it.
    """
    if isinstance(source, xr.Dataset):
        return "dataset:" + checksum(source)
    path = os.path.abspath(os.fspath(source))
    try:
        st = os.stat(path)
    except OSError:
        return f"missing:{path}"
    return f"file:{path}:{st.st_size}:{st.st_mtime_ns}"


def chunk_key(func, dim, names, prints, params, preprocess=()) -> str:
    """SHA-256 key of one chunk's inputs.

    ``preprocess``: the steps applied to each measurement after reading
    (:func:`xtopo.preprocess.checked_steps`); a chunk without any has the key it had
    before batches could preprocess, so that its stored file is still reused.

    The function (a partial's arguments included) and the parameter values enter by content
    (dask's ``tokenize``; the function's own code too, :mod:`xtopo._tokens`), which is the same in every
    process: a ``repr`` holds memory addresses
    (``<function f at 0x...>``: never reused by a new process) and abbreviates large arrays
    (``[1., 1., ..., 1.]``: reused when the array changed).
    """
    tokenize = require("dask.base", "xtopo.batch").tokenize  # the [dask] extra, loaded on first use

    inputs = {"f": callable_token(func), "dim": dim, "names": list(names), "m": list(prints),
              "p": None if params is None else tokenize(list(params)), "v": __version__}
    if preprocess:
        inputs["pre"] = [[step, options] for step, options in preprocess]
    blob = json.dumps(inputs, sort_keys=True, default=repr)
    return hashlib.sha256(blob.encode()).hexdigest()


def _strip(ds: xr.Dataset) -> xr.Dataset:
    for k in (KEY_ATTR, FAILED_ATTR, *PROVENANCE_KEYS):
        ds.attrs.pop(k, None)
    return ds


class Store:
    """A directory holding one NetCDF file per completed chunk of a batch.

    Parameters
    ----------
    directory : str or os.PathLike
        Created if absent. Files of other batches in the same directory are left alone.
    """

    def __init__(self, directory):
        self.directory = os.path.abspath(directory)
        if os.path.exists(self.directory) and not os.path.isdir(self.directory):
            raise XtopoError(f"batch store {self.directory} exists and is not a directory; "
                             "give a directory path (it is created when absent)")
        make_directory(self.directory, "batch store")

    def path(self, key: str) -> str:
        """The file of chunk ``key``."""
        return os.path.join(self.directory, f"chunk-{key[:40]}.nc")

    def reusable(self, key: str) -> xr.Dataset | None:
        """Chunk ``key`` if it is stored, readable, has the same key and no failed item; else None."""
        try:
            with IO_LOCK:  # read with h5netcdf (HDF5), written with netCDF4 (netCDF-C): see IO_LOCK
                ds = read_netcdf(self.path(key))
        except Exception:  # an absent or damaged file is computed, never trusted
            return None
        if ds.attrs.get(KEY_ATTR) != key or int(ds.attrs.get(FAILED_ATTR, 1)) != 0:
            return None
        return _strip(ds)

    def write(self, ds: xr.Dataset, key: str, n_failed: int) -> str:
        """Store one chunk's result atomically.

        The data are in memory and the file is this task's alone, so xarray must not take
        its scheduler-wide write lock: inside a distributed worker that is a
        ``distributed.Lock`` (a scheduler round trip per write, and a lease a killed
        worker holds until it expires). Declaring the synchronous scheduler for the
        write gives xarray's process-local lock instead.
        """
        import dask

        ds = ds.copy(deep=False)
        ds.attrs = {**ds.attrs, KEY_ATTR: key, FAILED_ATTR: int(n_failed)}
        with IO_LOCK, dask.config.set(scheduler="synchronous"):  # config.set is global: keep it under the lock
            return to_netcdf(ds, self.path(key))

    def read(self, key: str) -> xr.Dataset:
        """A stored chunk, loaded, without the store's bookkeeping attributes."""
        with IO_LOCK:
            return _strip(read_netcdf(self.path(key)))

    def write_manifest(self, manifest: dict) -> str:
        """Write ``manifest.json`` (what the batch is, which chunk files make it up) atomically."""
        path = os.path.join(self.directory, MANIFEST)

        def write(tmp):
            with open(tmp, "w") as f:
                json.dump(manifest, f, indent=1, default=str)

        return atomic_write(path, write)
