"""The twin's data model: an ``xarray.DataTree`` whose root's children are the measurements.

Below both the twins (:mod:`xtopo.twins`) and the storage formats of twins (NetCDF archives,
contact.engineering containers in :mod:`xtopo.io.container`): node names, the frozen (read-only)
measurements and the tree itself.
"""

from __future__ import annotations

import os
from typing import Annotated

import numpy as np
import xarray as xr

from .conventions import CONVENTIONS, safe_name
from .errors import ValidationError, XtopoError
from .params import Data, checked

__all__ = ["make_twin", "measurements", "freeze", "unique_name", "name_of"]


def _immutable(arr: np.ndarray) -> bool:
    """True when no one can write to ``arr``'s memory: a read-only chain of views ending in ``bytes``."""
    base = arr
    while isinstance(base, np.ndarray):
        if base.flags.writeable:
            return False
        base = base.base
    return isinstance(base, bytes)


@checked
def freeze(ds: Annotated[xr.Dataset, Data("Dataset")]) -> xr.Dataset:
    """A copy of ``ds`` whose numpy-backed variables live in immutable memory.

    Their checksums are computed once per array and remembered, so repeated
    :class:`xtopo.cache.Cache` look-ups of the same frozen measurement skip hashing its data.
    Writing into the arrays raises ``ValueError`` (numpy refuses to make them writeable).
    Dask-backed variables are left as they are.
    """
    out = ds.copy(deep=False)
    for name, var in ds.variables.items():
        if name in ds.indexes or not isinstance(var.data, np.ndarray) or var.dtype.hasobject:
            continue
        data = np.ascontiguousarray(var.data)
        out[name].variable.data = np.frombuffer(data.tobytes(), dtype=data.dtype).reshape(data.shape)
    return out


def unique_name(name: str, taken) -> str:
    """``name``, or ``name_2``, ``name_3``, ... : the first not in ``taken``."""
    candidate, k = name, 1
    while candidate in taken:
        k += 1
        candidate = f"{name}_{k}"
    return candidate


def name_of(ds: xr.Dataset, index: int) -> str:
    """A node name for a measurement: its ``title``, source file or instrument, else ``measurement_<index>``."""
    for key in ("title", "source_file", "instrument"):
        if ds.attrs.get(key):
            return safe_name(os.path.splitext(str(ds.attrs[key]))[0] if key == "source_file" else ds.attrs[key])
    return f"measurement_{index}"


def measurements(tree: xr.DataTree) -> dict[str, xr.Dataset]:
    """The measurement Datasets of a twin by node name (children holding a ``height``).

    Parameters
    ----------
    tree : xarray.DataTree
        A twin (:func:`xtopo.twin`, :func:`xtopo.open_twin`).

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


def make_twin(nodes: dict, *, name: str | None = None, **attrs) -> xr.DataTree:
    """A twin of measurements by (unique, safe) node name: frozen copies (:func:`freeze`) under a root
    holding ``Conventions``, ``title`` (the surface's ``name``) and ``attrs``."""
    if not nodes:
        raise XtopoError("a twin needs at least one measurement")
    root = {"Conventions": CONVENTIONS, **attrs}
    if name is not None:
        root["title"] = name
    return xr.DataTree.from_dict({"/": xr.Dataset(attrs=root), **{f"/{k}": freeze(v) for k, v in nodes.items()}})
