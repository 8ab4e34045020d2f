"""Batch runs on Dask: many measurements × many parameters, chunked, resumable, fault tolerant.

The work is a grid of *items* (one measurement × one parameter value, e.g. a load)
cut into *chunks* (blocks of measurements × parameter values). Each chunk is one
Dask task that runs :func:`_run_chunk`, a plain top-level function: it opens the
measurement inside the worker (paths travel, not arrays), builds whatever the work
needs there (a contact Scene and its FFT plans never cross a process boundary),
and writes its result atomically into the store as soon as it is done. A chunk
whose file is in the store under the same key (inputs, parameters, function,
xtopo version) and without failed items is not computed again, so an interrupted
run resumes where it stopped.

Where the tasks run:

* on the ``client=`` given, else on the active :class:`distributed.Client`;
* ``scheduler="tcp://host:port"``: a client to that scheduler (closed afterwards);
* ``scheduler="local"``: a :class:`distributed.LocalCluster` of ``workers`` processes
  with one thread each (fault tolerant: a worker that dies is replaced and its
  tasks rerun);
* otherwise dask's local ``"threads"`` (default), ``"processes"`` or ``"sync"`` scheduler.

Errors of single items (an unreadable file, a solve that fails) are caught in the
task and reported in the result's ``error`` variable; the other items go on.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import inspect
import json
import os
import pkgutil
import re
import uuid

import numpy as np
import xarray as xr

from ._batch_store import IO_LOCK, MANIFEST, Store, chunk_key, fingerprint, func_name
from ._checks import flag, integer
from .conventions import length_units_of, append_history, convert_length, normalize_units
from .errors import UnitsError, XtopoError

__all__ = ["run", "contact", "analyze", "open_store"]

MEASUREMENT = "measurement"
ERROR = "error"
HISTORY = "history"
_ADDRESS_PREFIXES = ("tcp://", "tls://", "inproc://", "ucx://", "ws://", "wss://")
_LOCAL_SCHEDULERS = ("threads", "processes", "sync", "synchronous", "single-threaded")


# --------------------------------------------------------------------------- inputs


def _names_and_sources(measurements):
    """Names and sources (Dataset or path) of the measurements, in order."""
    if isinstance(measurements, xr.DataTree):
        items = [(name, node.to_dataset()) for name, node in measurements.children.items()]
    elif isinstance(measurements, dict):
        items = list(measurements.items())
    elif isinstance(measurements, (str, os.PathLike, xr.Dataset)):
        items = [(None, measurements)]
    else:
        items = [(None, m) for m in measurements]
    if not items:
        raise XtopoError("a batch needs at least one measurement (a Dataset or a file path)")
    names, sources, seen = [], [], set()
    for i, (name, src) in enumerate(items):
        if isinstance(src, (str, os.PathLike)):
            src = os.fspath(src)
            name = name if name is not None else os.path.basename(src)
        elif isinstance(src, xr.Dataset):
            name = name if name is not None else str(src.attrs.get("title") or src.attrs.get("source_file")
                                                     or f"measurement_{i}")
        else:
            raise XtopoError(f"measurement {i} is a {type(src).__name__}; give an xarray Dataset or a file path")
        name, base, k = str(name), str(name), 1
        while name in seen:
            k += 1
            name = f"{base}-{k}"
        seen.add(name)
        names.append(name)
        sources.append(src)
    return names, sources


def _chunk_sizes(chunks, dim, n_meas, n_par):
    if chunks is None:
        chunks = {}
    elif isinstance(chunks, (int, np.integer)) and not isinstance(chunks, (bool, np.bool_)):
        chunks = {MEASUREMENT: integer(chunks, "chunks")}
    elif not isinstance(chunks, dict):
        raise XtopoError(f"chunks must be an int (measurements per chunk) or a dict like "
                         f"{{'{MEASUREMENT}': 1, '{dim}': 4}}, got {chunks!r}")
    unknown = set(chunks) - {MEASUREMENT, dim}
    if unknown:
        raise XtopoError(f"chunks names unknown dims {sorted(unknown)}; use {MEASUREMENT!r} and {dim!r}")
    sizes = []
    for d, n, default in ((MEASUREMENT, n_meas, 1), (dim, n_par, None)):
        c = chunks.get(d, default)
        everything = c is None or (isinstance(c, (int, np.integer)) and c == -1)   # True == -1 is False
        sizes.append(n if everything else integer(c, f"chunk size along {d!r} (or -1/None for all)"))
    return sizes


def _options(dim, workers, fft_threads, retries, progress, params):
    """The run options checked on the client, before any task is built; returns ``params`` as a list."""
    if not isinstance(dim, str) or not dim or dim in (MEASUREMENT, ERROR, HISTORY, "source"):
        raise XtopoError(f"dim must be a name (str) other than {MEASUREMENT!r}, {ERROR!r}, {HISTORY!r} and 'source', "
                         f"got {dim!r}")
    if workers is not None:
        integer(workers, "workers")
    if fft_threads is not None:
        integer(fft_threads, "fft_threads")
    integer(retries, "retries", minimum=0)
    flag(progress, "progress")
    if params is None:
        return None
    try:
        values = np.atleast_1d(np.asarray(params))
    except (TypeError, ValueError):  # ragged: [[1, 2], [3]]
        raise XtopoError(f"{dim} values must be a number or a 1D sequence, got {params!r}") from None
    if values.ndim != 1:
        raise XtopoError(f"{dim} values must be a number or a 1D sequence, got shape {values.shape}")
    if not values.size:
        raise XtopoError(f"no {dim} values given; give at least one")
    return values.tolist()


# --------------------------------------------------------------------------- the task


def _message(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}"


def _load(source, read_options=None) -> xr.Dataset:
    if isinstance(source, xr.Dataset):
        return source
    from .io.open import open_topography

    with IO_LOCK:  # see xtopo._batch_store.IO_LOCK
        return open_topography(source, **(read_options or {}))


def _read_options(read_options) -> dict:
    """``read_options`` checked against :func:`xtopo.open_topography`'s keywords (before any task runs)."""
    if read_options is not None and not isinstance(read_options, dict):
        raise XtopoError(f"read_options must be a dict of xtopo.open_topography keywords, got "
                         f"{type(read_options).__name__}")
    if not read_options:
        return {}
    from .io.open import open_topography

    allowed = [k for k, v in inspect.signature(open_topography).parameters.items() if v.kind is v.KEYWORD_ONLY]
    unknown = sorted(set(read_options) - set(allowed))
    if unknown:
        raise XtopoError(f"read_options {unknown} are not options of xtopo.open_topography ({', '.join(allowed)})")
    return dict(read_options)


