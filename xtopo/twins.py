"""Digital surface twins: all measurements of one physical surface in an ``xarray.DataTree``.

A twin has one child node per measurement (any mix of line and area scans,
sizes, instruments and units) and the surface's description in the root's attrs.
Scale-dependent averages over a twin are in :mod:`xtopo.stitching`; this
module builds, stores and restores twins.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Iterable, Mapping
from typing import Annotated

import xarray as xr

from ._tree import freeze, make_twin, measurements, name_of, unique_name
from .conventions import safe_name, validate
from .errors import ReaderError, ValidationError
from .io.container import container_twin, is_container
from .io.netcdf import READ_ENGINES, lazy_xtopo_netcdf, read_netcdf, tree_to_netcdf
from .io.open import open_topography
from .io.registry import detect
from .params import Flag, Path, checked

__all__ = ["twin", "open_twin", "to_netcdf", "measurements"]


def _open_lazily(path) -> xr.Dataset:
    """Open a file for a twin: xtopo NetCDF stays lazy (dask, where installed), other formats are read now."""
    if any(fmt.name == "netcdf" for fmt in detect(path)):
        lazy = importlib.util.find_spec("dask") is not None  # without the [dask] extra: read now
        ds = lazy_xtopo_netcdf(path) if lazy else None
        if ds is not None:
            return ds
        ds = read_netcdf(path, lazy=lazy)
        if "xtopo_version" in ds.attrs and "height" in ds:
            return ds.chunk() if lazy else ds
        ds.close()
    return open_topography(path)


def twin(measurements, *, name: str | None = None, **attrs) -> xr.DataTree:
    """Build a digital surface twin from measurements.

    Parameters
    ----------
    measurements : mapping of str to Dataset/path, or iterable of Dataset/path
        The measurements of one surface. Paths are opened with
        :func:`xtopo.open_topography` (xtopo NetCDF files lazily, as dask arrays).
        Node names come from the mapping keys, else from the file name (paths), else from
        ``title``/``source_file`` (a reader's ``title`` is often only a channel name: "Raw").
        A twin is an archive: in-memory data are stored as read-only copies
        (:func:`xtopo.cache.freeze`), so the cache checksums each array once and
        nothing can change a measurement behind the twin's back (write into a
        ``.copy()`` instead). Lazy (dask) data stay lazy.
    name : str, optional
        Name of the surface (root attr ``title``).
    **attrs
        Further root attributes (``description``, ``material``, ...).

    Returns
    -------
    xarray.DataTree
    """
    if isinstance(measurements, xr.DataTree):
        return measurements
    if isinstance(measurements, (str, os.PathLike, xr.Dataset)) or not isinstance(measurements, Iterable):
        raise ValidationError(f"measurements must be a mapping or a list of Datasets/paths, got "
                              f"{type(measurements).__name__}")
    items = measurements.items() if isinstance(measurements, Mapping) else enumerate(measurements)
    nodes: dict[str, xr.Dataset] = {}
    for key, m in items:
        if not isinstance(m, (xr.Dataset, str, os.PathLike)):
            raise ValidationError(f"measurement {key!r} must be an xarray.Dataset or a file path, got "
                                  f"{type(m).__name__}")
        ds = m if isinstance(m, xr.Dataset) else _open_lazily(os.fspath(m))
        try:
            validate(ds)
        except ValidationError as exc:
            raise ValidationError(f"measurement {key!r}: {exc}") from None
        if isinstance(key, str):
            node = safe_name(key)
        elif isinstance(m, xr.Dataset):
            node = name_of(ds, key)
        else:
            node = safe_name(os.path.splitext(os.path.basename(os.fspath(m)))[0])
        nodes[unique_name(node, nodes)] = ds
    return make_twin(nodes, name=name, **attrs)


@checked
def to_netcdf(tree: xr.DataTree, path: Annotated[str, Path("file path")], engine: str | None = None, *,
              checksums: Annotated[bool, Flag(error=ValidationError)] = True) -> str:
    """Archive a twin as one NetCDF file: a group per measurement, CF/ACDD and provenance on the root.

    Other groups of the tree (notes, stored results) are written as they are.

    Parameters
    ----------
    tree : xarray.DataTree
        The twin.
    path : str or os.PathLike
        Target file, written atomically.
    engine : {"netcdf4", "h5netcdf"}, optional
    checksums : bool
        Keep the measurements' ``source_sha256`` attrs (checksums of the original files)
        and list them on the root as ``source_checksums``.

    Returns
    -------
    str
    """
    ms = measurements(tree)
    root = tree.to_dataset(inherit=False)
    root.attrs.pop("source_checksums", None)  # listed afresh from the measurements archived now
    nodes = {node.path: node.to_dataset(inherit=False) for node in tree.subtree if not node.is_root}
    sums = []
    for name, ds in ms.items():
        ds = ds.copy(deep=False)
        if checksums and ds.attrs.get("source_sha256"):
            sums.append(f"{name}: {ds.attrs['source_sha256']}")
        elif not checksums:
            ds.attrs.pop("source_sha256", None)
        nodes[f"/{name}"] = ds
    if sums:
        root.attrs["source_checksums"] = "\n".join(sums)
    return tree_to_netcdf(xr.DataTree.from_dict({"/": root, **nodes}), path, engine)


@checked
def open_twin(path: Annotated[str, Path("file path")], engine: str | None = None, *, surface=None) -> xr.DataTree:
    """Restore a twin archived with :func:`to_netcdf`, or read one from a contact.engineering container (ZIP).

    Data are loaded into read-only memory, as in :func:`twin`. A contact.engineering download
    (ZIP with ``index.json`` or ``meta.yml``) gives the twin of its surface, with the stored height
    scale, filling and detrending applied (see :mod:`xtopo.io.container`); a container with several
    surfaces needs ``surface=`` (or read them all with :func:`xtopo.io.open_container`).

    Parameters
    ----------
    path : str or os.PathLike
        The archive (NetCDF) or the container (ZIP).
    engine : {"netcdf4", "h5netcdf"}, optional
        NetCDF library (default ``h5netcdf``: a damaged archive cannot crash the interpreter, see
        :data:`xtopo.io.netcdf.READ_ENGINES`).
    surface : str or int, optional
        For a container: the surface's name or index.
    """
    if is_container(path):
        return container_twin(path, surface)
    if surface is not None:
        raise ValidationError(f"surface= applies to contact.engineering containers (ZIP); {path} is not one")
    try:
        tree = xr.open_datatree(path, engine=engine or READ_ENGINES["hdf5"])
    except (OSError, ValueError, KeyError, RuntimeError, TypeError) as exc:
        raise ReaderError(path, f"not a readable twin archive: {exc}") from None
    with tree:
        loaded = tree.load()
    nodes = {node.path: node.to_dataset(inherit=False).drop_encoding() for node in loaded.subtree}
    return xr.DataTree.from_dict({key: freeze(ds) if "height" in ds else ds for key, ds in nodes.items()})
