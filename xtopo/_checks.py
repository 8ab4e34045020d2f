"""Checks of user-given parameters (analyses, preprocessing, contact, batch, storage). Not public API.

Each check returns the value in the type the caller needs, or raises an
:class:`~xtopo.errors.XtopoError` that names the parameter, says what it got and
what it expects (instead of a TypeError or a silent truncation deep inside).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Mapping

import numpy as np
import xarray as xr

from .errors import GridError, XtopoError

__all__ = ["option", "flag", "integer", "positive_number", "real_number", "per_axis", "lengths", "path",
           "make_directory", "bin_count", "MAX_SPARSE_BINS", "xarray_object", "text", "mapping", "real_array"]

#: a number of bins may exceed the number of values binned (most bins then stay empty) up to this many bins.
MAX_SPARSE_BINS = 10_000


def option(value, options, name: str):
    """``value`` if it is one of the strings ``options``."""
    if not isinstance(value, str) or value not in options:
        raise XtopoError(f"{name} must be one of {tuple(options)}, got {value!r}")
    return value


def xarray_object(value, what: str, types: tuple = (xr.Dataset, xr.DataArray)):
    """``value`` if it is one of the xarray ``types``, else an XtopoError; ``what`` names the argument."""
    if not isinstance(value, types):
        names = " or ".join(t.__name__ for t in types)
        raise XtopoError(f"{what} needs an xarray {names}, got {type(value).__name__}")
    return value


def text(value, name: str, *, optional: bool = True):
    """``value`` if it is a str (or None when ``optional``): a title, a label, a variable name."""
    if isinstance(value, str) or (optional and value is None):
        return value
    raise XtopoError(f"{name} must be a string{' or None' if optional else ''}, got {type(value).__name__}")


def mapping(value, name: str) -> dict:
    """``value`` as a dict if it is a mapping (None: empty), e.g. legend labels by name."""
    if value is None:
        return {}
    if not isinstance(value, Mapping) or isinstance(value, (xr.Dataset, xr.DataTree)):
        raise XtopoError(f"{name} must be a dict (or None), got {type(value).__name__}")
    return dict(value)


def flag(value, name: str, *, error: type[XtopoError] = XtopoError) -> bool:
    """``value`` as a bool if it is one (numpy's included) or the integer 0 or 1 (not a string, not None).

    ``error``: the :class:`~xtopo.errors.XtopoError` subclass raised otherwise.
    """
    if isinstance(value, (bool, np.bool_)) or (isinstance(value, numbers.Integral) and value in (0, 1)):
        return bool(value)
    raise error(f"{name} must be True or False, got {value!r}")


def integer(value, name: str, minimum: int = 1, *, error: type[XtopoError] = XtopoError) -> int:
    """``value`` as an int if it is an integer (not a bool, not a float) of at least ``minimum``.

    ``error``: the :class:`~xtopo.errors.XtopoError` subclass raised otherwise.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < minimum:
        raise error(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _real(value) -> float | None:
    """``value`` as a float if it is a real number (not a bool; a 0-d array counts), else None.

    ``float()``, not ``np.isfinite``, decides: an int beyond float64 (``10**400``) is None, not a TypeError.
    """
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if not isinstance(value, numbers.Real) or isinstance(value, (bool, np.bool_)):
        return None
    try:
        return float(value)
    except OverflowError:
        return None


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


def positive_number(value, name: str, *, infinite: bool = False, error: type[XtopoError] = XtopoError) -> float:
    """``value`` as a float if it is a real number above 0 (finite unless ``infinite``; a 0-d array counts).

    ``error``: the :class:`~xtopo.errors.XtopoError` subclass raised otherwise.
    """
    number = _real(value)
    if number is None or not number > 0 or not (infinite or math.isfinite(number)):
        raise error(f"{name} must be a positive {'' if infinite else 'finite '}number, got {value!r}")
    return number


def per_axis(value, ndim: int, name: str, *, sign: str = "positive") -> np.ndarray:
    """``value`` as ``ndim`` finite numbers, one per axis (``(y, x)`` or ``x``; one value is used for every axis).

    ``sign``: ``"positive"`` (sizes), ``"non-negative"`` (offsets) or ``"any"`` (positions).
    """
    v = None
    if not isinstance(value, (str, bytes, bool, np.bool_)):
        try:
            v = np.asarray(value, dtype=float)
        except (TypeError, ValueError, OverflowError):
            v = None
    ok = v is not None and v.ndim <= 1 and (v.ndim == 0 or v.size in (1, ndim)) and np.all(np.isfinite(v))
    if ok and sign != "any":
        ok = bool(np.all(v > 0) if sign == "positive" else np.all(v >= 0))
    if not ok:
        what = "" if sign == "any" else f"{sign} "
        axes = "(y, x) or one for both" if ndim == 2 else "x"
        raise GridError(f"{name} must be {what}finite number(s) in the length unit, {axes}, got {value!r}")
    return np.broadcast_to(v, (ndim,)).copy()


def real_number(value, name: str, *, low: float = -np.inf, high: float = np.inf, closed: bool = True) -> float:
    """``value`` as a finite float in ``[low, high]`` (``(low, high)`` unless ``closed``)."""
    number = _real(value)
    ok = (number is not None and math.isfinite(number)
          and (low <= number <= high if closed else low < number < high))
    if not ok:
        if (low, high) == (-np.inf, np.inf):
            bounds = ""
        elif high == np.inf:
            bounds = f" {'>=' if closed else '>'} {low:g}"
        else:
            bounds = f" in [{low:g}, {high:g}]" if closed else f" in ({low:g}, {high:g})"
        raise XtopoError(f"{name} must be a finite number{bounds}, got {value!r}")
    return number


def real_array(values) -> np.ndarray | None:
    """``values`` as a float array (any shape) if they are real numbers (not bools, strings or objects), else None."""
    if isinstance(values, (str, bytes)):
        return None
    try:
        raw = np.asarray(values)
        return np.asarray(raw, dtype=float) if raw.dtype.kind in "iuf" else None
    except (TypeError, ValueError, OverflowError):
        return None


def lengths(values, name: str, units: str, longest: float | None = None) -> np.ndarray:
    """``values`` as a 1D float array of lengths in ``(0, longest]`` (``units`` names their unit).

    Without ``longest`` any positive finite value is accepted (e.g. wavevectors in ``m-1``).
    """
    v = None
    if not isinstance(values, (str, bytes)):
        try:
            raw = np.asarray(values)
            if raw.dtype.kind not in "bcSU":  # True is not the length 1, nor "1" a number
                v = np.atleast_1d(np.asarray(raw, dtype=float))
        except (TypeError, ValueError, OverflowError):
            v = None
    if v is None or v.ndim != 1:
        raise XtopoError(f"{name} must be a number or a 1D sequence of numbers (lengths in {units}), got {values!r}")
    bad = v[~(np.isfinite(v) & (v > 0) & (longest is None or v <= longest))]
    if bad.size:
        bound = f" in {units}" if longest is None else f" of at most {longest:g} {units} (the size of the measurement)"
        raise XtopoError(f"{name} must be positive finite lengths{bound}, got {bad.tolist()}")
    return v


def path(value, name: str, *, kind: str = "path") -> str:
    """``value`` as a str path if it is one (str, bytes or os.PathLike); ``kind`` says which (e.g. "file path").

    An empty path is refused: it would mean the working directory (a store or cache filling it).
    """
    try:
        text = os.fsdecode(os.fspath(value))  # bytes too: a str, as the callers join it with str
    except TypeError:
        raise XtopoError(f"{name} must be a {kind} (str or os.PathLike), got {type(value).__name__}") from None
    if not text:
        raise XtopoError(f"{name} must be a {kind}, got an empty string")
    return text


def make_directory(directory: str, what: str) -> None:
    """Create ``directory`` (and its parents) unless it exists; ``what`` names it in the error."""
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError as exc:
        raise XtopoError(f"cannot create the {what} {directory}: {exc.strerror}") from None
