"""Defensive helpers for parsing untrusted binary files.

Every read is bounds-checked and every allocation size is checked against the
bytes actually present *before* allocating, so a corrupt size field gives a
:class:`~xtopo.errors.ReaderError` instead of a crash or a multi-GB allocation.
"""

from __future__ import annotations

import os
import struct

import numpy as np

from ..errors import ReaderError

__all__ = ["BinaryReader", "read_bytes", "check_count", "MAX_PIXELS"]

#: Refuse images larger than this many pixels outright (2^31 ≈ 2e9).
MAX_PIXELS = 1 << 31


def read_bytes(path, limit: int | None = None) -> bytes:
    """The file's bytes (all, or the first ``limit``); errors become :class:`ReaderError`."""
    try:
        with open(path, "rb") as f:
            return f.read() if limit is None else f.read(limit)
    except OSError as exc:
        raise ReaderError(path, _OS_ERRORS.get(type(exc)) or f"cannot be read: {exc}") from None


_OS_ERRORS = {IsADirectoryError: "is a directory, not a file", FileNotFoundError: "no such file",
              PermissionError: "permission denied"}


def check_count(path, count, itemsize: int, available: int, what: str = "data") -> int:
    """Check that ``count`` items of ``itemsize`` bytes fit into ``available`` bytes; return ``count``."""
    try:
        count = int(count)
    except (TypeError, ValueError, OverflowError):
        raise ReaderError(path, f"invalid size field for {what}: {count!r}") from None
    if count < 0 or count > MAX_PIXELS:
        raise ReaderError(path, f"implausible size field for {what}: {count}")
    if count * itemsize > available:
        raise ReaderError(path, f"{what} needs {count * itemsize} bytes but only {available} are in the file "
                                "(truncated or corrupt)")
    return count


class BinaryReader:
    """Bounds-checked reading from a bytes buffer of a named file.

    Parameters
    ----------
    data : bytes
        File content.
    path : str
        Used in error messages.
    endian : {"<", ">"}
        Default byte order for :meth:`unpack` and :meth:`array`.
    """

    def __init__(self, data: bytes, path, endian: str = "<"):
        self.data = data
        self.path = os.fspath(path) if path is not None else None
        self.endian = endian
        self.pos = 0

    @classmethod
    def from_file(cls, path, *, magic: bytes | tuple = b"", not_this: str = "", endian: str = "<") -> "BinaryReader":
        """Read ``path`` whole; raise ``not_this`` as a ReaderError unless it starts with ``magic`` (or one of them)."""
        reader = cls(read_bytes(path), path, endian)
        if magic and not reader.data.startswith(magic):
            raise reader.error(not_this or "unexpected file signature")
        return reader

    def __len__(self):
        return len(self.data)

    def error(self, message: str) -> ReaderError:
        return ReaderError(self.path, message)

    def seek(self, pos: int, what: str = "data") -> None:
        if not 0 <= pos <= len(self.data):
            raise self.error(f"{what} at offset {pos} lies outside the file ({len(self.data)} bytes)")
        self.pos = int(pos)

    def need(self, n: int, what: str = "data") -> None:
        if n < 0 or self.pos + n > len(self.data):
            raise self.error(f"truncated: {what} needs {n} bytes at offset {self.pos}, file has {len(self.data)}")

    def read(self, n: int, what: str = "data", at: int | None = None) -> bytes:
        if at is not None:
            self.seek(at, what)
        self.need(n, what)
        out = self.data[self.pos:self.pos + n]
        self.pos += n
        return out

    def unpack(self, fmt: str, what: str = "header field", at: int | None = None):
        if fmt[0] not in "<>=!@":
            fmt = self.endian + fmt
        size = struct.calcsize(fmt)
        vals = struct.unpack(fmt, self.read(size, what, at))
        return vals[0] if len(vals) == 1 else vals

    def array(self, dtype, count: int, what: str = "data", at: int | None = None) -> np.ndarray:
        """``count`` items of ``dtype`` (byte order from ``dtype`` or the reader) as a new array."""
        if at is not None:
            self.seek(at, what)
        dt = np.dtype(dtype)
        if dt.byteorder == "=" and dt.itemsize > 1:
            dt = dt.newbyteorder(self.endian)
        count = check_count(self.path, count, dt.itemsize, len(self.data) - self.pos, what)
        raw = self.read(count * dt.itemsize, what)
        return np.frombuffer(raw, dtype=dt, count=count).astype(dt.newbyteorder("="))
