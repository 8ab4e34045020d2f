"""The batch engine: plan the chunks, reuse those in the store, run the rest, assemble the result.

:func:`run` is the whole of it for any function; :func:`xtopo.batch.contact` and
:func:`xtopo.batch.analyze` are :func:`run` with a function of theirs. A store's
``manifest.json`` records what the batch is (its measurements, parameter values and
chunks), how its chunks are assembled into the result (the ``finish`` step, e.g. a contact
batch's :func:`~xtopo.batch._scans.settle_scans`) and which items of that result failed,
so that :func:`open_store` gives the result a run gave from the same chunk files.
"""

from __future__ import annotations

import json
import os
from typing import Annotated

import xarray as xr

from ..errors import XtopoError
from ..preprocess import checked_steps
from ._dispatch import execute, fft_env
from ..params import Path, checked
from ._inputs import Attrs, Progress, ReadOptions, Retries, StorePath, Workers, checked_read_options, chunk_sizes, \
    names_and_sources, run_options
from ._results import combine, failed_items, failure_block
from ._scans import settle_scans
from ._store import MANIFEST, Store, chunk_key, fingerprint, func_name
from ._task import Chunk, error_message

__all__ = ["run", "run_batch", "open_store"]

#: the steps that may finish the assembly of a batch's result, by the name the manifest records
_FINISH = {"settle_scans": settle_scans}


@checked
def run(func, measurements, params=None, *, dim: str = "load", dim_attrs: Attrs = None, chunks=None,
        client=None, scheduler: str | None = None, workers: Workers = None, store: StorePath = None,
        progress: Progress = True,
        fft_threads: Workers = 1, retries: Retries = 1, read_options: ReadOptions = None,
        preprocess=None) -> xr.Dataset:
    """Run ``func`` on every measurement (× every parameter value) as chunked Dask tasks.

    The work is a grid of *items* (one measurement × one parameter value, e.g. a load) cut
    into *chunks* (blocks of measurements × parameter values), one Dask task each. A chunk
    whose file is in the store under the same key (inputs, parameters, function, xtopo
    version) and without failed items is not computed again, so an interrupted run resumes
    where it stopped.

    Parameters
    ----------
    func : callable
        A picklable top-level function (or ``functools.partial`` of one):
        ``func(ds)`` → Dataset when ``params`` is None, else ``func(ds, values)`` → Dataset
        with a ``dim`` dimension of ``len(values)``. It runs inside the worker; build
        expensive objects (FFT plans, contact scenes) there.
    measurements : mapping, DataTree, or sequence of Dataset / path
        Paths are opened in the worker with :func:`xtopo.open_topography`. Names (the
        ``measurement`` coordinate) are the mapping keys / child names, file basenames or
        a Dataset's ``title``/``source_file``.
    params : sequence, optional
        Parameter values along ``dim`` (loads, penetrations, ...), in the units ``func``
        takes them in.
    dim : str
        Name of the parameter dimension.
    dim_attrs : dict, optional
        Attributes (``units``, ``long_name``) of the ``dim`` coordinate if ``func`` gives none.
    chunks : int or dict, optional
        Items per task: an int is measurements per chunk; a dict names both,
        e.g. ``{"measurement": 1, "load": 4}`` (``-1``/None: all). Default: one measurement
        with all parameter values per task. A chunk is what the store keeps and reuses; on a
        distributed client, chunks that take less than about 0.25 s each (timed on the first
        ones) are packed several to a task (``XTOPO_BATCH_TASK_SECONDS`` sets the target, 0
        turns packing off).
    client : distributed.Client, optional
        Run on this client. Default: the active client, if any.
    scheduler : str, optional
        Without a client: ``"threads"`` (default), ``"processes"``, ``"sync"``, ``"local"``
        (a LocalCluster of ``workers`` one-thread processes) or a scheduler address
        ``"tcp://host:port"``.
    workers : int, optional
        Number of local workers (threads, processes or LocalCluster workers).
    store : str or os.PathLike, optional
        Directory that receives one NetCDF file per completed chunk (workers must be
        able to write there: a local or shared file system) and ``manifest.json``.
        Rerunning with the same store skips chunks already done.
    progress : bool
        Show a progress bar (dask's for local schedulers, distributed's for a client).
    fft_threads : int or None
        FFT threads per task (``XTOPO_FFT_THREADS`` in the worker); default 1, since the
        batch is parallel over tasks. None leaves the worker's setting alone.
    retries : int
        Automatic retries of a task that raised (distributed only; a task whose worker
        died is always rescheduled by the scheduler).
    read_options : dict, optional
        Keywords of :func:`xtopo.open_topography` for the file paths, e.g.
        ``{"file_units": "um", "physical_size": (Ly, Lx)}`` for files that store no size or
        unit (plain text, npy, MATLAB, HDF5). ``tip_radius``/``resolution`` (the reliability
        cutoff, paper §4.9, of files that store none; in the result's units) may be lists with
        one value per measurement. They are part of a chunk's store key.
    preprocess : str, dict or sequence, optional
        Preprocessing applied in the worker to each measurement (file or Dataset) before
        ``func`` sees it, by step name and options, in the order given:
        ``{"detrend": "plane", "fill_missing": True}``, ``[("detrend", {"mode": "curvature"}),
        "fill_missing"]`` (see :func:`xtopo.preprocess.checked_steps`; the same as
        :func:`xtopo.preprocess.apply_steps` does in-process). Checked before any task is
        built; part of a chunk's store key (a rerun with other steps recomputes). Each step is
        recorded in the history of the item's result (a result without a history of its own
        gets the preprocessed measurement's).

    Returns
    -------
    xarray.Dataset
        Results with dims (``measurement``, ``dim``, ...), a ``source`` coordinate, a
        ``history`` coordinate when the results carry a history, and a string variable
        ``error`` ('' where the item succeeded). Errors of single items (an unreadable
        file, a solve that fails) are caught in the task; the other items go on. Failed
        items hold NaN ('' in string variables): where some item failed, an integer or
        boolean variable is a float one (1.0/0.0 for True/False). Attrs: ``n_failed``,
        ``failed_items`` (JSON list), ``chunks_computed``, ``chunks_reused`` and ``store``.
    """
    return run_batch(func, measurements, params, dim=dim, dim_attrs=dim_attrs, chunks=chunks, client=client,
                     scheduler=scheduler, workers=workers, store=store, progress=progress, fft_threads=fft_threads,
                     retries=retries, read_options=read_options, preprocess=preprocess)


