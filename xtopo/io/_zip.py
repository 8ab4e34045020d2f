"""Reading members of untrusted ZIP archives (X3P, Keyence VK6/VK7/ZON, Sensofar PLUX, Olympus POIR files,
contact.engineering containers).

A member's declared size is checked before anything is decompressed: against a limit, and
against its compressed size (deflate cannot compress better than about 1032:1, so a member
claiming more is a zip bomb). Decompression is capped at the declared size, and a member that
decompresses to a different size is refused. Member names that are absolute or climb out of the
archive (``..``) are refused before they are used.
"""

from __future__ import annotations

import re
import zipfile
import zlib

from ..errors import ReaderError

__all__ = ["MAX_RATIO", "MAX_MEMBER", "MAX_METADATA", "unsafe_name", "open_zip", "check_declared", "read_member",
           "copy_member"]

#: deflate cannot compress better than about 1032:1; a member claiming more is a bomb
MAX_RATIO = 1100
#: bytes decompressed per member at most
MAX_MEMBER = 1 << 30
#: metadata members (XML, JSON, YAML) larger than this are refused (the largest real ones are a few kB)
MAX_METADATA = 16 << 20
_DRIVE = re.compile(r"^[A-Za-z]:")
_BLOCK = 1 << 20
#: what decompressing a damaged member raises (a bad CRC, a truncated or invalid stream)
_CORRUPT = (zipfile.BadZipFile, zlib.error, OSError, ValueError, EOFError, NotImplementedError, RuntimeError)


def unsafe_name(name: str) -> bool:
    """True for a member name that is absolute, names a drive, climbs out (``..``) or holds a NUL."""
    n = name.replace("\\", "/")
    return n.startswith("/") or bool(_DRIVE.match(n)) or ".." in n.split("/") or "\0" in n


def open_zip(path, what: str) -> zipfile.ZipFile:
    """The zip archive ``path``; a :class:`ReaderError` naming ``what`` if it is none, or if a member name is
    unsafe."""
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


def check_declared(path, info, what: str, limit: int = MAX_MEMBER) -> int:
    """The declared size of member ``info``, refused when above ``limit`` or an impossible ratio."""
    declared = info.file_size
    if declared > limit:
        raise ReaderError(path, f"{what} member {info.filename!r} declares {declared} bytes, more than the "
                                f"{limit} accepted (zip bomb?)")
    if declared > max(MAX_RATIO * info.compress_size, 1 << 16):
        raise ReaderError(path, f"{what} member {info.filename!r} declares {declared} bytes from "
                                f"{info.compress_size} compressed bytes, an impossible ratio (zip bomb)")
    return declared


def read_member(path, zf, info, what: str, expected: int | None = None, limit: int = MAX_MEMBER,
                expected_from: str = "the metadata") -> bytes:
    """Bytes of member ``info`` of the open archive ``zf``, refusing bombs and size mismatches.

    ``expected``: the size that ``expected_from`` (the archive's metadata) implies; a member that
    declares another size is refused.
    """
    declared = check_declared(path, info, what, limit)
    if expected is not None and declared != expected:
        raise ReaderError(path, f"{what} member {info.filename!r} has {declared} bytes but {expected_from} "
                                f"implies {expected}")
    try:
        with zf.open(info) as f:
            data = f.read(declared + 1)
    except _CORRUPT as exc:
        raise ReaderError(path, f"{what} member {info.filename!r} is corrupt: {exc}") from None
    if len(data) != declared:
        raise ReaderError(path, f"{what} member {info.filename!r} decompresses to {len(data)} bytes, "
                                f"not the declared {declared}")
    return data


def copy_member(path, zf, info, target: str, what: str) -> None:
    """Decompress member ``info`` into the new file ``target`` in blocks (capped at its declared size)."""
    declared = check_declared(path, info, what)
    written = 0
    with open(target, "xb") as dst:
        try:
            with zf.open(info) as src:
                while written <= declared:
                    block = src.read(min(_BLOCK, declared + 1 - written))
                    if not block:
                        break
                    dst.write(block)
                    written += len(block)
        except _CORRUPT as exc:
            raise ReaderError(path, f"{what} member {info.filename!r} is corrupt: {exc}") from None
    if written != declared:
        more = "more than " if written > declared else ""
        raise ReaderError(path, f"{what} member {info.filename!r} decompresses to {more}{written} bytes, not the "
                                f"declared {declared}")
