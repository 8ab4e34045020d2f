"""A small bounds-checked TIFF parser for instrument files built on TIFF (Park, JPK, ...).

Only what those readers need: the image file directories (IFDs) with their tags,
tag values decoded by TIFF type, and uncompressed strip data.  Every offset and
count is checked against the file size (through :class:`~xtopo.io._binary.BinaryReader`)
before anything is allocated, and IFD chains are guarded against loops.

TIFF 6.0 layout: ``II*\\0`` (little-endian) or ``MM\\0*`` (big-endian), then the
offset of the first IFD.  An IFD is a 2-byte entry count, 12-byte entries
``(tag, type, count, value-or-offset)`` and the offset of the next IFD (0 ends
the chain).  A value is stored inline when it fits into 4 bytes.
"""

from __future__ import annotations

import struct

import numpy as np

from ..errors import ReaderError
from ._binary import BinaryReader, check_count

__all__ = ["TiffFile", "is_tiff", "head_tags", "MAX_IFDS"]

#: Refuse files with more directories than this (loops and corrupt chains).
MAX_IFDS = 4096

# TIFF type code -> (numpy dtype char, item size)
_TYPES = {1: ("u1", 1), 2: ("S1", 1), 3: ("u2", 2), 4: ("u4", 4), 5: ("u4", 8), 6: ("i1", 1), 7: ("u1", 1),
          8: ("i2", 2), 9: ("i4", 4), 10: ("i4", 8), 11: ("f4", 4), 12: ("f8", 8), 13: ("u4", 4),
          16: ("u8", 8), 17: ("i8", 8), 18: ("u8", 8)}


def is_tiff(head: bytes) -> bool:
    """True if ``head`` starts with a classic TIFF signature."""
    return head[:4] in (b"II*\x00", b"MM\x00*")


def head_tags(head: bytes) -> dict[int, tuple[int, int, bytes]]:
    """Tags of the first directory found in ``head`` (for sniffing): ``tag -> (type, count, 4 value bytes)``.

    Returns an empty dict when ``head`` is not a TIFF or the directory lies beyond it.
    """
    if not is_tiff(head):
        return {}
    e = "<" if head[:2] == b"II" else ">"
    try:
        (off,) = struct.unpack_from(e + "I", head, 4)
        (n,) = struct.unpack_from(e + "H", head, off)
        entries = (struct.unpack_from(e + "HHI4s", head, off + 2 + 12 * i) for i in range(n))
        return {tag: (typ, count, val) for tag, typ, count, val in entries}
    except struct.error:
        return {}