def _call(func, ds, params, dim):
    out = func(ds) if params is None else func(ds, list(params))
    if isinstance(out, xr.DataArray):
        out = out.to_dataset(name=out.name or "result")
    if not isinstance(out, xr.Dataset):
        raise XtopoError(f"batch function {func_name(func)} returned a {type(out).__name__}; "
                         "it must return an xarray Dataset or DataArray")
    out = out.compute()
    if params is not None:
        if out.sizes.get(dim) != len(params):
            raise XtopoError(f"batch function {func_name(func)} must return a Dataset with dim {dim!r} of "
                             f"length {len(params)} (one entry per parameter value)")
        attrs = out[dim].attrs if dim in out.coords else {}
        out = out.assign_coords({dim: (dim, list(params), attrs)})
    return out


def _run_item(func, source, params, dim, read_options=None):
    """(result or None, errors): errors is one message, or one per parameter value ('' where it worked)."""
    n = 1 if params is None else len(params)
    try:
        ds = _load(source, read_options)
    except Exception as exc:
        return None, [_message(exc)] * n
    try:
        return _call(func, ds, params, dim), [""] * n
    except Exception as exc:
        if params is None or n == 1:
            return None, [_message(exc)]
    # isolate the failing parameter values; the others keep their results
    parts, errors = [], []
    for p in params:
        try:
            parts.append(_call(func, ds, [p], dim))
            errors.append("")
        except Exception as exc:
            errors.append(_message(exc))
    if not parts:
        return None, errors
    return xr.concat(parts, dim=dim, join="outer", combine_attrs="drop_conflicts", data_vars="minimal",
                     coords="minimal", compat="override"), errors


def _chunk_dataset(names, sources, results, errors, params, dim):
    """One chunk's Dataset: results stacked along ``measurement`` (and ``dim``), plus ``error``."""
    coords = {MEASUREMENT: (MEASUREMENT, list(names), {"long_name": "measurement"}),
              "source": (MEASUREMENT, [s if isinstance(s, str) else "" for s in sources],
                         {"long_name": "file the measurement was read from ('' for in-memory data)"})}
    # each measurement's own history (its input's, plus what the function did) would conflict with the
    # others' and be dropped as a Dataset attribute: it is kept per measurement, as a coordinate
    history = [r.attrs.get("history", "") if r is not None else "" for r in results]
    if any(history):
        coords[HISTORY] = (MEASUREMENT, history, {"long_name": "processing history of each measurement's result "
                                                                "('' for a failed one)"})
    good = [r.drop_attrs(deep=False).assign_attrs({k: v for k, v in r.attrs.items() if k != "history"})
            .expand_dims({MEASUREMENT: [n]}) for n, r in zip(names, results) if r is not None]
    if good:
        ds = xr.concat(good, dim=MEASUREMENT, join="outer", combine_attrs="drop_conflicts", data_vars="all")
        ds = ds.reindex({MEASUREMENT: list(names)})
    else:
        ds = xr.Dataset()
    err_dims = (MEASUREMENT,) if params is None else (MEASUREMENT, dim)
    if params is not None:
        attrs = ds[dim].attrs if dim in ds.coords else {}
        ds = ds.reindex({dim: list(params)}) if dim in ds.dims else ds
        coords[dim] = (dim, list(params), attrs)
    err = np.array(errors, dtype=object).reshape([len(names)] + ([] if params is None else [len(params)]))
    ds = ds.assign_coords(coords)
    ds[ERROR] = (err_dims, err, {"long_name": "error message of the failed item ('' where it succeeded)"})
    # attributes as the store holds them (bool → int, dict → JSON): a chunk computed now equals one reused
    from .io.netcdf import prepare_for_netcdf

    return prepare_for_netcdf(ds, provenance=False)