def _plan(func, dim, names, sources, params, chunks, read_options, steps, store,
          fft_threads) -> list[list[Chunk]]:
    """The batch's chunks: rows of measurement blocks, each a list of parameter-value blocks."""
    mchunk, pchunk = chunk_sizes(chunks, dim, len(names), 1 if params is None else len(params))
    # a file read with other options is another measurement: the options enter its fingerprint
    opts = [json.dumps(o, sort_keys=True, default=repr) if o else "" for o in read_options]
    prints = [fingerprint(s) + (f"|read:{o}" if o and not isinstance(s, xr.Dataset) else "")
              for s, o in zip(sources, opts)]
    home = os.getpid()
    grid = []
    for i in range(0, len(names), mchunk):
        m = slice(i, min(i + mchunk, len(names)))
        row = []
        for j in range(0, 1 if params is None else len(params), pchunk):
            p = None if params is None else params[j:j + pchunk]
            row.append(Chunk(func=func, dim=dim, names=names[m], sources=sources[m], params=p,
                             key=chunk_key(func, dim, names[m], prints[m], p, steps),
                             store=None if store is None else store.directory, fft_threads=fft_threads,
                             home_pid=home, read_options=read_options[m], preprocess=steps, rows=(m.start, m.stop),
                             cols=None if p is None else (j, j + len(p))))
        grid.append(row)
    return grid


def _assemble(blocks, dim, has_params, dim_attrs, finish, where: str = "a batch") -> xr.Dataset:
    """The chunks' Datasets combined into the batch's result, then ``finish`` (as the manifest records it);
    ``where`` names the batch in an error."""
    ds = combine(blocks, dim, has_params, dim_attrs)
    if finish is None:
        return ds
    step = _FINISH.get(finish.get("name")) if isinstance(finish, dict) else None
    if step is None:
        raise XtopoError(f"{where}: unknown finishing step {finish!r} of the batch result (known: "
                         f"{', '.join(_FINISH)}); was the store written by another xtopo version?")
    return step(ds, **finish.get("kwargs", {}))


