"""Small helpers shared by the format readers in :mod:`xtopo.io.formats`.

* :func:`reading` turns any failure while parsing a file into a
  :class:`~xtopo.errors.ReaderError` that names the file,
* :func:`pick_channel` resolves the ``channel=`` argument of a reader,
* :func:`iso_time`, :func:`parse_time`, :func:`unix_time` give acquisition times as ISO 8601,
* :func:`clean_text` decodes fixed-size, NUL-padded header strings.
"""

from __future__ import annotations

import contextlib
import datetime as _dt

import numpy as np

from ..errors import ReaderError, UnsupportedFormatError, XtopoError

__all__ = ["reading", "pick_channel", "iso_time", "parse_time", "unix_time", "clean_text"]


@contextlib.contextmanager
def reading(path, what: str):
    """Context in which every parse failure of ``path`` becomes a :class:`ReaderError`.

    Parameters
    ----------
    path : str
        The file being read (named in the message).
    what : str
        The format, e.g. ``"Wyko OPD"``, used in the message.
    """
    try:
        with np.errstate(all="ignore"):  # overflow from absurd scale factors yields inf, which is masked
            yield
    except ReaderError:
        raise
    except XtopoError as exc:  # e.g. a unit or grid the header states that makes no sense
        raise ReaderError(path, f"invalid {what} header: {exc}") from None
    except (MemoryError, RecursionError) as exc:
        raise ReaderError(path, f"{what} reader gave up: {type(exc).__name__}") from None
    except Exception as exc:  # any parse failure of untrusted content
        raise ReaderError(path, f"malformed {what} content ({type(exc).__name__}: {exc})") from None


def pick_channel(path, names, channel) -> int:
    """Index of the requested ``channel`` (int index, name, or None for the first) among ``names``."""
    names = list(names)
    if not names:
        raise ReaderError(path, "the file holds no readable height channel")
    if channel is None:
        return 0
    if isinstance(channel, str):
        if channel in names:
            return names.index(channel)
        raise UnsupportedFormatError(path, f"no channel named {channel!r}; channels are {names}")
    try:
        idx = int(channel)
    except (TypeError, ValueError):
        raise UnsupportedFormatError(path, f"channel must be an index or a name, got {channel!r}") from None
    if not 0 <= idx < len(names):
        raise UnsupportedFormatError(path, f"channel index {idx} out of range; the file has {len(names)} "
                                           f"channel(s): {names}")
    return idx


def iso_time(year, month=1, day=1, hour=0, minute=0, second=0) -> str | None:
    """ISO 8601 string for a date/time, or ``None`` where the fields do not form a valid date."""
    try:
        return _dt.datetime(int(year), int(month), int(day), int(hour), int(minute), int(second)).isoformat()
    except (TypeError, ValueError, OverflowError):
        return None


def parse_time(text: str, formats) -> str | None:
    """ISO 8601 string from ``text`` using the first of the ``strptime`` ``formats`` that fits."""
    text = " ".join(str(text).split())
    for fmt in formats:
        try:
            return _dt.datetime.strptime(text, fmt).isoformat()
        except ValueError:
            continue
    return None


def unix_time(seconds) -> str | None:
    """ISO 8601 (UTC) string of a POSIX timestamp; ``None`` for 0/unset or out-of-range values."""
    try:
        s = int(seconds)
        if s <= 0 or s >= 0xFFFFFFFF:
            return None
        return _dt.datetime.fromtimestamp(s, tz=_dt.timezone.utc).isoformat()
    except (TypeError, ValueError, OverflowError, OSError):
        return None


def clean_text(raw: bytes, encoding: str = "latin-1") -> str:
    """Decode a NUL-padded fixed-size header string and strip blanks."""
    return raw.split(b"\0", 1)[0].decode(encoding, errors="replace").strip()
