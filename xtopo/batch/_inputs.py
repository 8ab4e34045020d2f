"""What a batch is given, checked on the client before any task is built.

The measurements (names and sources), the run options, the chunk sizes and the
``read_options`` for the files: each check raises an :class:`~xtopo.errors.XtopoError`
that names the argument, so that a bad call fails at once instead of as N identical
item errors in the workers.
"""

from __future__ import annotations

import os
from typing import Annotated

import numpy as np
import xarray as xr

from ..errors import XtopoError
from ..io.open import open_topography
from ..io.registry import detect
from ..params import Count, Dict, Flag, Path, preflight
from ._results import ERROR, HISTORY, MEASUREMENT, SOURCE

__all__ = ["names_and_sources", "run_options", "chunk_sizes", "checked_read_options",
           "Workers", "Retries", "Progress", "Attrs", "StorePath", "ReadOptions"]

#: the declared run options of a batch (:func:`xtopo.batch.run`, :func:`xtopo.batch.contact`)
Workers = Annotated[int | None, Count()]
Retries = Annotated[int, Count(min=0)]
Progress = Annotated[bool, Flag()]
Attrs = Annotated[dict | None, Dict()]
StorePath = Annotated[str | None, Path("directory path")]
ReadOptions = Annotated[dict | None, Dict()]


def names_and_sources(measurements) -> tuple[list[str], list]:
    """Names and sources (Dataset or path) of the measurements, in order.

    Names are the mapping keys / child names, file basenames or a Dataset's
    ``title``/``source_file``; a name given twice gets ``-2``, ``-3``, ... appended.
    """
    if isinstance(measurements, xr.DataTree):
        items = [(name, node.to_dataset()) for name, node in measurements.children.items()]
    elif isinstance(measurements, dict):
        items = list(measurements.items())
    elif isinstance(measurements, (str, os.PathLike, xr.Dataset)):
        items = [(None, measurements)]
    else:
        try:
            items = [(None, m) for m in measurements]
        except TypeError:
            raise XtopoError(f"measurements must be a Dataset, a file path, or a mapping, DataTree or sequence of "
                             f"them, got {type(measurements).__name__}") from None
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


def run_options(func, dim, params) -> list | None:
    """``func`` and ``dim`` checked (the other run options are declared); returns ``params`` (the parameter values
    along ``dim``) as a list, or None."""
    if not callable(func):
        raise XtopoError(f"func must be a function to run on each measurement, got {type(func).__name__}")
    reserved = (MEASUREMENT, ERROR, HISTORY, SOURCE)
    if not isinstance(dim, str) or not dim or dim in reserved:
        raise XtopoError(f"dim must be a name (str) other than {', '.join(map(repr, reserved))}, got {dim!r}")
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


def chunk_sizes(chunks, dim, n_meas: int, n_par: int) -> list[int]:
    """Measurements and parameter values per chunk, from ``chunks`` (an int: measurements; a dict: both)."""
    if chunks is None:
        chunks = {}
    elif isinstance(chunks, (int, np.integer)) and not isinstance(chunks, (bool, np.bool_)):
        chunks = {MEASUREMENT: Count().check(chunks, "chunks")}
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
        sizes.append(n if everything else Count().check(c, f"chunk size along {d!r} (or -1/None for all)"))
    return sizes


#: read options that may differ per file: a list or tuple gives one value per measurement
PER_FILE = ("tip_radius", "resolution")


def checked_read_options(read_options: dict | None, n: int) -> list[dict]:
    """``read_options`` (a dict, declared; None: {}) for each of ``n`` measurements, checked against
    :func:`xtopo.open_topography`'s keywords: a ``tip_radius``/``resolution`` given as a list or tuple holds one
    value per measurement (an :class:`~xtopo.errors.XtopoError` when its length is not ``n``)."""
    read_options = read_options or {}
    out = [dict(read_options) for _ in range(n)]
    for key in PER_FILE:
        values = read_options.get(key)
        if isinstance(values, (list, tuple)):
            if len(values) != n:
                raise XtopoError(f"read_options[{key!r}] holds {len(values)} values for {n} measurements: give one "
                                 "value for all, or one per measurement")
            for opts, v in zip(out, values):
                opts[key] = v
    for opts in out if read_options else ():
        preflight(open_topography, opts, "read_options")
        if opts.get("format") is not None:
            detect("read_options", opts["format"])
    return out
