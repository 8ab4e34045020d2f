"""Where a batch's tasks run: a distributed client or one of dask's local schedulers.

* on the ``client=`` given, else on the active :class:`distributed.Client`;
* ``scheduler="tcp://host:port"``: a client to that scheduler (closed afterwards);
* ``scheduler="local"``: a :class:`distributed.LocalCluster` of ``workers`` processes
  with one thread each (fault tolerant: a worker that dies is replaced and its
  tasks rerun);
* otherwise dask's local ``"threads"`` (default), ``"processes"`` or ``"sync"`` scheduler.

:func:`execute` runs the chunks there and returns, for each chunk key, the chunk's
Dataset or the exception that ended its task.
"""

from __future__ import annotations

import collections
import contextlib
import os
import uuid

import numpy as np

from ..errors import XtopoError
from ._task import run_chunk, run_chunks

__all__ = ["fft_env", "execute"]

_ADDRESS_PREFIXES = ("tcp://", "tls://", "inproc://", "ucx://", "ws://", "wss://")
_LOCAL_SCHEDULERS = ("threads", "processes", "sync", "synchronous", "single-threaded")


@contextlib.contextmanager
def fft_env(threads):
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

        return get_client()
    except (ImportError, ValueError):  # distributed comes with the [dask] extra; ValueError: no client is running
        return None


@contextlib.contextmanager
def _client_for(client, scheduler, workers):
    """The distributed client to use (None: a local dask scheduler), closing any we open."""
    if client is not None:
        from distributed import Client

        if not isinstance(client, Client):
            raise XtopoError(f"client must be a distributed.Client, got {type(client).__name__}; give scheduler= "
                             "for a local scheduler or a scheduler address")
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
                Client(cluster, set_as_default=False) as c:
            yield c
        return
    if not scheduler.startswith(_ADDRESS_PREFIXES):
        raise XtopoError(f"unknown scheduler {scheduler!r}; use 'threads', 'processes', 'sync', 'local' "
                         "or a scheduler address like 'tcp://host:8786'")
    if scheduler.startswith(("tcp://", "tls://")):
        from distributed.comm import get_address_host_port

        try:  # before any Client exists: a Client that fails to connect lingers until exit (60 s on close)
            get_address_host_port(scheduler)
        except ValueError as exc:
            raise XtopoError(f"scheduler {scheduler!r} is not an address: {exc}; give it as "
                             "'tcp://host:port', e.g. 'tcp://127.0.0.1:8786'") from None
    try:
        # not the process's default client: a batch leaves the user's dask configuration as it found it
        # (a Client that fails to connect would otherwise stay registered, and every later dask compute
        # in the process would ask the dead scheduler)
        c = Client(scheduler, set_as_default=False)  # connect timeout: dask config distributed.comm.timeouts.connect
    except (OSError, TimeoutError, ValueError) as exc:  # ValueError: an address without host or port
        raise XtopoError(f"cannot connect to the Dask scheduler at {scheduler}: {exc}. Is `dask scheduler` "
                         f"running there, and are workers attached (`dask worker {scheduler}`)?") from None
    try:
        yield c
    finally:
        c.close()


#: seconds of work a task should carry before small chunks are packed into it (a distributed task costs
#: 2.5-10 ms of scheduling and transfer on the reference machine: at most a few per cent of this);
#: ``XTOPO_BATCH_TASK_SECONDS`` overrides it, 0 gives every chunk a task of its own
TASK_SECONDS = 0.25

#: times a task whose result was lost (its worker died after finishing it) is submitted again
LOST_RESUBMITS = 3