_MALLOC_TUNED = False


def _tune_malloc() -> None:
    """Undo the cost of distributed's ``MALLOC_TRIM_THRESHOLD_`` in a worker process (glibc only, once).

    Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``; glibc then also
    freezes the mmap threshold at 128 KiB, so every FFT-sized temporary is a fresh
    ``mmap`` + page faults: FFT-bound work ran 2-4× slower in a worker than in a plain
    process on the reference machine. Raising both thresholds (64 MiB mmap, 128 MiB trim)
    restores plain-process speed. Set ``XTOPO_BATCH_MALLOC_TUNE=0`` to leave malloc alone.
    """
    global _MALLOC_TUNED
    if _MALLOC_TUNED or os.environ.get("XTOPO_BATCH_MALLOC_TUNE", "1") == "0":
        return
    _MALLOC_TUNED = True
    if "MALLOC_TRIM_THRESHOLD_" not in os.environ:
        return
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-3, 64 << 20)  # M_MMAP_THRESHOLD
        libc.mallopt(-1, 128 << 20)  # M_TRIM_THRESHOLD
    except (OSError, AttributeError):  # not glibc: nothing to undo
        pass


def _run_chunk(func, dim, names, sources, params, store, ckey, fft_threads, home_pid, read_options=None):
    """Run one chunk (top-level, picklable): every measurement × every parameter value of it.

    In a worker process FFT threads are set to ``fft_threads`` (``XTOPO_FFT_THREADS``) and
    malloc is tuned (:func:`_tune_malloc`); the result is written to the store (when given) before the task returns.

    Returns
    -------
    xarray.Dataset
        The chunk's results (also in the store, when one is given).
    """
    if os.getpid() != home_pid:  # a dedicated worker process
        _tune_malloc()
        if fft_threads:
            os.environ["XTOPO_FFT_THREADS"] = str(int(fft_threads))
    results, errors = [], []
    for source in sources:
        res, err = _run_item(func, source, params, dim, read_options)
        results.append(res)
        errors.append(err)
    ds = _chunk_dataset(names, sources, results, errors, params, dim)
    failed = int(sum(bool(e) for row in errors for e in row))
    if store is not None:
        Store(store).write(ds, ckey, failed)
    return ds


# --------------------------------------------------------------------------- execution


@contextlib.contextmanager
def _fft_env(threads):
    """Set ``XTOPO_FFT_THREADS`` in this process for tasks that run in it (threads scheduler)."""
    old = os.environ.get("XTOPO_FFT_THREADS")
    if threads:
        os.environ["XTOPO_FFT_THREADS"] = str(int(threads))
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("XTOPO_FFT_THREADS", None)
        else:
            os.environ["XTOPO_FFT_THREADS"] = old


def _active_client():
    try:
        from distributed import get_client
    except ImportError:  # pragma: no cover - distributed is a dependency
        return None
    try:
        return get_client()
    except ValueError:
        return None


@contextlib.contextmanager
def _client_for(client, scheduler, workers):
    """The distributed client to use (None: a local dask scheduler), closing any we open."""
    if client is not None:
        yield client
        return
    if scheduler is None:
        yield _active_client()
        return
    if not isinstance(scheduler, str):
        raise XtopoError(f"scheduler must be a string, got {type(scheduler).__name__}; pass a "
                         "distributed.Client as client= instead")
    if scheduler in _LOCAL_SCHEDULERS:
        yield None
        return
    from distributed import Client, LocalCluster

    if scheduler == "local":
        n = int(workers) if workers else (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                                          else os.cpu_count() or 1)
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
                Client(cluster) as c:
            yield c
        return
    if not scheduler.startswith(_ADDRESS_PREFIXES):
        raise XtopoError(f"unknown scheduler {scheduler!r}; use 'threads', 'processes', 'sync', 'local' "
                         "or a scheduler address like 'tcp://host:8786'")
    try:
        c = Client(scheduler)  # connect timeout: dask config distributed.comm.timeouts.connect
    except (OSError, TimeoutError) as exc:
        raise XtopoError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}. Is `dask scheduler` "
                         "running there, and are workers attached (`dask worker {scheduler}`)?") from None
    try:
        yield c
    finally:
        c.close()


_CHUNK_ARGS = ("func", "dim", "names", "sources", "params", "store", "ckey", "fft_threads", "home_pid",
               "read_options")


def _args(spec) -> tuple:
    """Positional arguments of :func:`_run_chunk` (``Client.submit`` reserves ``func``, ``key``)."""
    return tuple(spec[k] for k in _CHUNK_ARGS)


def _execute_distributed(client, specs, progress, retries):
    from distributed import as_completed

    token = uuid.uuid4().hex[:8]
    futures = {client.submit(_run_chunk, *_args(spec), key=f"xtopo-batch-{spec['ckey'][:16]}-{token}", pure=False,
                             retries=retries): spec["ckey"] for spec in specs}
    if progress and futures:
        from distributed import progress as _progress

        _progress(list(futures))
    out = {}
    for fut in as_completed(list(futures)):
        key = futures[fut]
        if fut.status == "error":
            exc = fut.exception()
            out[key] = exc if isinstance(exc, BaseException) else XtopoError(str(exc))
        elif fut.status == "cancelled":
            out[key] = XtopoError("task was cancelled (the scheduler lost it)")
        else:
            out[key] = fut.result()
        fut.release()
    return out


