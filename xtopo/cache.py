"""On-disk result cache for analyses, with an in-process layer in front of it.

Results are keyed by the content checksum of the measurement (after
preprocessing: heights, mask, coordinates and the attributes analyses read),
the function and its parameters (by content: dask's ``tokenize``, and the function's own code,
:mod:`xtopo._tokens`) and the xtopo version, and stored as NetCDF files in a directory the user
chooses (default: the user cache directory). Writes are atomic (temp file + ``os.replace``), so two
processes writing the same key never leave a broken file: the last complete
write wins and both results are identical by construction.

Entries are NetCDF-3 files where the result survives NetCDF-3 unchanged (checked by reading it back),
else NetCDF-4 written and read with h5netcdf. NetCDF-3 is read by scipy, pure Python after
:func:`xtopo.io.netcdf.read_engine` has checked the header: a damaged entry cannot crash the process,
and a cold hit costs 1.4-14 ms where HDF5 took 35-190 ms (1024² PSD, ACF, scalars).

Every entry carries its own full key and a checksum of its content (attrs ``xtopo_cache_key``,
``xtopo_cache_sum``), both verified whenever the file is read: a damaged entry (a flipped bit,
a value overwritten, a truncated file) or another key's valid entry copied over it is computed
again and replaced, never served.

Array contents are hashed with XXH3-128 (``xxhash``): about 60 GB/s, where SHA-256 managed
1.6 GB/s here, so that a look-up of a writeable 1024² map costs 0.14 ms of hashing instead of 5 ms.
The keys guard against accidental staleness (changed data, edited code), not against an
adversary who can write to the cache directory, who could replace any entry anyway.

Two in-process shortcuts make a hit cheap without weakening the key:

* the results last read from (or written to) the directory are kept in memory,
  each tied to its file's ``os.stat`` signature: a file replaced, damaged or
  removed by anyone invalidates the memory copy; callers get deep copies;
* the checksum of an array is remembered only when its content provably cannot
  change: arrays whose memory is an immutable ``bytes`` object (numpy refuses to
  make them writeable), as :func:`freeze` produces. Every other array is hashed
  in full on every call, so an array changed in place gets a new key.

A hit returns a private copy: new arrays, new attribute dicts (``benchmarks/bench_cache.py``
measures hits against computing).
"""

from __future__ import annotations

import collections
import functools
import hashlib
import json
import os
import threading
import weakref
from typing import Annotated

import numpy as np
import xarray as xr
import xxhash

from ._checks import make_directory
from ._kernels._cache_dir import default_directory
from ._optional import require
from ._tokens import callable_token
from ._tree import _immutable, freeze
from ._version import __version__
from .conventions import MEASUREMENT_ATTRS
from .errors import XtopoError
from .params import Count, Data, Path, checked
from .io.netcdf import PROVENANCE_KEYS, atomic_write, prepare_for_netcdf, read_netcdf, sanitize_attrs, to_netcdf

__all__ = ["Cache", "checksum", "default_directory", "freeze"]

#: arrays smaller than this are hashed every time (remembering them costs more than hashing)
_MEMO_MIN_BYTES = 1 << 16
#: default budget of the in-process result layer
MEMORY_BYTES = 256 * 2**20

_lock = threading.Lock()
_digests: dict[int, tuple] = {}  # id(array) -> (weakref to array, digest)


#: dtype kinds whose arrays export their bytes as a buffer (bool, integers, floats, complex)
_BUFFERED = frozenset("biufc")


@functools.lru_cache(maxsize=1024)
def _head(dtype: np.dtype, shape: tuple) -> bytes:
    """What identifies an array's layout (formatting it took half of hashing a small array)."""
    return f"{dtype.str}{shape}".encode()


def _hash_array(a: np.ndarray) -> bytes:
    """An array's dtype and shape followed by the XXH3-128 digest of its content (text arrays by their values)."""
    if a.dtype.kind in "OUS":  # text: the same digest whichever way numpy holds it (a NetCDF read gives objects)
        text = repr([str(v) for v in a.ravel().tolist()]).encode()
        return f"text{a.shape}".encode() + xxhash.xxh3_128_digest(text)
    # the bytes of any dtype (datetimes have no buffer of their own: a byte view); a C-contiguous numeric array is
    # hashed through its own buffer (the view took a third of a small array's digest); one-shot digest: 6 µs less
    # than a hasher object at 1024² (issue 27's writeable cache hit is this hash)
    data = a if a.flags.c_contiguous and a.dtype.kind in _BUFFERED else np.ascontiguousarray(a).reshape(-1).view(
        np.uint8)
    return _head(a.dtype, a.shape) + xxhash.xxh3_128_digest(data)