def _group_size(seconds: float, remaining: int, workers: int) -> int:
    """Chunks per task: enough for :data:`TASK_SECONDS` of work at ``seconds`` per chunk, but at least
    four tasks per worker (so that the workers finish together and a killed worker loses little)."""
    target = float(os.environ.get("XTOPO_BATCH_TASK_SECONDS", TASK_SECONDS))
    want = int(np.ceil(target / max(seconds, 1e-6)))
    return max(1, min(want, -(-remaining // (4 * max(workers, 1)))))


def _execute_distributed(client, chunks, progress, retries) -> dict:
    """Run ``chunks`` on the client's workers: first two chunks per worker, timed, then the rest packed
    into tasks of :func:`_group_size` chunks. A chunk whose group failed as a whole (its worker died too
    often, or it raised) runs again in a task of its own."""
    from distributed import as_completed

    workers = max(1, sum(client.nthreads().values()))  # tasks that run at once
    pending = list(chunks)
    out, spent, lost, groups = {}, [], collections.Counter(), {}  # groups: each running future's chunks

    def submit(group, retry=retries):  # a key of its own each time: a resubmitted group is a new task
        key = f"xtopo-batch-{group[0].key[:16]}-{len(group)}-{uuid.uuid4().hex[:8]}"
        fut = client.submit(run_chunks, group, key=key, pure=False, retries=retry)
        groups[fut] = group
        return fut

    # two probes a worker: a worker's first chunk may carry its imports; the group size is taken from the
    # quickest of the first workers + 1 chunks
    probes = [submit([c]) for c in pending[:2 * workers]]
    pending = pending[2 * workers:]
    waiting = as_completed(probes)

    def show(futures):  # distributed's bar (blocks until they are done) over every task of the batch
        if progress and futures:
            from distributed import progress as _progress

            _progress(futures)

    if not pending:
        show(probes)
    for fut in waiting:
        group = groups.pop(fut)
        if fut.status == "finished":
            for key, res, seconds in fut.result():
                if isinstance(res, BaseException) and len(group) > 1:
                    waiting.add(submit([c for c in group if c.key == key]))
                    continue
                out[key] = res
                spent.append(seconds)
        elif fut.status == "lost" and lost[group[0].key, len(group)] < LOST_RESUBMITS:
            # the worker holding the finished result died: run it again (its chunks' files in the store,
            # written before the task returned, are read back)
            lost[group[0].key, len(group)] += 1
            waiting.add(submit(group))
        elif len(group) > 1:  # isolate the chunk that failed the group
            for c in group:
                waiting.add(submit([c]))
        elif fut.status == "error":
            out[group[0].key] = fut.exception()
        else:
            out[group[0].key] = XtopoError("task was cancelled (the scheduler lost it)" if fut.status == "cancelled"
                                           else f"the task's result was lost {LOST_RESUBMITS + 1} times (the "
                                           "workers holding it died)")
        fut.release()
        if pending and (len(spent) > workers or not groups):  # timed (or the probes failed: one chunk a task)
            size = _group_size(min(spent), len(pending), workers) if spent else 1
            new = [submit(pending[i:i + size]) for i in range(0, len(pending), size)]
            pending = []
            waiting.update(new)
            show([f for f in probes if f in groups] + new)
    return out


def _execute_local(chunks, scheduler, workers, progress) -> dict:
    import dask
    from dask.diagnostics import ProgressBar

    if not chunks:
        return {}
    tasks = [dask.delayed(run_chunk, pure=False)(chunk) for chunk in chunks]
    with ProgressBar() if progress else contextlib.nullcontext():
        results = dask.compute(*tasks, scheduler=scheduler or "threads", num_workers=workers)
    return {chunk.key: r for chunk, r in zip(chunks, results)}


def execute(chunks, *, client, scheduler, workers, progress, retries) -> dict:
    """Run ``chunks`` (a list of :class:`~xtopo.batch._task.Chunk`) where the options say.

    Returns
    -------
    dict
        Chunk key → the chunk's Dataset, or the exception its task ended with (distributed
        only; on a local scheduler an exception that escapes a task ends the run).
    """
    with _client_for(client, scheduler, workers) as c:
        if c is not None:
            # made the current client: distributed's as_completed and progress look it up, and one given as
            # client= need not be the process's default
            with c.as_current():
                return _execute_distributed(c, chunks, progress, retries)
        return _execute_local(chunks, scheduler, workers, progress)