def _execute_local(specs, scheduler, workers, progress):
    import dask

    if not specs:
        return {}
    tasks = [dask.delayed(_run_chunk, pure=False)(**spec) for spec in specs]
    bar = contextlib.nullcontext()
    if progress:
        from dask.diagnostics import ProgressBar

        bar = ProgressBar()
    with bar:
        results = dask.compute(*tasks, scheduler=scheduler or "threads", num_workers=workers)
    return {spec["ckey"]: r for spec, r in zip(specs, results)}


# --------------------------------------------------------------------------- assembly


def _failure_block(spec, msg: str):
    n = 1 if spec["params"] is None else len(spec["params"])
    return _chunk_dataset(spec["names"], spec["sources"], [None] * len(spec["names"]),
                          [[msg] * n for _ in spec["names"]], spec["params"], spec["dim"])


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


def _combine(blocks, dim, has_params, dim_attrs):
    blocks = _same_histories(blocks)
    if has_params:
        ds = xr.combine_nested(blocks, concat_dim=[MEASUREMENT, dim], join="outer", combine_attrs="drop_conflicts",
                               data_vars="all", coords="minimal", compat="override")
        if dim_attrs and not ds[dim].attrs:
            ds[dim].attrs = dict(dim_attrs)
    else:
        ds = xr.combine_nested([row[0] for row in blocks], concat_dim=MEASUREMENT, join="outer",
                               combine_attrs="drop_conflicts", data_vars="all", coords="minimal", compat="override")
    ds[ERROR] = ds[ERROR].fillna("").astype(object)
    ds[ERROR].attrs = {"long_name": "error message of the failed item ('' where it succeeded)"}
    return ds


def _failed_items(ds, dim):
    err = ds[ERROR]
    out = []
    if err.ndim == 1:
        for m, e in zip(err[MEASUREMENT].values, err.values):
            if e:
                out.append(f"{m}: {e}")
    else:
        for i, m in enumerate(err[MEASUREMENT].values):
            for j, p in enumerate(err[dim].values):
                if err.values[i, j]:
                    out.append(f"{m} [{dim}={p}]: {err.values[i, j]}")
    return out


def run(func, measurements, params=None, *, dim: str = "load", dim_attrs: dict | None = None, chunks=None,
        client=None, scheduler: str | None = None, workers: int | None = None, store=None, progress: bool = True,
        fft_threads: int | None = 1, retries: int = 1, read_options: dict | None = None) -> xr.Dataset:
    """Run ``func`` on every measurement (× every parameter value) as chunked Dask tasks.

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
        Parameter values along ``dim`` (loads, penetrations, ...).
    dim : str
        Name of the parameter dimension.
    dim_attrs : dict, optional
        Attributes (``units``, ``long_name``) of the ``dim`` coordinate if ``func`` gives none.
    chunks : int or dict, optional
        Items per task: an int is measurements per chunk; a dict names both,
        e.g. ``{"measurement": 1, "load": 4}`` (``-1``/None: all). Default: one measurement
        with all parameter values per task.
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
        able to write there: a local or shared file system). Rerunning with the same
        store skips chunks already done.
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
        unit (plain text, npy, MATLAB, HDF5). They are part of a chunk's store key.

    Returns
    -------
    xarray.Dataset
        Results with dims (``measurement``, ``dim``, ...), a ``source`` coordinate and a
        string variable ``error`` ('' where the item succeeded). Failed items hold NaN.
        Attrs: ``n_failed``, ``failed_items`` (JSON list), ``chunks_computed``,
        ``chunks_reused`` and ``store``.
    """
    names, sources = _names_and_sources(measurements)
    params = _options(dim, workers, fft_threads, retries, progress, params)
    mchunk, pchunk = _chunk_sizes(chunks, dim, len(names), 1 if params is None else len(params))
    read_options = _read_options(read_options)
    # a file read with other options is another measurement: the options enter its fingerprint
    opts = json.dumps(read_options, sort_keys=True, default=repr) if read_options else ""
    prints = [fingerprint(s) + (f"|read:{opts}" if opts and not isinstance(s, xr.Dataset) else "") for s in sources]
    store_obj = Store(store) if store is not None else None
    home = os.getpid()

    layout, specs, stored, spec_slices = [], [], {}, {}
    for i in range(0, len(names), mchunk):
        row = []
        for j in range(0, 1 if params is None else len(params), pchunk):
            p = None if params is None else params[j:j + pchunk]
            key = chunk_key(func, dim, names[i:i + mchunk], prints[i:i + mchunk], p)
            spec = dict(func=func, dim=dim, names=names[i:i + mchunk], sources=sources[i:i + mchunk], params=p,
                        store=None if store_obj is None else store_obj.directory, ckey=key,
                        fft_threads=fft_threads, home_pid=home, read_options=read_options)
            spec_slices[key] = {"key": key, "m": [i, min(i + mchunk, len(names))],
                                "p": None if p is None else [j, j + len(p)]}
            row.append(spec)
            done = None if store_obj is None else store_obj.reusable(key)
            if done is not None:
                stored[key] = done
            else:
                specs.append(spec)
        layout.append(row)
    manifest = {"function": func_name(func), "dim": dim, "measurements": names, "params": params,
                "sources": [s if isinstance(s, str) else "" for s in sources],
                "chunks": [[spec_slices[s["ckey"]] for s in row] for row in layout], "status": "running"}
    if store_obj is not None:
        store_obj.write_manifest(manifest)

    with _fft_env(fft_threads), _client_for(client, scheduler, workers) as c:
        if c is not None:
            outcomes = _execute_distributed(c, specs, progress, retries)
        else:
            outcomes = _execute_local(specs, scheduler, workers, progress)

    blocks = []
    for row in layout:
        brow = []
        for spec in row:
            out = stored.get(spec["ckey"], outcomes.get(spec["ckey"]))
            if isinstance(out, xr.Dataset):
                block = out
            else:
                block = _failure_block(spec, f"chunk failed: {_message(out or XtopoError('no result'))}")
            brow.append(block)
        blocks.append(brow)
    ds = _combine(blocks, dim, params is not None, dim_attrs)
    failed = _failed_items(ds, dim)
    ds.attrs.update({"title": f"xtopo batch: {func_name(func)}", "n_failed": len(failed),
                     "failed_items": json.dumps(failed), "chunks_computed": len(specs), "chunks_reused": len(stored),
                     "store": "" if store_obj is None else store_obj.directory})
    if store_obj is not None:
        store_obj.write_manifest({**manifest, "status": "partial" if failed else "complete", "failed": failed})
    return ds


