"""Registry of file formats and content-based format detection.

Each format module in :mod:`xtopo.io.formats` calls :func:`register` with a
:class:`Format`. Detection looks at the first bytes of the file (``sniff``);
the suffix is only a hint that orders candidates.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import os
import pkgutil
from typing import Callable

from ..errors import ReaderError, UnsupportedFormatError
from ._binary import read_bytes

__all__ = ["Format", "ChannelInfo", "register", "formats", "detect", "HEADER_BYTES", "READ_OPTIONS"]

#: Bytes handed to ``sniff`` functions.
HEADER_BYTES = 4096


@dataclasses.dataclass(frozen=True)
class ChannelInfo:
    """What :func:`xtopo.io.channels` reports for one channel of a file.

    ``shape`` is ``(ny, nx)`` or ``(nx,)``; ``size`` the physical size in ``units``
    (same order, ``None`` where the file does not say); ``height_units`` the unit of
    the data values as stored (may be non-length, e.g. ``"V"`` or ``"deg"``).
    """

    index: int
    name: str
    shape: tuple
    size: tuple | None
    units: str | None
    height_units: str | None = None
    is_height: bool = True


@dataclasses.dataclass(frozen=True)
class Format:
    """A file format xtopo can read.

    Parameters
    ----------
    name : str
        Short identifier (``"nanoscope"``, ``"x3p"``, ...), usable as ``format=``.
    description : str
        One line for humans.
    suffixes : tuple of str
        Lower-case suffixes with dot (hints only).
    sniff : callable(head: bytes, path: str) -> bool
        True if ``head`` (the first :data:`HEADER_BYTES` of the file) belongs to this format (raising: False).
    read : callable(path, *, channel=None) -> xarray.Dataset
        Returns a measurement in the file's native length unit (``make_measurement``);
        raises :class:`~xtopo.errors.ReaderError` on bad content.
    channels : callable(path) -> list of ChannelInfo, optional
    priority : int
        Higher is tried first among formats that sniff positive (specific before generic).
    options : tuple of str
        Extra keyword options ``read`` (and ``channels``) accept, from :data:`READ_OPTIONS`:
        generic formats that may lack a physical size or units take them from the caller.
    """

    name: str
    description: str
    suffixes: tuple
    sniff: Callable
    read: Callable
    channels: Callable | None = None
    priority: int = 0
    options: tuple = ()


#: Keyword options of :func:`xtopo.open_topography` that are handed to readers declaring them.
READ_OPTIONS = ("physical_size", "file_units", "height_units")


_REGISTRY: dict[str, Format] = {}


def register(fmt: Format) -> Format:
    """Add ``fmt`` to the registry (called at import time of a format module)."""
    _REGISTRY[fmt.name] = fmt
    return fmt


@functools.cache  # once: the format modules register themselves when imported
def _load_all() -> None:
    pkg = importlib.import_module(f"{__package__}.formats")
    for mod in pkgutil.iter_modules(pkg.__path__):
        if not mod.name.startswith("_"):
            importlib.import_module(f"{pkg.__name__}.{mod.name}")


def formats() -> dict[str, Format]:
    """All registered formats by name."""
    _load_all()
    return dict(_REGISTRY)


def detect(path, format: str | None = None) -> list[Format]:
    """Candidate formats for ``path``, best first.

    Raises
    ------
    UnsupportedFormatError
        If no format recognises the content (or ``format`` is unknown).
    """
    fmts = formats()
    if format is not None:
        if not isinstance(format, str) or format not in fmts:
            raise UnsupportedFormatError(path, f"unknown format {format!r}; known: {', '.join(sorted(fmts))}")
        return [fmts[format]]
    head = read_bytes(path, HEADER_BYTES)
    if not head:
        raise ReaderError(path, "the file is empty")
    suffix = os.path.splitext(str(path))[1].lower()
    hits = []
    for fmt in fmts.values():
        try:
            ok = fmt.sniff(head, str(path))
        except Exception:  # a sniffer must never decide by crashing
            ok = False
        if ok:
            hits.append(fmt)
    if not hits:
        raise UnsupportedFormatError(
            path, "file format not recognised from its content"
            + (f" (suffix {suffix!r})" if suffix else "")
            + f"; supported formats: {', '.join(sorted(fmts))}")
    hits.sort(key=lambda f: (-f.priority, suffix not in f.suffixes, f.name))
    return hits