def _array_digest(arr) -> bytes:
    a = np.asarray(arr)
    if a.nbytes < _MEMO_MIN_BYTES or not _immutable(a):
        return _hash_array(a)
    key = id(a)
    with _lock:
        hit = _digests.get(key)
    if hit is not None and hit[0]() is a:
        return hit[1]
    digest = _hash_array(a)
    with _lock:
        # the callback runs while ``a`` is being freed, before its id can be reused
        _digests[key] = (weakref.ref(a, lambda _, k=key: _digests.pop(k, None)), digest)
    return digest


@checked
def checksum(ds: Annotated[xr.Dataset | xr.DataArray, Data()]) -> str:
    """Checksum of what an analysis of ``ds`` depends on: data, coordinates and measurement attrs.

    SHA-256 over the names, dims, units and the XXH3-128 digests of the arrays.

    Computing it loads dask-backed data.
    """
    items = ds._variables.items() if isinstance(ds, xr.Dataset) else [(ds.name, ds.variable), *ds._coords.items()]
    indexes = ds._indexes  # xarray's own mappings: ``variables``/``xindexes`` build new ones per call
    parts = []  # one SHA-256 update of all parts (the same digest as one update per part)
    for name, var in sorted(items, key=lambda kv: str(kv[0])):
        parts.append(f"{name}\0{var.dims}\0{var.attrs.get('units')}\0".encode())
        index = indexes.get(name)  # a pandas index: its values without xarray's conversion (4 µs)
        parts.append(_array_digest(np.asarray(index.index) if isinstance(index, xr.indexes.PandasIndex) else var.values))
    attrs = ds.attrs
    parts.append(repr([(k, str(attrs[k])) for k in MEASUREMENT_ATTRS if k in attrs]).encode())
    return hashlib.sha256(b"".join(parts)).hexdigest()


#: parameter types keyed by ``repr`` (exact: 1, 1.0 and True differ; a tenth of a ``tokenize``)
_PLAIN = (str, int, float, bool, type(None))


def _key(func, data_sum: str, params: dict) -> str:
    """Key of ``func(ds, **params)``: function (with its own code, :mod:`xtopo._tokens`) and parameters by content.

    A name or ``repr`` is not enough: every lambda is ``<lambda>``, closures of one factory share
    a qualified name, and numpy abbreviates the repr of large arrays (``tokenize`` them, the [dask] extra).
    """
    token = repr(sorted(params.items())) if all(type(v) in _PLAIN for v in params.values()) else require(
        "dask.base", "the result cache").tokenize(params)
    return hashlib.sha256("\0".join((callable_token(func), data_sum, token, __version__)).encode()).hexdigest()


#: attributes of an entry that verify it (not part of the result)
_KEY_ATTR, _SUM_ATTR = "xtopo_cache_key", "xtopo_cache_sum"


def _plain(value):
    """An attribute value as plain Python, the same before writing and after reading back."""
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    if isinstance(value, (np.ndarray, np.generic)):
        value = np.asarray(value)
        return value.item() if value.size == 1 else value.tolist()
    return value


def _content_sum(ds: xr.Dataset) -> str:
    """Checksum of what an entry holds: every variable (name, dims, values, attrs) and the global attrs.

    Taken over the form NetCDF stores (attributes sanitised, text as values), so the result before
    writing and the file read back give the same sum.
    """
    def attrs_blob(attrs):
        kept = sanitize_attrs({k: v for k, v in attrs.items() if k not in PROVENANCE_KEYS + (_KEY_ATTR, _SUM_ATTR)})
        return json.dumps({k: _plain(v) for k, v in kept.items()}, sort_keys=True, default=str).encode()

    h = hashlib.sha256(attrs_blob(ds.attrs))
    for name in sorted(ds.variables, key=str):
        var = ds.variables[name]
        h.update(f"{name}{var.dims}".encode())
        h.update(attrs_blob(var.attrs))
        h.update(_hash_array(np.asarray(var.values)))
    return h.hexdigest()