def open_store(directory) -> xr.Dataset:
    """The results of a (possibly unfinished) batch from its store, without computing anything.

    Chunks not (yet) in the store show up with error ``'not computed'`` and NaN results.
    """
    store = Store(directory)
    try:
        with open(os.path.join(store.directory, MANIFEST)) as f:
            manifest = json.load(f)
    except (OSError, ValueError) as exc:
        raise XtopoError(f"{directory} is not a readable xtopo batch store ({MANIFEST}: {exc})") from None
    dim, params, names, sources = manifest["dim"], manifest["params"], manifest["measurements"], manifest["sources"]
    blocks = []
    for row in manifest["chunks"]:
        brow = []
        for c in row:
            try:
                block = store.read(c["key"])
            except Exception:
                (i0, i1), p = c["m"], c["p"]
                spec = dict(names=names[i0:i1], sources=sources[i0:i1], dim=dim,
                            params=None if p is None else params[p[0]:p[1]])
                block = _failure_block(spec, "not computed")
            brow.append(block)
        blocks.append(brow)
    return _combine(blocks, dim, params is not None, None)


# --------------------------------------------------------------------------- contact


def _contact_item(ds, values, *, control, scene, solve, maps, units=None, scan=None):
    """Contact solutions of one measurement for each value of ``control`` (runs in the worker).

    ``units``: the length unit the measurement is converted to before solving (None: as it is;
    ``"1"``: a batch of unitless data, which a measurement with a length unit cannot join).
    ``scan``: ``"line"`` or ``"area"``, the only kind of scan the batch's loads mean something for
    (None: any); a measurement of the other kind fails.
    """
    from .contact import Scene

    if units == "1":
        try:
            found = length_units_of(ds)
        except UnitsError:
            found = None
        if found is not None:
            raise UnitsError(f"this measurement is in {found!r}, but the batch is solved without a length unit (its "
                             "first measurement has none); give batch.contact(units=...) and units to every one")
    elif units is not None:
        ds = convert_length(ds, units)
    sc = Scene(ds, **scene)
    kind = "line" if sc.line else "area"
    if scan is not None and kind != scan:
        raise XtopoError(_mixed_scans_message(control, f"this measurement is {_a(kind)}, but the loads of this batch "
                                                       f"are for {scan} scans (its other measurements)", units))
    out = []
    for v in values:
        r = sc.solve(**{control: v}, **solve)
        if not maps:
            r = r.drop_vars([n for n, var in r.variables.items() if {"x", "y"} & set(var.dims)])
        attrs = dict(r[control].attrs) if control in r.variables else {}
        r = r.drop_vars(control, errors="ignore").expand_dims({control: [v]})
        r[control].attrs = attrs
        out.append(r)
    out = xr.concat(out, dim=control, combine_attrs="drop_conflicts", data_vars="all")
    # the solves' own history lines differ by load (and were dropped): the input's history plus one line for all
    out.attrs["history"] = ds.attrs.get("history", "")
    out = append_history(out, _contact_line(sc, control, out[control].attrs.get("units", "?"), scene, solve))
    return _snap_grid(out) if maps else out