class TiffFile:
    """The directories of a TIFF file held in memory.

    Parameters
    ----------
    data : bytes
        The whole file.
    path : str
        For error messages.

    Attributes
    ----------
    ifds : list of dict
        One dict per directory: ``tag -> (type, count, offset)`` where ``offset`` is
        the absolute position of the value bytes.
    endian : {"<", ">"}
    """

    def __init__(self, data: bytes, path):
        if not is_tiff(data[:4]):
            raise ReaderError(path, "not a TIFF file (no II*/MM* signature)")
        self.path = path
        self.endian = "<" if data[:2] == b"II" else ">"
        self.reader = BinaryReader(data, path, self.endian)
        self.ifds: list[dict[int, tuple[int, int, int]]] = []
        pos = self.reader.unpack("I", "first IFD offset", at=4)
        seen = set()
        while pos:
            if pos in seen:
                raise ReaderError(path, f"TIFF directory chain loops back to offset {pos}")
            seen.add(pos)
            pos = self._directory(pos)

    def _directory(self, pos: int) -> int:
        """Add the directory at ``pos`` to :attr:`ifds`; return the offset of the next directory."""
        if len(self.ifds) >= MAX_IFDS:
            raise ReaderError(self.path, f"more than {MAX_IFDS} TIFF directories (corrupt chain)")
        r = self.reader
        n = r.unpack("H", "IFD entry count", at=pos)
        check_count(self.path, n, 12, len(r) - r.pos, "TIFF directory entries")
        tags = {}
        for i in range(n):
            base = pos + 2 + 12 * i
            tag, typ, count = r.unpack("HHI", "IFD entry", at=base)
            if typ not in _TYPES:
                continue  # unknown types are skipped, as TIFF readers must
            size = _TYPES[typ][1] * count
            if size <= 4:
                off = base + 8
            else:
                off = r.unpack("I", "IFD value offset", at=base + 8)
                if off + size > len(r):
                    # keep the entry; reading it raises a clear error if needed
                    off = -off - 1
            tags[tag] = (typ, count, off)
        self.ifds.append(tags)
        return r.unpack("I", "next IFD offset", at=pos + 2 + 12 * n)

    def sub_directory(self, pos: int) -> int:
        """Read the directory at ``pos`` that a tag points to (EXIF, GPS); its index for :meth:`value`."""
        self._directory(int(pos))
        return len(self.ifds) - 1

    def has(self, ifd: int, tag: int) -> bool:
        return tag in self.ifds[ifd]

    def raw(self, ifd: int, tag: int) -> bytes:
        """The value bytes of ``tag`` in directory ``ifd``."""
        typ, count, off = self.ifds[ifd][tag]
        if off < 0:
            raise ReaderError(self.path, f"TIFF tag {tag} points beyond the end of the file (truncated)")
        return self.reader.read(_TYPES[typ][1] * count, f"TIFF tag {tag}", at=off)

    def value(self, ifd: int, tag: int, default=None):
        """Decoded value of ``tag``: ``str`` for ASCII, a scalar for count 1, else a numpy array."""
        if tag not in self.ifds[ifd]:
            return default
        typ, count, off = self.ifds[ifd][tag]
        raw = self.raw(ifd, tag)
        if typ == 2:
            return raw.split(b"\0", 1)[0].decode("latin-1", errors="replace")
        vals = np.frombuffer(raw, dtype=np.dtype(_TYPES[typ][0]).newbyteorder(self.endian))
        if typ in (5, 10):  # rationals
            with np.errstate(divide="ignore", invalid="ignore"):
                vals = vals[0::2].astype(float) / np.where(vals[1::2] == 0, np.nan, vals[1::2])
        if count == 1:
            return vals[0].item()
        return vals.astype(vals.dtype.newbyteorder("="))

    def strips(self, ifd: int, dtype, shape: tuple[int, int], what: str = "image") -> np.ndarray:
        """The uncompressed image of directory ``ifd`` as an array of ``dtype`` and ``shape`` (rows, columns)."""
        compression = self.value(ifd, 259, 1)
        if compression != 1:
            raise ReaderError(self.path, f"compressed TIFF {what} (compression {compression}) is not supported")
        offsets, counts = (np.atleast_1d(self.value(ifd, tag, ())) for tag in (273, 279))  # () where absent
        if offsets.size != counts.size or offsets.size == 0:
            raise ReaderError(self.path, f"TIFF {what} has no valid strip offsets/byte counts")
        dt = np.dtype(dtype).newbyteorder(self.endian)
        ny, nx = shape
        n = check_count(self.path, int(ny) * int(nx), dt.itemsize, len(self.reader), what)
        need = n * dt.itemsize
        if int(np.sum(counts.astype(np.int64))) < need:
            raise ReaderError(self.path, f"TIFF {what} strips hold {int(np.sum(counts))} bytes, "
                                         f"{need} are needed")
        parts = []
        got = 0
        for off, cnt in zip(offsets.tolist(), counts.tolist()):
            take = min(int(cnt), need - got)
            if take <= 0:
                break
            parts.append(self.reader.read(take, f"TIFF {what} strip", at=int(off)))
            got += take
        buf = b"".join(parts)
        return np.frombuffer(buf, dtype=dt, count=n).astype(dt.newbyteorder("=")).reshape(ny, nx)
