"""One measurement's analysis as one dask task (the per-measurement stage of a twin average).

Built with xarray on dask, a twin average was dozens of small tasks per measurement, and building them
cost the client more than the workers spent analysing. :func:`one_task` takes the coordinates from the
lazy result of another measurement of the same shape (:func:`template`, built once) and computes the
values by one task that reads the measurement and runs the in-memory analysis on it (dask's synchronous
scheduler), checking that its result has the template's coordinates; only the small outputs come back.
"""

from __future__ import annotations

import operator

import numpy as np
import xarray as xr

from ._worker import tune_malloc
from .errors import XtopoError

__all__ = ["one_task", "template"]


class _Opaque:
    """Holds dask collections as plain data, so that ``dask.delayed`` does not make them dependencies."""

    __slots__ = ("items",)

    def __init__(self, items):
        self.items = items


def _dask_parts(obj) -> list:
    """Names of ``obj``'s dask-backed data (None) and non-index coordinates."""
    if not isinstance(obj, xr.DataArray):
        return []
    return ([None] if obj.chunks is not None else []) + [
        name for name, c in obj.coords.items() if c.chunks is not None and name not in obj.dims]


def _fingerprint(objs, parts) -> str:
    """What a lazy result takes from its template: each object's dims, name, units and its numpy
    data and coordinates (values and attrs); of its dask-backed ``parts``, the shapes."""
    from dask.base import tokenize  # deferred, as all dask here: lazy data only (the core install has no dask)

    return tokenize([None if o is None else (
        o.dims, o.name, o.attrs.get("units"), o.attrs.get("long_name"),
        [(n, (o.variable if n is None else o.coords[n].variable).shape) for n in p],
        None if None in p else o.values,
        [(n, c.dims, c.attrs, c.values) for n, c in o.coords.items() if n not in p]) for o, p in zip(objs, parts)])


def _compute_here(fn, held: _Opaque, parts, check: str) -> list:
    import dask

    tune_malloc()  # in a distributed worker, FFT-sized temporaries were fresh mmaps: 1.4x the serial time
    (ds,) = dask.compute(held.items, scheduler="sync")
    out = fn(ds)
    if _fingerprint(out, parts) != check:
        raise XtopoError("a measurement's analysis gave other coordinates than the lazy graph of another "
                         "measurement of its shape (the coordinates depend on attributes outside "
                         "conventions.MEASUREMENT_ATTRS); load the twin into memory (.compute()) first")
    return [np.asarray(o.variable.data if n is None else o.coords[n].data) for o, p in zip(out, parts) for n in p]


def template(like: tuple) -> tuple:
    """``like`` (lazy results of an analysis of one measurement), the names of their dask-backed parts and
    their fingerprint: what :func:`one_task` needs of them, worked out once for all measurements of a shape."""
    parts = [_dask_parts(o) for o in like]
    return like, parts, _fingerprint(like, parts)


def one_task(fn, ds: xr.Dataset, like: tuple) -> tuple:
    """The lazy results of :func:`template` ``like`` with their dask data and non-index coordinates replaced by
    those of ``fn(ds)``, computed by one task.

    The task computes ``ds`` there (dask's synchronous scheduler) and runs ``fn`` on it in memory.
    """
    import dask  # deferred: the core install has no dask, and then no lazy data reach here
    import dask.array as da
    from dask.base import tokenize
    from dask.highlevelgraph import HighLevelGraph

    like, parts, check = like
    lazy = [(o.variable if n is None else o.coords[n].variable) for o, p in zip(like, parts) for n in p]
    name = "xtopo-one-task-" + tokenize(ds, [v.data.name for v in lazy])
    task = dask.delayed(_compute_here, pure=True)(fn, _Opaque(ds), parts, check, dask_key_name=name)
    out, i = [], 0
    for obj, p in zip(like, parts):
        for n in p:
            a = lazy[i].data
            # the array's one chunk is the task's i-th output: one task per part (from_delayed added a second)
            key = f"{name}-a{i}"
            graph = HighLevelGraph.from_collections(key, {(key,) + (0,) * a.ndim: (operator.getitem, name, i)},
                                                    dependencies=[task])
            new = da.Array(graph, key, tuple((s,) for s in a.shape), dtype=a.dtype, meta=a._meta)
            obj = obj.copy(data=new) if n is None else obj.assign_coords({n: lazy[i].copy(data=new)})
            i += 1
        out.append(obj)
    return tuple(out)