def _contact_line(sc, control, units, scene, solve) -> str:
    """The history line of a contact computation: what was modelled and how it was solved."""
    boundary = ("periodic" if sc.periodic else "free") + (" (as requested)" if "periodic" in scene else " (from the data)")
    counter = "compound topography h1 + h2" if scene.get("counter") is not None else "no counter surface (rigid rough surface)"
    settings = ", ".join(f"{k}={v:g}" for k, v in solve.items()) or "default tol and maxiter"
    scan = "a line scan (plane strain)" if sc.line else "an area scan"
    return (f"xtopo contact of {scan} at each {control} of the {control!r} coordinate ({units}): Scene(E*={sc.modulus:g} "
            f"{sc.modulus_units}, hardness={'none' if sc.hardness is None else f'{sc.hardness:g}'}, boundary {boundary}, "
            f"{counter}, lengths in {sc.length_units}); Polonsky-Keer solve, {settings}")


def _snap_grid(ds):
    """``x``/``y`` as ``x0 + m·Δ`` with ``Δ`` rounded to 10 significant digits (and ``x0`` to 1e-6 of it).

    A grid converted from another unit is off by rounding (0.0625 µm from nm: 0.06250000000000001),
    and maps on it would not align with those of the same grid given in µm (an outer join of both).
    """
    snapped = {}
    for d in ("x", "y"):
        if d in ds.coords and ds.sizes.get(d, 0) > 1:
            c = ds.coords[d]
            v = np.asarray(c.values, dtype=float)
            step = float(f"{(v[-1] - v[0]) / (v.size - 1):.10g}")
            q = 10.0 ** (np.floor(np.log10(abs(step))) - 6) if step else 1.0
            snapped[d] = c.copy(data=np.round(v[0] / q) * q + np.arange(v.size) * step)
    return ds.assign_coords(snapped)


def _contact_units(units, sources, read_options) -> str | None:
    """The one length unit of a contact batch: ``units``, else the first measurement's (a file's: the unit it
    is read in, metres unless ``read_options`` say otherwise); ``"1"`` when the first measurement has none."""
    if units is not None:
        return normalize_units(units)
    first = sources[0]
    if not isinstance(first, xr.Dataset):
        return normalize_units(read_options.get("units") or "m")
    try:
        return length_units_of(first)
    except UnitsError:  # unitless data: solved as they are
        return "1"


_SCAN_IN_HISTORY = re.compile(r"^xtopo contact of an? (line|area) scan", re.MULTILINE)
#: result variables whose units differ between line scans (force per unit length, contact length) and area
#: scans (force, contact area): one variable cannot label both, so a batch that mixes the two drops them
_SCAN_DEPENDENT = ("load", "contact_area")


def _scan_of(ds) -> str | None:
    """``"line"`` or ``"area"`` for a measurement Dataset (None where it has no height: its item fails)."""
    h = ds.get("height")
    return None if h is None else ("area" if "y" in h.dims else "line")


def _load_units(scan, units) -> str:
    return f"E* {units}" + ("2" if scan == "area" else "")


def _a(scan) -> str:
    return f"an {scan} scan" if scan == "area" else f"a {scan} scan"


def _mixed_scans_message(control, found, units) -> str:
    return (f"{found}: a load is a force on an area scan (E*·{units}²) but a force per unit length on a line scan "
            f"(E*·{units}), so one {control!r} coordinate cannot label both; solve line and area scans in separate "
            "batches, or give mean_pressures= or penetrations=, which mean the same on both")


def _scans_of_items(ds, sources) -> dict:
    """The kind of scan of each measurement that was solved: an in-memory Dataset's from its height, a file's
    from the contact line of its history (the file was read in the worker)."""
    kinds = {}
    hist = ds[HISTORY].values if HISTORY in ds.coords else [""] * ds.sizes[MEASUREMENT]
    for name, src, h in zip(ds[MEASUREMENT].values, sources, hist):
        found = _SCAN_IN_HISTORY.findall(str(h))
        kind = found[-1] if found else (_scan_of(src) if isinstance(src, xr.Dataset) else None)
        if kind is not None and (ds[ERROR].sel({MEASUREMENT: name}) == "").any():
            kinds[str(name)] = kind
    return kinds


def _refuse_mixed_scans(ds, control, kinds, units, dim):
    """A load-controlled batch of files that turned out to mix line and area scans: the items of another kind
    than the first solved one fail (NaN results and an error), as an item of the wrong kind does in a worker."""
    scan = next(iter(kinds.values()))
    wrong = [m for m, k in kinds.items() if k != scan]
    if not wrong:
        return ds
    keep = ~ds[MEASUREMENT].isin(wrong)
    for v in list(ds.data_vars):
        if v != ERROR and MEASUREMENT in ds[v].dims:
            ds[v] = ds[v].where(keep)
    other = "line" if scan == "area" else "area"
    msg = "XtopoError: " + _mixed_scans_message(control, f"this measurement is {_a(other)}, but the loads of this "
                                                         f"batch are for {scan} scans (its first file solved)", units)
    ds[ERROR] = xr.where(keep, ds[ERROR], msg, keep_attrs=True).astype(object)
    if HISTORY in ds.coords:  # as for any failed item
        ds = ds.assign_coords({HISTORY: ds[HISTORY].where(keep, "").astype(object)})
    # the labels the items of the two kinds disagreed on (and lost when they were combined): the kept kind's
    ds[control].attrs.update(units=_load_units(scan, units), long_name="normal load"
                             + (" per unit length" if scan == "line" else ""))
    if "contact_area" in ds.data_vars:
        ds["contact_area"].attrs.update(units=units + ("2" if scan == "area" else ""),
                                        long_name="contact " + ("area" if scan == "area" else "length"))
    failed = _failed_items(ds, dim)
    ds.attrs.update(n_failed=len(failed), failed_items=json.dumps(failed))
    return ds


