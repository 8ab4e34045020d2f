"""NetCDF out and in: CF-1.12/ACDD-1.3 attributes, provenance, atomic writes.

:func:`to_netcdf` writes a measurement (or any xtopo result Dataset) to a
temporary file next to the target and moves it into place with ``os.replace``,
so a write that fails midway never destroys an existing file.
"""

from __future__ import annotations

import datetime as _dt
import importlib.util
import json
import os
import tempfile
from typing import Annotated

import h5py
import numpy as np
import xarray as xr

from .._version import __version__
from ..conventions import CONVENTIONS, provenance_of
from ..errors import ReaderError, ValidationError, WriteError, XtopoError
from ..params import Choice, Flag, Path, checked
from ._netcdf3 import check_netcdf3_header

_FILE = Path("file path")

__all__ = ["to_netcdf", "tree_to_netcdf", "read_netcdf", "read_engine", "READ_ENGINES", "open_contact",
           "is_contact_result", "atomic_write", "prepare_for_netcdf", "sanitize_attrs", "provenance_attrs",
           "ENGINES"]

ENGINES = ("netcdf4", "h5netcdf")
#: Attributes the writer sets; they describe the file, not the data.
PROVENANCE_KEYS = ("Conventions", "xtopo_version", "date_created", "product_version", "processing_level")


_INT64 = np.iinfo(np.int64)


def _sanitize_value(value):
    if isinstance(value, (bool, np.bool_)):
        return int(value)
    if value is None:
        return None
    if isinstance(value, str):
        return str(value)  # numpy's str_ (a str subclass) has no HDF5 type
    if isinstance(value, int) and not _INT64.min <= value <= _INT64.max:
        return str(value)  # NetCDF stores at most 64-bit integers
    if isinstance(value, dict):
        return json.dumps(value, default=str, sort_keys=True)
    if isinstance(value, (_dt.datetime, _dt.date)):
        return value.isoformat()
    if isinstance(value, (list, tuple)):
        if all(isinstance(v, str) for v in value):
            return json.dumps(list(value))
        try:
            arr = np.asarray([_sanitize_value(v) for v in value])
        except ValueError:  # ragged nesting
            arr = None
        ok = arr is not None and arr.ndim == 1 and arr.dtype.kind in "iuf"
        return arr if ok else json.dumps(list(value), default=str)
    if isinstance(value, np.ndarray):
        if value.ndim > 1:  # NetCDF attributes are 1D
            return json.dumps(value.tolist(), default=str)
        if value.dtype == bool:
            return value.astype(np.int8)
        return value if value.dtype.kind in "iufS" else json.dumps(value.tolist(), default=str)
    if isinstance(value, (str, int, float, np.integer, np.floating, bytes)):
        return value
    return str(value)


def sanitize_attrs(attrs: dict) -> dict:
    """Attributes NetCDF can store: bool → int, dict/list of str/nested list/2D array → JSON,
    integers beyond 64 bits → str, None dropped."""
    out = {}
    for key, value in attrs.items():
        v = _sanitize_value(value)
        if v is not None:
            out[str(key)] = v
    return out


def provenance_attrs(attrs: dict) -> dict:
    """``attrs`` with the CF/ACDD and provenance attributes the writer adds."""
    now = _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()
    out = dict(attrs)
    out["Conventions"] = CONVENTIONS
    out.setdefault("date_created", now)
    out["xtopo_version"] = __version__
    out.setdefault("product_version", __version__)
    return out


def prepare_for_netcdf(ds: xr.Dataset, *, provenance: bool = True) -> xr.Dataset:
    """``ds`` with sanitised attributes, CF/ACDD provenance (unless not wanted, e.g. for
    groups below an archive's root) and only encodings NetCDF understands."""
    ds = ds.copy(deep=False)
    ds.attrs = sanitize_attrs(provenance_attrs(ds.attrs) if provenance else ds.attrs)
    for name in list(ds.variables):
        ds[name].attrs = sanitize_attrs(ds[name].attrs)
        ds[name].encoding = {k: v for k, v in ds[name].encoding.items()
                             if k in ("dtype", "_FillValue", "zlib", "complevel", "chunksizes", "units",
                                      "calendar", "compression")}
    return ds


