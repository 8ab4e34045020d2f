"""Batch runs on Dask: many measurements × many parameters, chunked, resumable, fault tolerant.

* :func:`run` maps any function over measurements (× parameter values, e.g. loads);
* :func:`contact` solves the contact of each measurement at each load (mean pressure,
  penetration);
* :func:`analyze` runs :mod:`xtopo.analysis` analyses on each measurement;
* :func:`open_store` reads the results of a (possibly unfinished) run from its store.

The work is a grid of *items* (one measurement × one parameter value) cut into *chunks*
(blocks of measurements × parameter values), one Dask task each. A task opens its
measurements in the worker (paths travel, not arrays), preprocesses them there when asked
(``preprocess={"detrend": "plane", "fill_missing": True}``), builds what the work needs there
and writes its chunk atomically into the store as soon as it is done; a rerun with the
same store computes only the chunks that are missing or had failed items. Errors of
single items (an unreadable file, a solve that fails) are caught in the task and reported
in the result's ``error`` variable; the other items go on.

How it is built, one concern per module:

* ``_inputs``: the arguments, checked on the client before any task is built;
* ``_task``: what runs in a worker, one :class:`~xtopo.batch._task.Chunk` of items;
* ``_dispatch``: where the tasks run, a distributed client or a local dask scheduler;
* ``_store``: one NetCDF file per chunk, keyed by its inputs, and a manifest;
* ``_results``: the layout of the results, items → a chunk's Dataset → the batch's Dataset;
* ``_engine``: :func:`run` and :func:`open_store` (plan, reuse, run, assemble);
* ``_contact``: :func:`contact` and the contact solves of one measurement;
* ``_scans``: line and area scans in one contact batch;
* ``_analyze``: :func:`analyze`.
"""

from __future__ import annotations

from ._analyze import analyze
from ._contact import contact
from ._engine import open_store, run

# internal names that the CLI, the tests and the benchmarks reach through xtopo.batch
from ._analyze import _analyze_item  # noqa: F401
from ._contact import _contact_item  # noqa: F401
from ._store import chunk_key  # noqa: F401

__all__ = ["run", "contact", "analyze", "open_store"]