def _require_contact():
    try:
        from .contact import Scene  # noqa: F401
    except ImportError as exc:
        raise XtopoError(f"the contact solver (xtopo.contact.Scene) is not available: {exc}") from None


def contact(measurements, loads=None, *, mean_pressures=None, penetrations=None, modulus: float = 1.0,
            hardness: float | None = None, periodic: bool | None = None, tol: float | None = None,
            maxiter: int | None = None, maps: bool = False, chunks=None, client=None, scheduler=None,
            workers=None, store=None, progress: bool = True, fft_threads: int | None = 1,
            retries: int = 1, read_options: dict | None = None, units: str | None = None) -> xr.Dataset:
    """Contact of many measurements at many loads, as a chunked Dask batch (see :func:`run`).

    Exactly one of ``loads``, ``mean_pressures``, ``penetrations`` is given; it becomes the
    second dimension of the result (``load``, ``mean_pressure`` or ``penetration``). Each task
    builds an :class:`xtopo.contact.Scene` in its worker and solves its items.

    Every measurement is converted to one length unit (``units``) before it is solved, so
    that a load means the same force on each of them whatever unit it was given in (a load
    of 0.01 E*·µm² applied to a copy in nm would otherwise be 10⁶ times smaller) and the
    results share their labels (the ``load`` coordinate, contact areas, penetrations, the
    x/y coordinates of the maps).

    Parameters
    ----------
    measurements : mapping, DataTree, or sequence of Dataset / path
        The topographies (paths are read in the workers).
    loads, mean_pressures, penetrations : sequence of float
        The controlled quantity: load in units of ``E*`` × ``units``² (``E*`` × ``units``
        for line scans: force per unit length), mean pressure in units of ``E*``,
        penetration in ``units``.

        A load is a force on an area scan but a force per unit length on a line scan: the
        two are different quantities, and one ``load`` coordinate (one units label) cannot
        hold both. So ``loads=`` needs all measurements to be line scans or all area scans:
        a mix of in-memory Datasets is refused before anything is solved (an
        :class:`~xtopo.errors.XtopoError`); a file, whose kind is known only once it is
        read, of the other kind than the in-memory measurements (or, in a batch of files
        only, than the first file solved) fails as an item with an error saying so. A mean
        pressure (in ``E*``) and a penetration (a length) mean the same on both kinds, so
        ``mean_pressures=`` and ``penetrations=`` accept a mix; their results then leave out
        ``load`` and ``contact_area`` (force per length and contact length for line scans,
        force and contact area for area scans: one variable cannot label both) and keep
        ``mean_pressure``, ``area_fraction`` and ``penetration``, which they share.
    modulus, hardness, periodic
        Passed to :class:`xtopo.contact.Scene` (``periodic=None``: from the measurement).
    tol, maxiter
        Passed to ``Scene.solve`` when given.
    maps : bool
        Keep the pressure/displacement/gap/contact maps (large); default only the scalars
        (load, mean pressure, area fraction, penetration, iterations, residual, converged).
    chunks, client, scheduler, workers, store, progress, fft_threads, retries, read_options
        See :func:`run`.
    units : str, optional
        Length unit of the solves (``"um"``, ``"nm"``, ...). Default: the unit of the first
        measurement (for a file, the unit it is read in: metres unless ``read_options`` give
        ``units``), as :func:`xtopo.stitching.twin_psd` does.

    Returns
    -------
    xarray.Dataset
        Dims (``measurement``, ``load``, ...) plus ``error``; see :func:`run`.
    """
    given = [(k, v) for k, v in (("load", loads), ("mean_pressure", mean_pressures),
                                 ("penetration", penetrations)) if v is not None]
    if len(given) != 1:
        raise XtopoError("give exactly one of loads=, mean_pressures=, penetrations=")
    control, values = given[0]
    _require_contact()
    from .contact.scene import scene_parameters
    from .contact.solve import control_value, solver_parameters

    # parameters shared by every item are checked here, not N times in the workers
    modulus, hardness, periodic = scene_parameters(modulus, hardness, periodic)
    tol, maxiter = solver_parameters(tol, maxiter)
    maps = flag(maps, "maps")
    _options(control, workers, fft_threads, retries, progress, values)  # a 1D, non-empty sequence
    values = [control_value(control, v, hardness) for v in np.atleast_1d(np.asarray(values, dtype=object))]
    scene = {"modulus": modulus}
    if hardness is not None:
        scene["hardness"] = hardness
    if periodic is not None:
        scene["periodic"] = periodic
    solve = {k: v for k, v in (("tol", tol), ("maxiter", maxiter)) if v is not None}
    names, sources = _names_and_sources(measurements)
    units = _contact_units(units, sources, _read_options(read_options))
    # the in-memory measurements' kinds (line or area scan) are known now; files' only once read
    scans = {n: k for n, s in zip(names, sources) if isinstance(s, xr.Dataset) and (k := _scan_of(s)) is not None}
    scan = None
    if control == "load" and scans:
        first = next(iter(scans.items()))
        other = next(((n, k) for n, k in scans.items() if k != first[1]), None)
        if other is not None:
            raise XtopoError(_mixed_scans_message(control, f"loads= for a mix of line and area scans: measurement "
                                                           f"{first[0]!r} is {_a(first[1])}, {other[0]!r} "
                                                           f"{_a(other[1])}", units))
        scan = first[1]
    func = functools.partial(_contact_item, control=control, scene=scene, solve=solve, maps=maps, units=units,
                             scan=scan)
    long_name = {"load": "normal load" + (" per unit length" if scan == "line" else ""),
                 "mean_pressure": "mean pressure", "penetration": "penetration"}[control]
    dim_attrs = {"long_name": f"{long_name} (imposed)"}
    # the coordinate's units when no item gives them (all failed); a load's depend on the scan (area or line)
    dim_units = {"mean_pressure": "E*", "penetration": units, "load": scan and _load_units(scan, units)}.get(control)
    if dim_units is not None:
        dim_attrs["units"] = dim_units
    ds = run(func, measurements, values, dim=control, dim_attrs=dim_attrs,
             chunks=chunks, client=client, scheduler=scheduler, workers=workers, store=store, progress=progress,
             fft_threads=fft_threads, retries=retries,
             read_options=read_options)
    kinds = _scans_of_items(ds, sources)
    if len(set(kinds.values())) > 1:
        if control == "load":  # files only (in-memory mixes were refused): which kind they are was learnt now
            ds = _refuse_mixed_scans(ds, control, kinds, units, control)
        else:
            ds = ds.drop_vars([v for v in _SCAN_DEPENDENT if v in ds.data_vars])
            ds.attrs["comment"] = ("the batch mixes line and area scans: load and contact_area (force per unit "
                                   "length and contact length for a line scan, force and contact area for an area "
                                   "scan) are left out; mean_pressure, area_fraction and penetration mean the same "
                                   "on both")
    return ds


