"""Digital surface twins: all measurements of one physical surface in an ``xarray.DataTree``.

A twin has one child node per measurement (any mix of line and area scans,
sizes, instruments and units) and the surface's description in the root's attrs.
Scale-dependent averages over a twin are in :mod:`xtopo.stitching`; this
module builds, stores and restores twins.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from typing import Annotated

import xarray as xr

from .cache import freeze
from .conventions import CONVENTIONS, safe_name, validate
from .errors import ValidationError, XtopoError
from .io.netcdf import READ_ENGINES, read_netcdf, tree_to_netcdf
from .params import Flag, Path, checked

__all__ = ["twin", "open_twin", "to_netcdf", "measurements"]


def _open_lazily(path) -> xr.Dataset:
    """Open a file for a twin: xtopo NetCDF stays lazy (dask), other formats are read now."""
    from .io.open import open_topography
    from .io.registry import detect

    if any(fmt.name == "netcdf" for fmt in detect(path)):
        ds = read_netcdf(path, lazy=True)
        if "xtopo_version" in ds.attrs and "height" in ds:
            return validate(ds.chunk())
        ds.close()
    return open_topography(path)


def unique_name(name: str, taken) -> str:
    """``name``, or ``name_2``, ``name_3``, ... : the first not in ``taken``."""
    candidate, k = name, 1
    while candidate in taken:
        k += 1
        candidate = f"{name}_{k}"
    return candidate


def _name_of(ds: xr.Dataset, index: int) -> str:
    for key in ("title", "source_file", "instrument"):
        if ds.attrs.get(key):
            return safe_name(os.path.splitext(str(ds.attrs[key]))[0] if key == "source_file" else ds.attrs[key])
    return f"measurement_{index}"


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
            node = _name_of(ds, key)
        else:
            node = safe_name(os.path.splitext(os.path.basename(os.fspath(m)))[0])
        node = unique_name(node, nodes)
        nodes[node] = freeze(ds)
    if not nodes:
        raise XtopoError("a twin needs at least one measurement")
    root = {"Conventions": CONVENTIONS, **attrs}
    if name is not None:
        root["title"] = name
    return xr.DataTree.from_dict({"/": xr.Dataset(attrs=root), **{f"/{k}": v for k, v in nodes.items()}})


def measurements(tree: xr.DataTree) -> dict[str, xr.Dataset]:
    """The measurement Datasets of a twin by node name (children holding a ``height``).

    Parameters
    ----------
    tree : xarray.DataTree
        A twin (:func:`twin`, :func:`open_twin`).

    Raises
    ------
    ValidationError
        If ``tree`` is not a DataTree, or a node other than a child of the root holds a
        ``height`` (a measurement that the twin's analyses and archive would not see).
    """
    if not isinstance(tree, xr.DataTree):
        raise ValidationError(f"expected a twin (xarray.DataTree, see xtopo.twin), got {type(tree).__name__}")
    misplaced = [node.path for node in tree.subtree if node.level != 1 and "height" in node.dataset]
    if misplaced:
        raise ValidationError(f"a twin holds its measurements as children of the root, but node(s) {misplaced} "
                              "hold a 'height' too; build the twin with xtopo.twin (one node per measurement)")
    return {name: node.to_dataset() for name, node in tree.children.items() if "height" in node.dataset}


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
    # other groups (notes, stored results) are archived as they are
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
    from .io.container import container_twin, is_container

    if is_container(path):
        return container_twin(path, surface)
    if surface is not None:
        raise ValidationError(f"surface= applies to contact.engineering containers (ZIP); {path} is not one")
    try:
        tree = xr.open_datatree(path, engine=engine or READ_ENGINES["hdf5"])
    except (OSError, ValueError, KeyError, RuntimeError, TypeError) as exc:
        from .errors import ReaderError

        raise ReaderError(path, f"not a readable twin archive: {exc}") from None
    with tree:
        loaded = tree.load()
    out = {}
    for node in loaded.subtree:
        ds = node.to_dataset(inherit=False)
        ds.encoding = {}
        for v in ds.variables.values():
            v.encoding = {}
        out[node.path] = freeze(ds) if "height" in ds else ds
    return xr.DataTree.from_dict(out)
