"""Data-dependent checks the declared parameters (:mod:`xtopo.params`) leave to the function body. Not public API.

A number of bins against the values binned, sizes per lateral axis of a grid of known dimensions, an
array of real numbers, a directory to create: each raises an :class:`~xtopo.errors.XtopoError` naming
what it checks.
"""

from __future__ import annotations

import os

import numpy as np

from .errors import GridError, XtopoError

__all__ = ["per_axis", "make_directory", "bin_count", "MAX_SPARSE_BINS", "real_array"]

#: a number of bins may exceed the number of values binned (most bins then stay empty) up to this many bins.
MAX_SPARSE_BINS = 10_000


def bin_count(value: int, name: str, samples: int, *, error: type[XtopoError] = XtopoError) -> int:
    """``value`` (declared an integer, :class:`~xtopo.params.Count`) as a number of bins for ``samples`` values.

    More than both ``samples`` and :data:`MAX_SPARSE_BINS` is refused: such bins are nearly all
    empty, and a request like ``10**9`` would allocate gigabytes of edges and counts.
    """
    limit = max(MAX_SPARSE_BINS, int(samples))
    if value > limit:
        raise error(f"{name} must be at most {limit} here ({int(samples)} values to bin; more bins "
                    f"than values stay empty), got {value!r}")
    return value


def per_axis(value, ndim: int, name: str, *, sign: str = "positive") -> np.ndarray:
    """``value`` as ``ndim`` finite numbers, one per axis (``(y, x)`` or ``x``; one value is used for every axis).

    ``sign``: ``"positive"`` (sizes), ``"non-negative"`` (offsets) or ``"any"`` (positions).
    """
    v = None if isinstance(value, (bool, np.bool_)) else real_array(value)  # True is not the length 1
    ok = v is not None and v.ndim <= 1 and (v.ndim == 0 or v.size in (1, ndim)) and np.all(np.isfinite(v))
    if ok and sign != "any":
        ok = bool(np.all(v > 0) if sign == "positive" else np.all(v >= 0))
    if not ok:
        what = "" if sign == "any" else f"{sign} "
        axes = "(y, x) or one for both" if ndim == 2 else "x"
        raise GridError(f"{name} must be {what}finite number(s) in the length unit, {axes}, got {value!r}")
    return np.broadcast_to(v, (ndim,)).copy()


def real_array(values) -> np.ndarray | None:
    """``values`` as a float array (any shape) if they are real numbers (not bools, strings or objects), else None."""
    if isinstance(values, (str, bytes)):
        return None
    try:
        raw = np.asarray(values)
        return np.asarray(raw, dtype=float) if raw.dtype.kind in "iuf" else None
    except (TypeError, ValueError, OverflowError):
        return None


def make_directory(directory: str, what: str) -> None:
    """Create ``directory`` (and its parents) unless it exists; ``what`` names it in the error."""
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError as exc:
        raise XtopoError(f"cannot create the {what} {directory}: {exc.strerror}") from None