def _signature(path: str):
    """What identifies one complete write of a cache file (``None`` if absent)."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_ino, st.st_size, st.st_mtime_ns


class _Memory:
    """Least-recently-used results by cache file path, valid while the file's signature holds."""

    def __init__(self):
        self.entries: collections.OrderedDict = collections.OrderedDict()
        self.nbytes = 0

    def get(self, path: str, signature):
        with _lock:
            entry = self.entries.get(path)
            if entry is None:
                return None
            if entry[0] != signature:
                self._drop(path)
                return None
            self.entries.move_to_end(path)
            return entry[1]

    def put(self, path: str, signature, result, budget: int) -> None:
        size = sum(int(r.nbytes) for r in (result if isinstance(result, tuple) else (result,)) if r is not None)
        with _lock:
            self._drop(path)
            if signature is None or size > budget:
                return
            self.entries[path] = (signature, result, size)
            self.nbytes += size
            while self.nbytes > budget:
                self._drop(next(iter(self.entries)))

    def _drop(self, path: str) -> None:
        entry = self.entries.pop(path, None)
        if entry is not None:
            self.nbytes -= entry[2]

    def clear(self, directory: str) -> None:
        with _lock:
            for path in [p for p in self.entries if os.path.dirname(p) == directory]:
                self._drop(path)


_memory = _Memory()


def _restore(stored: xr.Dataset, key: str):
    """The object the cached function returned, from its stored Dataset; ``None`` unless it verifies.

    An entry verifies when it holds ``key`` (not another key's result copied over it) and its content
    has the checksum written with it (no bit flipped, no value overwritten).
    """
    stored.attrs = dict(stored.attrs)
    if stored.attrs.pop(_KEY_ATTR, None) != key or stored.attrs.pop(_SUM_ATTR, None) != _content_sum(stored):
        return None
    kind = stored.attrs.pop("xtopo_cache_kind", "Dataset")
    for name in ("Conventions", "xtopo_version", "date_created", "product_version"):
        stored.attrs.pop(name, None)
    if kind == "DataArray":
        name = stored.attrs.pop("xtopo_cache_name")
        var = stored[name]
        return var.rename(None) if name == "__xtopo_unnamed__" else var
    return stored


def _private_copy(obj):
    """``obj`` with its own data arrays and attribute dicts, sharing the (immutable) indexes: xarray's private
    ``_replace`` at half the cost of ``copy(deep=False)``, which rebuilds them."""
    indexes = obj._indexes

    def own(name, var):  # new attrs and encoding dicts (the constructors copy them), new data (an index's is immutable)
        if name in indexes:
            return xr.IndexVariable(var.dims, var._data, var._attrs, var._encoding, fastpath=True)
        return xr.Variable(var.dims, np.array(var._data), var._attrs, var._encoding, fastpath=True)

    if isinstance(obj, xr.DataArray):
        return obj._replace(own(None, obj.variable), {k: own(k, v) for k, v in obj._coords.items()})
    return obj._replace({k: own(k, v) for k, v in obj._variables.items()})  # attrs, encoding copied


def remember(func, ds, *also):
    """``func(ds)``, kept in this process's memory layer only (no file): called again with the same ``ds`` (by
    :func:`checksum`), ``func`` (by content) and ``also`` (what else the result depends on, e.g. attributes of ``ds``
    that :func:`checksum` leaves out), a private copy of the result (an xarray object or a tuple of them and Nones).

    For work that a session repeats on data in memory (a twin's curves, which each of its averages, figures and
    reports takes again). Lazy (dask-backed) data, whose checksum would load them, and the core install (without
    dask, which keys functions) compute every call.
    """
    if any(v.chunks is not None for v in ds.variables.values()):
        return func(ds)
    try:
        key = _key(func, checksum(ds), {"also": also})
    except XtopoError:  # the core install: no tokens of functions
        return func(ds)
    held = _memory.get(key, "memory")
    if held is None:
        held = func(ds)
        _memory.put(key, "memory", held, MEMORY_BYTES)
    return tuple(None if r is None else _private_copy(r) for r in held) if isinstance(held, tuple) \
        else _private_copy(held)


