"""What runs in a worker: one chunk of items, from reading its measurements to its file in the store.

A :class:`Chunk` is one Dask task's work (a block of measurements × a block of parameter
values); :func:`run_chunk` does it. The measurements are opened inside the worker (paths
travel, not arrays) and preprocessed there (the steps travel by name), ``func`` builds
whatever it needs there (a contact Scene and its FFT plans never cross a process
boundary), and the chunk's Dataset is written atomically into the store as soon as it is
done. An item that raises (an unreadable file, a failed preprocessing step or solve)
becomes an ``error`` entry; the chunk's other items go on.
"""

from __future__ import annotations

import os
import time
from typing import Callable, NamedTuple

import xarray as xr

from .._worker import tune_malloc
from ..errors import XtopoError
from ..io.open import open_topography
from ..preprocess import apply_steps
from ._results import chunk_dataset
from ._store import IO_LOCK, Store, func_name

__all__ = ["Chunk", "run_chunk", "run_chunks", "error_message"]


class Chunk(NamedTuple):
    """One task's work: measurements ``rows`` × parameter values ``cols`` of the batch, and where it goes."""

    func: Callable  #: ``func(ds)`` or ``func(ds, values)``; top-level (or a partial of one): it is pickled
    dim: str  #: name of the parameter dimension
    names: list  #: the measurements' names
    sources: list  #: the measurements: Datasets or file paths (read in the worker)
    params: list | None  #: the parameter values (None: a batch without parameters)
    key: str  #: the store key of the chunk's inputs (:func:`xtopo.batch._store.chunk_key`)
    store: str | None  #: the store directory (None: no store)
    fft_threads: int | None  #: FFT threads in a worker process (None: its setting)
    home_pid: int  #: the client's process id: elsewhere, the task runs in a dedicated worker process
    read_options: list  #: keywords of :func:`xtopo.open_topography` for each of the sources (file paths)
    preprocess: tuple  #: the steps applied to each measurement once read (:func:`xtopo.preprocess.checked_steps`)
    rows: tuple  #: (first, end) index of the measurements in the batch
    cols: tuple | None  #: (first, end) index of the parameter values in the batch


def error_message(exc: BaseException) -> str:
    """``"<ExceptionType>: <message>"``, as an item's ``error`` entry."""
    return f"{type(exc).__name__}: {exc}"


def _call(func, ds, params, dim, preprocessed: bool = False) -> xr.Dataset:
    """``func`` on one measurement (and the parameter values ``params``), its result checked and loaded.

    ``preprocessed``: ``ds`` was preprocessed; a result without a history of its own gets ``ds``'s, which
    records the preprocessing.
    """
    out = func(ds) if params is None else func(ds, list(params))
    if isinstance(out, xr.DataArray):
        out = out.to_dataset(name=out.name or "result")
    if not isinstance(out, xr.Dataset):
        raise XtopoError(f"batch function {func_name(func)} returned a {type(out).__name__}; "
                         "it must return an xarray Dataset or DataArray")
    out = out.compute()
    if preprocessed and "history" not in out.attrs and "history" in ds.attrs:
        out.attrs["history"] = ds.attrs["history"]
    if params is not None:
        if out.sizes.get(dim) != len(params):
            raise XtopoError(f"batch function {func_name(func)} must return a Dataset with dim {dim!r} of "
                             f"length {len(params)} (one entry per parameter value)")
        attrs = out[dim].attrs if dim in out.coords else {}
        out = out.assign_coords({dim: (dim, list(params), attrs)})
    return out


def _run_item(func, source, params, dim, read_options, steps=()):
    """(result or None, errors) of one measurement, read and preprocessed by ``steps``: errors is one message per
    parameter value ('' where it worked), or one message for a batch without parameters."""
    n = 1 if params is None else len(params)
    try:
        if not isinstance(source, xr.Dataset):
            with IO_LOCK:  # see xtopo.batch._store.IO_LOCK
                source = open_topography(source, **read_options)
        ds = apply_steps(source, steps)
    except Exception as exc:
        return None, [error_message(exc)] * n
    try:
        return _call(func, ds, params, dim, bool(steps)), [""] * n
    except Exception as exc:
        if params is None or n == 1:
            return None, [error_message(exc)]
    # isolate the failing parameter values; the others keep their results
    parts, errors = [], []
    for p in params:
        try:
            parts.append(_call(func, ds, [p], dim, bool(steps)))
            errors.append("")
        except Exception as exc:
            errors.append(error_message(exc))
    if not parts:
        return None, errors
    return xr.concat(parts, dim=dim, join="outer", combine_attrs="drop_conflicts", data_vars="minimal",
                     coords="minimal", compat="override"), errors


def run_chunk(chunk: Chunk) -> xr.Dataset:
    """Run one chunk (top-level, picklable): every measurement × every parameter value of it.

    In a worker process FFT threads are set to ``chunk.fft_threads`` (``XTOPO_FFT_THREADS``)
    and malloc is tuned (:func:`xtopo._worker.tune_malloc`); the result is written to the store (when
    there is one) before the task returns.

    Returns
    -------
    xarray.Dataset
        The chunk's results (see :mod:`xtopo.batch._results`).
    """
    if os.getpid() != chunk.home_pid:  # a dedicated worker process
        tune_malloc()
        if chunk.fft_threads:
            os.environ["XTOPO_FFT_THREADS"] = str(int(chunk.fft_threads))
    results, errors = zip(*(_run_item(chunk.func, source, chunk.params, chunk.dim, options, chunk.preprocess)
                            for source, options in zip(chunk.sources, chunk.read_options)))
    ds = chunk_dataset(chunk.names, chunk.sources, results, errors, chunk.params, chunk.dim)
    if chunk.store is not None:
        Store(chunk.store).write(ds, chunk.key, sum(bool(e) for row in errors for e in row))
    return ds


def run_chunks(chunks: list) -> list:
    """Several chunks in one task (small items need not each pay a task's overhead), one after the other.

    A chunk that raises does not stop the others (a task of one chunk raises, so that distributed's
    ``retries`` apply to it). A chunk whose file is already in the store
    (an earlier attempt of this task, on a worker that was then killed) is read back, not
    computed again.

    Returns
    -------
    list of tuple
        ``(key, Dataset or the exception, seconds)`` per chunk.
    """
    out = []
    for chunk in chunks:
        t = time.perf_counter()
        try:
            ds = None if chunk.store is None else Store(chunk.store).reusable(chunk.key)
            out.append((chunk.key, run_chunk(chunk) if ds is None else ds, time.perf_counter() - t))
        except Exception as exc:
            if len(chunks) == 1:
                raise
            out.append((chunk.key, exc, time.perf_counter() - t))
    return out
