"""Safe reading of zip archives from untrusted files (X3P, Keyence VK6/VK7, Sensofar PLUX).

Members are read only after their declared size has been checked against a limit and against
the compressed size (deflate cannot compress better than about 1032:1: a member claiming more
is a zip bomb), and decompression is capped at the declared size.
"""

from __future__ import annotations

import re
import zipfile

from ..errors import ReaderError

__all__ = ["open_zip", "read_member", "unsafe_name", "MAX_MEMBER", "MAX_RATIO"]

#: deflate cannot compress better than about 1032:1; a member claiming more is a bomb
MAX_RATIO = 1100
#: bytes decompressed per member
MAX_MEMBER = 1 << 30
_DRIVE = re.compile(r"^[A-Za-z]:")


def unsafe_name(name: str) -> bool:
    """True for a member name that is absolute or leaves the archive (path traversal)."""
    n = name.replace("\\", "/")
    return n.startswith("/") or bool(_DRIVE.match(n)) or ".." in n.split("/") or "\0" in n


def open_zip(path, what: str) -> zipfile.ZipFile:
    """The zip archive ``path`` (a :class:`ReaderError` naming ``what`` if it is none, or if a member
    name is unsafe)."""
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, zipfile.LargeZipFile, OSError, ValueError, EOFError) as exc:
        raise ReaderError(path, f"not a readable {what} (zip) archive: {exc}") from None
    bad = [n for n in zf.namelist() if unsafe_name(n)]
    if bad:
        zf.close()
        raise ReaderError(path, f"{what} archive member name {bad[0]!r} is absolute or leaves the archive "
                                "(path traversal); refused")
    return zf


def read_member(path, zf, info, what: str, expected: int | None = None, limit: int = MAX_MEMBER) -> bytes:
    """Bytes of the member ``info``, refusing bombs and size mismatches; decompression is capped.

    Parameters
    ----------
    path : str
        The archive (named in errors).
    zf : zipfile.ZipFile
        The open archive.
    info : zipfile.ZipInfo
        The member.
    what : str
        The format (``"X3P"``), named in errors.
    expected : int, optional
        The size the member must have (from a header).
    limit : int
        Largest size accepted (bytes).
    """
    declared = info.file_size
    if declared > limit:
        raise ReaderError(path, f"{what} member {info.filename!r} declares {declared} bytes, more than the "
                                f"{limit} accepted (zip bomb?)")
    if declared > max(MAX_RATIO * info.compress_size, 1 << 16):
        raise ReaderError(path, f"{what} member {info.filename!r} declares {declared} bytes from "
                                f"{info.compress_size} compressed bytes, an impossible ratio (zip bomb)")
    if expected is not None and declared != expected:
        raise ReaderError(path, f"{what} member {info.filename!r} has {declared} bytes but the header implies "
                                f"{expected}")
    cap = declared if expected is None else expected
    try:
        with zf.open(info) as f:
            data = f.read(cap + 1)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError, NotImplementedError) as exc:
        raise ReaderError(path, f"{what} member {info.filename!r} cannot be decompressed: {exc}") from None
    if len(data) != cap:
        raise ReaderError(path, f"{what} member {info.filename!r} decompresses to {len(data)} bytes, "
                                f"not the declared {cap}")
    return data