class Cache:
    """A directory of cached analysis results.

    Parameters
    ----------
    directory : str or os.PathLike, optional
        Where results are stored (created on first write); default :func:`default_directory`.
    memory_bytes : int
        Budget (bytes) of the in-process copies of recently used results shared by all
        caches of this process; 0 reads every hit from disk.

    Examples
    --------
    >>> cache = Cache("/tmp/xtopo-cache")                  # doctest: +SKIP
    >>> psd = cache(xtopo.analysis.psd.psd, ds, kind="1d")  # computed and stored
    >>> psd = cache(xtopo.analysis.psd.psd, ds, kind="1d")  # read back
    """

    @checked
    def __init__(self, directory: Annotated[str | None, Path("directory path")] = None, *,
                 memory_bytes: Annotated[int, Count(min=0)] = MEMORY_BYTES):
        self.directory = directory if directory is not None else default_directory()
        self.memory_bytes = memory_bytes
        self.hits = 0
        self.misses = 0

    def path(self, func, ds, **params) -> str:
        """The file that holds (or will hold) ``func(ds, **params)``."""
        if not callable(func):  # was a bare TypeError ('NoneType' object is not callable) after the look-up
            raise XtopoError(f"Cache needs a function to call, got {type(func).__name__}")
        return os.path.join(os.path.abspath(self.directory), _key(func, checksum(ds), params) + ".nc")

    def _load(self, path: str):
        """The stored result (a private copy), or ``None`` when absent, damaged or another key's."""
        signature = _signature(path)
        if signature is None:
            return None
        held = _memory.get(path, signature)
        if held is None:
            try:
                held = _restore(read_netcdf(path), os.path.basename(path)[:-len(".nc")])
            except Exception:  # a damaged entry is recomputed, never trusted
                return None
            if held is None:
                return None
            _memory.put(path, signature, held, self.memory_bytes)
        return _private_copy(held)

    def __call__(self, func, ds, **params):
        """``func(ds, **params)``, from the cache when present, else computed and stored.

        DataArray results come back as DataArrays, Dataset results as Datasets; the
        first computation returns the stored form too (attributes as NetCDF holds them,
        e.g. bool → int), so a hit is identical to it.
        """
        path = self.path(func, ds, **params)
        stored = self._load(path)
        if stored is not None:
            self.hits += 1
            return stored
        self.misses += 1
        result = func(ds, **params)
        if not isinstance(result, (xr.Dataset, xr.DataArray)):
            raise XtopoError(f"Cache stores xarray results; {getattr(func, '__qualname__', func)!r} returned a "
                             f"{type(result).__name__}")
        result = result.compute()
        make_directory(self.directory, "cache directory")
        if isinstance(result, xr.DataArray):
            name = result.name if result.name is not None else "__xtopo_unnamed__"
            out = result.to_dataset(name=name)
            out.attrs = {"xtopo_cache_kind": "DataArray", "xtopo_cache_name": name}
        else:
            out = result.copy(deep=False)
            out.attrs = {**result.attrs, "xtopo_cache_kind": "Dataset"}
        out.attrs[_KEY_ATTR] = os.path.basename(path)[:-len(".nc")]
        out.attrs[_SUM_ATTR] = _content_sum(out)
        stored = None
        try:  # NetCDF-3 first: read back by scipy (pure Python) 15-25x faster than HDF5 (module docstring)
            atomic_write(path, lambda tmp: prepare_for_netcdf(out).to_netcdf(tmp, engine="scipy",
                                                                           format="NETCDF3_64BIT"))
            stored = self._load(path)  # None when NetCDF-3 changed it (int64, text): verified by its checksum
        except (TypeError, ValueError, OverflowError):  # content NetCDF-3 cannot hold (complex, non-Latin-1 text)
            pass
        if stored is None:
            to_netcdf(out, path, engine="h5netcdf")  # the library that reads it: one HDF5 lock, no netCDF-C
            stored = self._load(path)  # the stored form becomes the in-process copy (disk and memory hits agree)
        return result if stored is None else stored

    def clear(self) -> int:
        """Delete every cached result; return how many files were removed."""
        n = 0
        _memory.clear(os.path.abspath(self.directory))
        if os.path.isdir(self.directory):
            for f in os.listdir(self.directory):
                if f.endswith(".nc"):
                    os.unlink(os.path.join(self.directory, f))
                    n += 1
        return n