# --------------------------------------------------------------------------- analyses


def _available_analyses() -> list[str]:
    from . import analysis

    return sorted(m.name for m in pkgutil.iter_modules(analysis.__path__) if not m.name.startswith("_"))


def _resolve_analysis(analysis):
    """``"scalars"`` → :func:`xtopo.analysis.scalars.scalars`; callables pass through."""
    if callable(analysis):
        return analysis
    name = str(analysis)
    try:
        module = importlib.import_module(f"xtopo.analysis.{name}")
        return getattr(module, name)
    except (ImportError, AttributeError):
        raise XtopoError(f"unknown analysis {name!r}; available: {', '.join(_available_analyses())} "
                         "(or pass a function)") from None


def _analysis_label(analysis) -> str:
    return analysis if isinstance(analysis, str) else getattr(analysis, "__name__", "analysis")


def _analyze_item(ds, *, analyses):
    """Every analysis of one measurement, merged (variables prefixed by the analysis when several)."""
    parts = []
    for a in analyses:
        res = _resolve_analysis(a)(ds)
        if isinstance(res, xr.DataArray):
            res = res.to_dataset(name=res.name or _analysis_label(a))
        if len(analyses) > 1:
            res = res.rename({v: f"{_analysis_label(a)}_{v}" for v in res.data_vars})
        parts.append(res)
    return xr.merge(parts, join="outer", combine_attrs="drop_conflicts", compat="no_conflicts")


def analyze(measurements, analyses=("scalars",), *, chunks=None, client=None, scheduler=None, workers=None,
            store=None, progress: bool = True, fft_threads: int | None = 1, retries: int = 1,
            read_options: dict | None = None) -> xr.Dataset:
    """Analyses of many measurements as a chunked Dask batch (see :func:`run`).

    Parameters
    ----------
    measurements : mapping, DataTree, or sequence of Dataset / path
        The measurements (paths are read in the workers).
    analyses : sequence of str or callable
        Names of :mod:`xtopo.analysis` modules (``"scalars"``, ``"psd"``, ...; the function of
        the same name is called with the measurement) or picklable functions ``f(ds)``.
        With several analyses the variables are named ``<analysis>_<variable>``.
    chunks, client, scheduler, workers, store, progress, fft_threads, retries, read_options
        See :func:`run`.

    Returns
    -------
    xarray.Dataset
        Results along ``measurement`` plus ``error``; see :func:`run`.
    """
    analyses = tuple(analyses)
    if not analyses:
        raise XtopoError("give at least one analysis")
    for a in analyses:
        _resolve_analysis(a)  # fail early, on the client, for unknown names
    func = functools.partial(_analyze_item, analyses=analyses)
    return run(func, measurements, None, chunks=chunks, client=client, scheduler=scheduler, workers=workers,
               store=store, progress=progress, fft_threads=fft_threads, retries=retries,
               read_options=read_options)