def check_engine(engine: str | None) -> str:
    """The engine to use (default ``netcdf4`` if installed); raise for unknown ones."""
    if engine is not None:
        return Choice(*ENGINES).check(engine, "engine")
    return "netcdf4" if importlib.util.find_spec("netCDF4") is not None else "h5netcdf"


def _file_mode(path) -> int:
    """Mode for the new file: that of the file it replaces, else 0o666 minus the umask."""
    try:
        return os.stat(path).st_mode & 0o777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


def atomic_write(path, write) -> str:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then move it into place.

    A ``write`` that fails (or a process that dies) leaves an existing ``path`` untouched
    and no temporary file behind (the latter except on a hard kill).

    Raises
    ------
    WriteError
        When the file cannot be created or written (an ``OSError`` from ``write`` included);
        other exceptions of ``write`` propagate unchanged.
    """
    directory = os.path.dirname(os.path.abspath(path))
    try:
        fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".", suffix=".tmp", dir=directory)
    except OSError as exc:  # name the target, not the temporary file
        raise WriteError(exc.errno, f"cannot write {path}: {exc.strerror}") from None
    os.close(fd)
    try:
        write(tmp)
        os.chmod(tmp, _file_mode(path))
        os.replace(tmp, path)
    except BaseException as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError) and not isinstance(exc, WriteError):
            error = WriteError(exc.errno, f"cannot write {path}: {exc.strerror or exc}")
            if exc.filename == tmp:  # the temporary file's name says nothing to the caller
                raise error from None
            raise error from exc
        raise
    return path


@checked
def to_netcdf(ds, path: Annotated[str, _FILE], engine: str | None = None, *,
              compress: Annotated[bool, Flag()] = False) -> str:
    """Write ``ds`` to ``path`` atomically, with CF/ACDD and provenance attributes.

    Parameters
    ----------
    ds : xarray.Dataset or xarray.DataArray
        A measurement or an analysis result (a DataArray is written as its Dataset, its
        ``source_file``, ``source_sha256`` and ``history`` as the file's global attributes).
    path : str or os.PathLike
        Target file; replaced only once the new file is complete.
    engine : {"netcdf4", "h5netcdf"}, optional
        Default ``netcdf4`` if installed.
    compress : bool
        zlib-compress float variables.

    Returns
    -------
    str
        The path written.

    Raises
    ------
    ValidationError
        A variable NetCDF cannot hold (e.g. complex values with ``netcdf4``); nothing is written.
    """
    if isinstance(ds, xr.DataArray):
        # its provenance (an analysis result's source file and history) belongs to the file (CF: global)
        moved = provenance_of(ds)
        ds = ds.copy(deep=False)
        ds.attrs = {k: v for k, v in ds.attrs.items() if k not in moved}
        ds = ds.to_dataset(name=ds.name or "data").assign_attrs(moved)
    if not isinstance(ds, xr.Dataset):
        raise XtopoError(f"to_netcdf expects an xarray Dataset, got {type(ds).__name__}")
    engine = check_engine(engine)
    out = prepare_for_netcdf(ds)
    codec = {"zlib": True} if engine == "netcdf4" else {"compression": "gzip"}
    encoding = {v: dict(codec) for v in out.data_vars if compress and out[v].dtype.kind == "f"}
    return atomic_write(path, lambda tmp: _write(out, tmp, path, engine=engine, encoding=encoding))


def _write(obj, tmp, path, **kwargs):
    """``obj.to_netcdf(tmp)``; xarray's refusal of content NetCDF cannot hold becomes a ValidationError."""
    try:
        obj.to_netcdf(tmp, **kwargs)
    except (TypeError, ValueError) as exc:
        raise ValidationError(f"cannot write {os.fspath(path)}: {exc}") from exc


@checked
def tree_to_netcdf(tree: xr.DataTree, path: Annotated[str, _FILE], engine: str | None = None) -> str:
    """Write every node of a DataTree as a NetCDF group (atomically); provenance on the root only.

    Each group holds the coordinates it inherits too (``measurement`` names), so that a group opened
    on its own (``xr.open_dataset(path, group="psd")``) is labelled; :func:`xarray.open_datatree`
    reads them back as inherited.
    """
    engine = check_engine(engine)
    groups = [(node.path, prepare_for_netcdf(node.to_dataset(inherit=not node.is_root), provenance=node.is_root))
              for node in tree.subtree]

    def write(tmp):
        for k, (group, ds) in enumerate(groups):
            _write(ds, tmp, path, engine=engine, mode="a" if k else "w", group=None if group == "/" else group)

    return atomic_write(path, write)


#: The engines that read files xtopo did not just write (archives, cache entries, twins, batch stores, files
#: from elsewhere). Why (issue 24; measured with tests/io/test_netcdf_fuzz.py's mutants, each read in a
#: child process):
#:
#: * netCDF-C (the netCDF4 library) is never handed an untrusted file: a NetCDF-3 header whose dimension
#:   count reads 2**31 kills the interpreter (SIGSEGV) — xtopo reached it through the SurfaceTopography
#:   reader's engine fallback — another header mutant made it allocate 14 GB, and an outside audit saw
#:   NetCDF-4 mutants crash it, one only at the next garbage collection. It parses NetCDF-4's own layer
#:   (dimension scales, hidden attributes) on top of HDF5, so h5py's attack surface is a subset of it.
#: * NetCDF-4/HDF5 files are read with h5netcdf (h5py): 0 crashes in the fuzz runs (1,100+ HDF5 mutants of
#:   measurements and twins, and the slow test's). Cost: a read takes 20-40 ms more (64²: 50 ms against
#:   12 ms median; 1024²: 61 against 40), paid once per file; the cache avoids it (NetCDF-3 entries).
#: * NetCDF-3 files are read with scipy (pure Python) once :func:`check_netcdf3_header` has bounded every
#:   size in the header by the file's size (scipy allocated up to 16 GB for a 14 kB file).
#: * Isolating every read in a subprocess was the alternative: 2-5 s per read for the imports here, and a
#:   result copied across processes; refused.
READ_ENGINES = {"netcdf3": "scipy", "hdf5": "h5netcdf"}


def read_engine(path) -> str:
    """The engine that reads ``path`` safely: ``scipy`` for NetCDF-3 (header checked first), else ``h5netcdf``."""
    with open(path, "rb") as f:
        head = f.read(4)
    if head[:3] == b"CDF":
        check_netcdf3_header(path)
        return READ_ENGINES["netcdf3"]
    return READ_ENGINES["hdf5"]


@checked
def read_netcdf(path: Annotated[str, _FILE], *, engine: str | None = None, lazy: bool = False) -> xr.Dataset:
    """Open an xtopo NetCDF file; loaded into memory unless ``lazy``.

    Without ``engine``, NetCDF-4/HDF5 files are read with h5netcdf and NetCDF-3 files with scipy after
    a check of their header (:data:`READ_ENGINES`): no file can crash the interpreter or make the reader
    allocate more than the file holds.
    """
    try:
        if engine is None:  # naming the engine skips xarray's guessing over every backend (ours included)
            engine = read_engine(path)
        ds = xr.open_dataset(path, engine=engine)
    except (OSError, ValueError, KeyError, RuntimeError, TypeError, IndexError) as exc:
        raise ReaderError(path, f"not a readable NetCDF/HDF5 file: {exc}") from None
    if lazy:
        return ds
    with ds:
        out = ds.load()
    for name in out.variables:
        out[name].encoding.pop("source", None)
    out.encoding.pop("source", None)
    return out


#: variables by which a Dataset is a contact result (xtopo.contact.Scene.solve/curve, xtopo contact)
_CONTACT_VARIABLES = ("area_fraction", "converged")


def is_contact_result(ds) -> bool:
    """Whether ``ds`` holds a contact result (``area_fraction`` and ``converged``) rather than a measurement."""
    return all(v in ds.variables for v in _CONTACT_VARIABLES) and "height" not in ds.variables


def open_contact(path, *, engine: str | None = None) -> xr.Dataset:
    """Read back a contact result written with :func:`to_netcdf` or by ``xtopo contact``.

    :func:`xtopo.open_topography` reads measurements (a ``height``); a contact result (maps
    and scalars of :meth:`xtopo.contact.Scene.solve`/``curve``, units and provenance kept) is
    read with this function.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    engine : {"netcdf4", "h5netcdf"}, optional
        NetCDF library (default: from the file's first bytes).

    Returns
    -------
    xarray.Dataset
        The result as it was written, loaded into memory.

    Raises
    ------
    ReaderError
        The file is not readable, or holds no contact result (e.g. a measurement).
    """
    ds = read_netcdf(path, engine=engine)
    if not is_contact_result(ds):
        what = "a measurement; read it with xtopo.open_topography" if "height" in ds else (
            f"no contact result (variables {sorted(map(str, ds.data_vars))})")
        raise ReaderError(path, f"this file holds {what}")
    return ds


#: attrs by which xarray would decode a variable (then the file is opened by xarray)
_DECODED = {"scale_factor", "add_offset", "missing_value", "_Unsigned", "calendar", "coordinates", "dtype"}
_HIDDEN = {"REFERENCE_LIST", "CLASS", "DIMENSION_LIST", "NAME", "_Netcdf4Dimid", "_Netcdf4Coordinates",
           "_nc3_strict", "_NCProperties", "_FillValue"}


def _attrs(h5attrs) -> dict:
    """HDF5 attributes as h5netcdf and xarray give them (strings decoded, one-element arrays as scalars)."""
    out = {}
    for key in h5attrs:
        if key not in _HIDDEN:
            v = h5attrs[key]
            if isinstance(v, bytes):
                v = v.decode("utf-8", "surrogateescape")
            elif not isinstance(v, (str, np.number, np.ndarray)) or isinstance(v, np.ndarray) and v.dtype.kind in "OSU":
                raise ValueError(f"attribute {key!r} of type {type(v).__name__}")
            out[key] = v[0] if isinstance(v, np.ndarray) and v.shape == (1,) else v
    return out


def _read_variable(path, name):
    """The values of variable ``name`` of an xtopo NetCDF file (in a worker, for :func:`lazy_xtopo_netcdf`)."""
    with read_netcdf(path, lazy=True) as ds:
        return ds[name].values


def lazy_xtopo_netcdf(path) -> xr.Dataset | None:
    """A measurement written by xtopo (:func:`to_netcdf`) as a Dataset whose data dask reads when computed (:func:`read_netcdf`,
    one task a variable); its coordinates and attributes are read now with h5py (a twin of a thousand files:
    3 ms a file, xarray's open took 14). None for anything else (xarray opens it then)."""
    import dask  # deferred: called where dask is installed (the core install has none)
    import dask.array as da
    from dask.base import tokenize

    try:
        with h5py.File(path, "r") as f:
            if "xtopo_version" not in f.attrs or "height" not in f or not set(f) <= {"height", "mask", "x", "y"}:
                return None
            dims = {int(f[d].attrs["_Netcdf4Dimid"]): d for d in ("x", "y") if d in f}
            coords, data = {}, {}
            for name, v in f.items():
                attrs = _attrs(v.attrs)
                fill = v.attrs.get("_FillValue", np.nan)
                dtype = np.dtype(bool) if attrs.get("dtype") == "bool" and v.dtype == np.int8 else v.dtype
                if dtype == bool:  # a mask: int8 on disk, decoded to bool
                    del attrs["dtype"]
                if _DECODED & set(attrs) or dtype.kind not in "fb" or " since " in str(attrs.get("units", "")):
                    return None
                var_dims = tuple(dims[int(i)] for i in v.attrs["_Netcdf4Coordinates"])
                if name in dims.values():
                    values = v[()]
                    if var_dims != (name,) or np.any(values == fill):
                        return None
                    coords[name] = (var_dims, values, attrs)
                else:
                    data[name] = (var_dims, v.shape, dtype, attrs)
            stamp = os.stat(path)
            key = tokenize(os.path.abspath(path), stamp.st_mtime_ns, stamp.st_size)
            return xr.Dataset({name: (d, da.from_delayed(dask.delayed(_read_variable, pure=True)(
                path, name, dask_key_name=f"xtopo-read-{name}-{key}"), shape, dtype=dtype, name=f"xtopo-{name}-{key}"),
                a) for name, (d, shape, dtype, a) in data.items()}, coords=coords, attrs=_attrs(f.attrs))
    except (OSError, ValueError, KeyError, TypeError):
        return None  # xarray opens it, and says what is wrong
