"""Lazy xarray objects whose dask graph runs as one task (the per-measurement stage of a twin average).

A twin average builds, for every measurement, a chain of a few dozen small dask tasks (read,
fill, spectrum, reliability masks, errors). On a distributed cluster each task costs a
scheduler round trip and a transfer of its intermediate result, so a twin of a thousand
measurements spent more time in the scheduler than in the analyses. :func:`one_task` keeps
the objects lazy and their values the same, but computes the whole subgraph behind them in a
single task with dask's synchronous scheduler: the graph travels to the worker (a file-backed
measurement as its file path, not its array), and only the small outputs come back.
"""

from __future__ import annotations

import operator

import xarray as xr

__all__ = ["one_task"]


class _Opaque:
    """Holds dask collections as plain data, so that ``dask.delayed`` does not make them dependencies."""

    __slots__ = ("items",)

    def __init__(self, items):
        self.items = items


def _compute_here(held: _Opaque) -> tuple:
    import dask

    from .batch._task import _tune_malloc

    _tune_malloc()  # in a distributed worker, FFT-sized temporaries were fresh mmaps: 1.4x the serial time
    return dask.compute(*held.items, scheduler="sync")


def _dask_parts(obj: xr.DataArray) -> list[tuple]:
    """(coordinate name or None for the data, array) of ``obj``'s dask-backed data and coordinates."""
    parts = [(None, obj.variable)] if obj.chunks is not None else []
    parts += [(name, c.variable) for name, c in obj.coords.items() if c.chunks is not None and name not in obj.dims]
    return parts


def one_task(*objs):
    """``objs`` (DataArrays or None) with all their dask data computed by one task.

    Data and non-index coordinates that are dask arrays are replaced by arrays taken from
    that task's output; numpy-backed objects (and None) come back unchanged.
    """
    parts = [_dask_parts(o) if isinstance(o, xr.DataArray) else [] for o in objs]
    arrays = [v.data for p in parts for _, v in p]
    if not arrays:  # in memory (also where the [dask] extra is not installed)
        return objs
    import dask  # deferred: the core install has no dask, and then no lazy data reach here
    import dask.array as da
    from dask.base import tokenize

    name = "xtopo-one-task-" + tokenize(*[a.name for a in arrays])
    task = dask.delayed(_compute_here, pure=True)(_Opaque(arrays), dask_key_name=name)
    it = iter(range(len(arrays)))
    out = []
    for obj, p in zip(objs, parts):
        for coord, var in p:
            i = next(it)
            a = arrays[i]
            piece = dask.delayed(operator.getitem, pure=True)(task, i, dask_key_name=f"{name}-{i}")
            new = var.copy(data=da.from_delayed(piece, a.shape, dtype=a.dtype, meta=a._meta, name=f"{name}-a{i}"))
            obj = obj.copy(data=new.data) if coord is None else obj.assign_coords({coord: new})
        out.append(obj)
    return tuple(out)
