"""Analyses of many measurements: :func:`analyze` and its item function."""

from __future__ import annotations

import functools
import importlib
import pkgutil

import xarray as xr

from .. import analysis
from ..errors import XtopoError
from ._engine import run

__all__ = ["analyze"]


@functools.lru_cache(maxsize=1)
def _available_analyses() -> tuple[str, ...]:
    """The :mod:`xtopo.analysis` modules that hold a function of their name (what ``analyses`` may name)."""
    names = sorted(m.name for m in pkgutil.iter_modules(analysis.__path__) if not m.name.startswith("_"))
    return tuple(n for n in names if callable(getattr(importlib.import_module(f"xtopo.analysis.{n}"), n, None)))


def _resolve_analysis(analysis):
    """``"scalars"`` → :func:`xtopo.analysis.scalars.scalars`; callables pass through."""
    if callable(analysis):
        return analysis
    name = str(analysis)
    if name in _available_analyses():
        return getattr(importlib.import_module(f"xtopo.analysis.{name}"), name)
    raise XtopoError(f"unknown analysis {name!r}; available: {', '.join(_available_analyses())} "
                     "(or pass a function)")


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
            read_options: dict | None = None, preprocess=None) -> xr.Dataset:
    """Analyses of many measurements as a chunked Dask batch (see :func:`run`).

    Parameters
    ----------
    measurements : mapping, DataTree, or sequence of Dataset / path
        The measurements (paths are read in the workers).
    analyses : sequence of str or callable
        Names of :mod:`xtopo.analysis` modules (``"scalars"``, ``"psd"``, ...; the function of
        the same name is called with the measurement) or picklable functions ``f(ds)``.
        With several analyses the variables are named ``<analysis>_<variable>``.
    chunks, client, scheduler, workers, store, progress, fft_threads, retries, read_options, preprocess
        See :func:`run`; e.g. ``preprocess={"detrend": "plane"}`` for the scalars of a tilted
        measurement without its tilt.

    Returns
    -------
    xarray.Dataset
        Results along ``measurement`` plus ``error``, in the units the analyses give; see :func:`run`.
    """
    if isinstance(analyses, str) or callable(analyses):
        analyses = (analyses,)
    try:
        analyses = tuple(analyses)
    except TypeError:
        raise XtopoError(f"analyses must be a name, a function or a sequence of them, got "
                         f"{type(analyses).__name__}") from None
    if not analyses:
        raise XtopoError("give at least one analysis")
    for a in analyses:
        _resolve_analysis(a)  # fail early, on the client, for unknown names
    func = functools.partial(_analyze_item, analyses=analyses)
    return run(func, measurements, None, chunks=chunks, client=client, scheduler=scheduler, workers=workers,
               store=store, progress=progress, fft_threads=fft_threads, retries=retries, read_options=read_options,
               preprocess=preprocess)
