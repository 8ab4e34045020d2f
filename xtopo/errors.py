"""Exceptions and warnings raised by xtopo.

Every error xtopo raises on purpose is an :class:`XtopoError`, so callers can
catch one type.  Messages name the file or variable involved and say what to do.
"""

from __future__ import annotations

import sys
import warnings

__all__ = [
    "XtopoError",
    "ReaderError",
    "UnsupportedFormatError",
    "OptionError",
    "UnitsError",
    "GridError",
    "MissingDataError",
    "ChunkError",
    "ValidationError",
    "ContactError",
    "WriteError",
    "ConvergenceWarning",
    "warn",
    "MetadataWarning",
    "UndefinedValueWarning",
]


class XtopoError(Exception):
    """Root of every error raised by xtopo."""


class ReaderError(XtopoError, ValueError):
    """A file could not be read: it is corrupt, truncated or inconsistent.

    Parameters
    ----------
    path : str or os.PathLike or None
        The file that failed; its name is put in front of the message.
    message : str
        What is wrong with the file.
    """

    def __init__(self, path, message: str):
        self.path = None if path is None else str(path)
        self.reason = message
        super().__init__(message if path is None else f"{path}: {message}")


class UnsupportedFormatError(ReaderError):
    """The file's format is not recognised, or the requested channel does not exist."""


class OptionError(ReaderError):
    """The file is of the format tried, and an option given does not apply to it (no other reader is tried)."""


class UnitsError(XtopoError, ValueError):
    """A unit string could not be parsed, or two quantities have incompatible units."""


class GridError(XtopoError, ValueError):
    """The data do not lie on the grid an operation needs (uniform, 2D, large enough, ...)."""


class MissingDataError(GridError):
    """Heights hold missing data (NaN) where an analysis needs complete data."""


class ChunkError(XtopoError, ValueError):
    """A dask array is chunked along a dimension the operation needs whole."""


class ValidationError(XtopoError, ValueError):
    """A Dataset does not follow the xtopo data model (see :mod:`xtopo.conventions`)."""


class ContactError(XtopoError, ValueError):
    """A contact problem is ill-posed (negative modulus, no load given, ...)."""


class WriteError(XtopoError, OSError):
    """A result could not be written (no permission, no such directory, disk full, ...).

    An :class:`OSError` too, with the ``errno`` of the failure (``None`` when the writer gave
    none); the message names the target file, not a temporary one.
    """

    def __str__(self) -> str:
        return self.strerror if self.strerror is not None else super().__str__()


class UndefinedValueWarning(UserWarning):
    """A result is NaN because it is mathematically undefined for this input (the skewness of a flat
    surface), not because a computation failed."""


class ConvergenceWarning(UserWarning):
    """An iterative solver stopped before reaching its tolerance."""


class MetadataWarning(UserWarning):
    """A file lacks metadata a measurement needs (its length unit, its size) and a default was assumed.

    The message names the file and the option (``file_units=``, ``physical_size=``) that states the
    missing value.
    """


#: Top-level packages whose frames stand between a user's call and xtopo's code (a batch's scheduler,
#: xarray's apply_ufunc): a warning is attributed to the first frame outside them and outside xtopo.
_PASS_THROUGH = frozenset({"xtopo", "dask", "distributed", "xarray", "toolz", "concurrent", "threading", "functools"})


def _internal(frame) -> bool:
    return str(frame.f_globals.get("__name__", "")).partition(".")[0] in _PASS_THROUGH


def warn(message: str, category: type[Warning] = UserWarning) -> None:
    """``warnings.warn`` attributed to the user's call: the first frame outside xtopo (and the
    scheduler/xarray frames it runs under), not the internal line that noticed the problem.

    Parameters
    ----------
    message : str
        The warning's text.
    category : type
        Its class, e.g. :class:`ConvergenceWarning`.
    """
    frame, level = sys._getframe(1), 2
    while frame.f_back is not None and _internal(frame):
        frame, level = frame.f_back, level + 1
    warnings.warn(message, category, stacklevel=level)