def run_batch(func, measurements, params, *, dim, dim_attrs, chunks, client, scheduler, workers, store, progress,
              fft_threads, retries, read_options, preprocess, finish: dict | None = None) -> xr.Dataset:
    """:func:`run` with a last step of the assembly.

    Parameters
    ----------
    finish : dict, optional
        ``{"name": <a key of _FINISH>, "kwargs": {...}}`` (JSON-serialisable): a step applied to
        the assembled result and recorded in the store's manifest, so that a rerun and
        :func:`open_store` apply it too.

    Other parameters and the result are those of :func:`run`.
    """
    names, sources = names_and_sources(measurements)
    params = run_options(func, dim, params)
    read_options = checked_read_options(read_options, len(names))
    steps = checked_steps(preprocess)
    store_obj = Store(store) if store is not None else None
    grid = _plan(func, dim, names, sources, params, chunks, read_options, steps, store_obj, fft_threads)

    stored = {}
    if store_obj is not None:
        stored = {c.key: ds for row in grid for c in row if (ds := store_obj.reusable(c.key)) is not None}
    todo = [c for row in grid for c in row if c.key not in stored]
    manifest = {"function": func_name(func), "dim": dim, "dim_attrs": dim_attrs, "measurements": names,
                "params": params, "preprocess": [list(step) for step in steps],
                "sources": [s if isinstance(s, str) else "" for s in sources],
                "chunks": [[{"key": c.key, "m": list(c.rows), "p": None if c.cols is None else list(c.cols)}
                            for c in row] for row in grid],
                "finish": finish, "status": "running"}
    if store_obj is not None:
        store_obj.write_manifest(manifest)

    with fft_env(fft_threads):
        outcomes = execute(todo, client=client, scheduler=scheduler, workers=workers, progress=progress,
                           retries=retries)

    def block(c):
        out = stored.get(c.key, outcomes.get(c.key))
        return out if isinstance(out, xr.Dataset) else failure_block(
            c.names, c.sources, c.params, dim, f"chunk failed: {error_message(out or XtopoError('no result'))}")

    ds = _assemble([[block(c) for c in row] for row in grid], dim, params is not None, dim_attrs, finish)
    failed = failed_items(ds, dim)
    ds.attrs.update({"title": f"xtopo batch: {func_name(func)}", "n_failed": len(failed),
                     "failed_items": json.dumps(failed), "chunks_computed": len(todo), "chunks_reused": len(stored),
                     "store": "" if store_obj is None else store_obj.directory})
    if store_obj is not None:
        store_obj.write_manifest({**manifest, "status": "partial" if failed else "complete", "failed": failed})
    return ds


@checked
def open_store(directory: Annotated[str, Path("directory path")]) -> xr.Dataset:
    """The results of a (possibly unfinished) batch from its store, without computing anything.

    Parameters
    ----------
    directory : str or os.PathLike
        The ``store`` of a :func:`run` (or :func:`~xtopo.batch.contact`, :func:`~xtopo.batch.analyze`).

    Returns
    -------
    xarray.Dataset
        The result the run gave (without its run attributes: ``n_failed``, ``chunks_computed``,
        ...). Chunks not (yet) in the store show up with error ``'not computed'`` and NaN results.
    """
    where = os.path.abspath(directory)
    if not os.path.isdir(where):
        raise XtopoError(f"no batch store at {where}: not a directory (a batch run's store= creates it)")
    store = Store(where)
    where = f"batch store {store.directory} ({MANIFEST})"
    try:
        with open(os.path.join(store.directory, MANIFEST)) as f:
            manifest = json.load(f)
    except (OSError, ValueError) as exc:
        raise XtopoError(f"{directory} is not a readable xtopo batch store ({MANIFEST}: {exc})") from None
    try:
        dim, params, names, sources = (manifest["dim"], manifest["params"], manifest["measurements"],
                                       manifest["sources"])
        blocks = [[_stored_block(store, c, names, sources, params, dim) for c in row] for row in manifest["chunks"]]
    except (KeyError, TypeError, ValueError, IndexError) as exc:
        raise XtopoError(f"{where} is damaged or not a batch manifest ({type(exc).__name__}: {exc})") from None
    return _assemble(blocks, dim, params is not None, manifest.get("dim_attrs"), manifest.get("finish"), where=where)


def _stored_block(store, chunk: dict, names, sources, params, dim) -> xr.Dataset:
    """One chunk of a store's manifest: its file, or a 'not computed' block where it is missing or unreadable."""
    try:
        return store.read(chunk["key"])
    except Exception:
        (i0, i1), p = chunk["m"], chunk["p"]
        return failure_block(names[i0:i1], sources[i0:i1], None if p is None else params[p[0]:p[1]], dim,
                             "not computed")
