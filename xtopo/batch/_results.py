"""The layout of a batch's results: items → one chunk's Dataset → the batch's Dataset.

A result has the dims ``measurement`` (and the parameter dim, e.g. ``load``, when the batch
has parameter values), a ``source`` coordinate (the file each measurement was read from),
a ``history`` coordinate (each measurement's processing history, when the results carry
one) and a string variable ``error`` ('' where the item succeeded).

A failed item holds NaN in every numeric variable and '' in every string one. NaN has no
integer or boolean form, so in a result where some item failed an integer or boolean
variable (contact's ``iterations``, ``converged``) is a float one (1.0/0.0 for True/False,
NaN for the failed items); where none failed it keeps its type.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from ..io.netcdf import prepare_for_netcdf

__all__ = ["MEASUREMENT", "ERROR", "HISTORY", "SOURCE", "chunk_dataset", "failure_block", "combine", "failed_items"]

MEASUREMENT = "measurement"
ERROR = "error"
HISTORY = "history"
SOURCE = "source"
_ERROR_ATTRS = {"long_name": "error message of the failed item ('' where it succeeded)"}
_HISTORY_ATTRS = {"long_name": "processing history of each measurement's result ('' for a failed one)"}


def _blank_missing_strings(ds: xr.Dataset) -> xr.Dataset:
    """'' for the missing entries of string variables (an outer join fills them with NaN, a float)."""
    for name, var in ds.data_vars.items():
        if var.dtype.kind in "OU":
            ds[name] = var.fillna("").astype(object)
    return ds


def chunk_dataset(names, sources, results, errors, params, dim) -> xr.Dataset:
    """One chunk's Dataset: the items' results stacked along ``measurement`` (and ``dim``), plus ``error``.

    Parameters
    ----------
    names, sources : list
        The chunk's measurement names and sources (Dataset or file path).
    results : list of xarray.Dataset or None
        One per measurement (None where every item of it failed).
    errors : list of list of str
        One row per measurement, one message per parameter value ('' where it worked).
    params : list or None
        The chunk's parameter values along ``dim`` (None: a batch without parameters).
    dim : str
        Name of the parameter dimension.

    Returns
    -------
    xarray.Dataset
        With its attributes as the store holds them (bool → int, dict → JSON), so that a chunk
        computed now equals one read back from the store.
    """
    coords = {MEASUREMENT: (MEASUREMENT, list(names), {"long_name": "measurement"}),
              SOURCE: (MEASUREMENT, [s if isinstance(s, str) else "" for s in sources],
                       {"long_name": "file the measurement was read from ('' for in-memory data)"})}
    # each measurement's own history (its input's, plus what the function did) would conflict with the
    # others' and be dropped as a Dataset attribute: it is kept per measurement, as a coordinate
    history = [r.attrs.get("history", "") if r is not None else "" for r in results]
    if any(history):
        coords[HISTORY] = (MEASUREMENT, history, dict(_HISTORY_ATTRS))
    good = [r.drop_attrs(deep=False).assign_attrs({k: v for k, v in r.attrs.items() if k != "history"})
            .expand_dims({MEASUREMENT: [n]}) for n, r in zip(names, results) if r is not None]
    if len(good) == len(names) == 1:  # a chunk of one measurement: nothing to align (a third of its overhead)
        ds = good[0]
    elif good:
        ds = xr.concat(good, dim=MEASUREMENT, join="outer", combine_attrs="drop_conflicts", data_vars="all")
        ds = ds.reindex({MEASUREMENT: list(names)})
    else:
        ds = xr.Dataset()
    err_dims = (MEASUREMENT,) if params is None else (MEASUREMENT, dim)
    if params is not None:
        attrs = ds[dim].attrs if dim in ds.coords else {}
        if dim in ds.dims and list(ds[dim].values) != list(params):
            ds = ds.reindex({dim: list(params)})
        coords[dim] = (dim, list(params), attrs)
    err = np.array(errors, dtype=object).reshape([len(names)] + ([] if params is None else [len(params)]))
    ds = _blank_missing_strings(ds.assign_coords(coords))
    ds[ERROR] = (err_dims, err, dict(_ERROR_ATTRS))

    return prepare_for_netcdf(ds, provenance=False)


def failure_block(names, sources, params, dim, message: str) -> xr.Dataset:
    """The Dataset of a chunk none of whose items has a result: every item failed with ``message``."""
    n = 1 if params is None else len(params)
    return chunk_dataset(names, sources, [None] * len(names), [[message] * n for _ in names], params, dim)


def _same_histories(blocks):
    """Every block with the ``history`` coordinate where one has it, the same along a row (one measurement's
    chunks of parameter values): the first non-empty entry of the row (a failed chunk has none)."""
    attrs = next((b[HISTORY].attrs for row in blocks for b in row if HISTORY in b.coords), None)
    if attrs is None:
        return blocks
    out = []
    for row in blocks:
        found = [[str(h) for h in b[HISTORY].values] if HISTORY in b.coords else [] for b in row]
        merged = [next((h[i] for h in found if h and h[i]), "") for i in range(row[0].sizes[MEASUREMENT])]
        out.append([b.assign_coords({HISTORY: (MEASUREMENT, merged, dict(attrs))}) for b in row])
    return out


def combine(blocks, dim, has_params: bool, dim_attrs: dict | None) -> xr.Dataset:
    """The chunks' Datasets (rows: blocks of measurements; columns: blocks of parameter values) as one.

    ``dim_attrs``: the attributes of the ``dim`` coordinate where no chunk gives any.
    """
    blocks = _same_histories(blocks)
    options = dict(join="outer", combine_attrs="drop_conflicts", data_vars="all", coords="minimal",
                   compat="override")
    if has_params:
        ds = xr.combine_nested(blocks, concat_dim=[MEASUREMENT, dim], **options)
        if dim_attrs and not ds[dim].attrs:
            ds[dim].attrs = dict(dim_attrs)
    else:
        ds = xr.combine_nested([row[0] for row in blocks], concat_dim=MEASUREMENT, **options)
    ds = _blank_missing_strings(ds)
    ds[ERROR].attrs = dict(_ERROR_ATTRS)
    return ds


def failed_items(ds: xr.Dataset, dim: str) -> list[str]:
    """``"<measurement>: <error>"`` (``"<measurement> [<dim>=<value>]: <error>"``) for every failed item."""
    err = ds[ERROR]
    out = []
    for (i, *j), e in np.ndenumerate(err.values):  # err's dims: (measurement, dim) or (measurement,)
        if e:
            at = f" [{dim}={err[dim].values[j[0]]}]" if j else ""
            out.append(f"{err[MEASUREMENT].values[i]}{at}: {e}")
    return out
