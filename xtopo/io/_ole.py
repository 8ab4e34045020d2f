"""A small, bounds-checked reader for OLE / Compound File Binary files ([MS-CFB]).

Only what reading measurement files needs: list the directory and read a
stream by name.  Every sector number, chain and size is checked against the
file, sector chains are followed with loop detection, so corrupt or hostile
files give a :class:`~xtopo.errors.ReaderError` instead of a hang or a huge
allocation.

Layout: a 512-byte header (signature ``D0 CF 11 E0 A1 B1 1A E1``, sector shift
at 30, mini sector shift at 32, number of FAT sectors at 44, first directory
sector at 48, mini stream cutoff at 56, first mini FAT sector at 60, number of
mini FAT sectors at 64, first DIFAT sector at 68, number of DIFAT sectors at 72,
the first 109 DIFAT entries at 76).  Sector ``n`` starts at ``(n + 1) * sector_size``.
The FAT maps each sector to the next one of its chain (``0xFFFFFFFE`` ends a
chain).  Directory entries are 128 bytes: UTF-16 name[64], name length (bytes,
uint16) at 64, type (1 storage, 2 stream, 5 root) at 66, start sector at 116,
size (uint64) at 120.  Streams shorter than the cutoff live in the mini stream
(the root entry's chain) in 64-byte mini sectors mapped by the mini FAT.
"""

from __future__ import annotations

import struct

import numpy as np

from ..errors import ReaderError
from ._binary import read_bytes

__all__ = ["OLE_MAGIC", "OleFile"]

OLE_MAGIC = b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1"
_END = 0xFFFFFFFE
_MAX_REGULAR = 0xFFFFFFFA


class OleFile:
    """A parsed compound file.

    Parameters
    ----------
    path : str
        The file (read whole; named in error messages).
    data : bytes, optional
        The file's content, if already read.
    """

    def __init__(self, path, data: bytes | None = None):
        self.path = path
        self.data = read_bytes(path) if data is None else data
        d = self.data
        if len(d) < 512 or d[:8] != OLE_MAGIC:
            raise self._err("not an OLE compound file (signature missing)")
        shift, mshift = struct.unpack_from("<HH", d, 30)
        if shift not in (9, 12) or mshift != 6:
            raise self._err(f"unsupported OLE sector shifts {shift}/{mshift}")
        self.sector_size = 1 << shift
        self.mini_size = 1 << mshift
        (nfat, self._dir_start, _tx, self.cutoff, mfat_start, nmfat,
         difat_start, ndifat) = struct.unpack_from("<8I", d, 44)
        self.nsectors = max(0, (len(d) - self.sector_size) // self.sector_size)
        if nfat > self.nsectors + 1 or nmfat > self.nsectors + 1 or ndifat > self.nsectors + 1:
            raise self._err("OLE header sector counts exceed the file size")
        fat_sectors = [s for s in struct.unpack_from("<109I", d, 76) if s <= _MAX_REGULAR]
        sec, seen = difat_start, set()
        per = self.sector_size // 4 - 1
        while sec <= _MAX_REGULAR and len(fat_sectors) < nfat:
            if sec in seen:
                raise self._err("loop in the OLE DIFAT chain")
            seen.add(sec)
            vals = struct.unpack_from(f"<{per + 1}I", self._sector(sec))
            fat_sectors.extend(v for v in vals[:per] if v <= _MAX_REGULAR)
            sec = vals[per]
        fat_sectors = fat_sectors[:nfat]
        self.fat = np.frombuffer(b"".join(self._sector(s) for s in fat_sectors), "<u4")
        dir_bytes = self._chain_bytes(self._dir_start, self.fat, self.sector_size, self._sector)
        self.entries = []
        for off in range(0, len(dir_bytes) - 127, 128):
            raw = dir_bytes[off:off + 128]
            nlen, typ = struct.unpack_from("<HB", raw, 64)
            if typ == 0:
                continue
            name = raw[:max(0, min(nlen, 64) - 2)].decode("utf-16-le", errors="replace")
            start, size = struct.unpack_from("<IQ", raw, 116)
            if self.sector_size == 512:
                size &= 0xFFFFFFFF
            self.entries.append({"name": name, "type": typ, "start": start, "size": size})
        roots = [e for e in self.entries if e["type"] == 5]
        if not roots:
            raise self._err("OLE file has no root directory entry")
        self._root = roots[0]
        self.minifat = np.frombuffer(self._chain_bytes(mfat_start, self.fat, self.sector_size, self._sector)
                                     if nmfat else b"", "<u4")
        self._ministream = None

    def _err(self, message):
        return ReaderError(self.path, message)

    def _sector(self, n: int) -> bytes:
        start = (int(n) + 1) * self.sector_size
        if n > _MAX_REGULAR or start + self.sector_size > len(self.data):
            raise self._err(f"OLE sector {n} lies outside the file")
        return self.data[start:start + self.sector_size]

    def _chain_bytes(self, start, fat, unit, fetch, size=None) -> bytes:
        limit = len(fat)
        if size is not None and size > (limit + 1) * unit:
            raise self._err(f"OLE stream of {size} bytes is larger than its allocation table allows")
        parts, sec, seen = [], int(start), 0
        while sec != _END:
            if sec >= limit or seen > limit:
                raise self._err(f"broken or looping OLE sector chain (sector {sec})")
            parts.append(fetch(sec))
            seen += 1
            if size is not None and seen * unit >= size:
                break
            sec = int(fat[sec])
        out = b"".join(parts)
        if size is not None:
            if len(out) < size:
                raise self._err(f"OLE stream truncated: {len(out)} of {size} bytes")
            out = out[:size]
        return out

    def _mini_sector(self, n: int) -> bytes:
        start = int(n) * self.mini_size
        if start + self.mini_size > len(self._ministream):
            raise self._err(f"OLE mini sector {n} lies outside the mini stream")
        return self._ministream[start:start + self.mini_size]

    def listdir(self) -> list[str]:
        """Names of all streams."""
        return [e["name"] for e in self.entries if e["type"] == 2]

    def exists(self, name: str) -> bool:
        return name in self.listdir()

    def read_stream(self, name: str) -> bytes:
        """Content of the stream ``name`` (first match in the directory)."""
        entry = next((e for e in self.entries if e["type"] == 2 and e["name"] == name), None)
        if entry is None:
            raise self._err(f"OLE file has no stream {name!r}")
        size = entry["size"]
        if size > len(self.data):
            raise self._err(f"OLE stream {name!r} declares {size} bytes, more than the whole file")
        if size < self.cutoff:
            if self._ministream is None:
                self._ministream = self._chain_bytes(self._root["start"], self.fat, self.sector_size,
                                                     self._sector, self._root["size"])
            return self._chain_bytes(entry["start"], self.minifat, self.mini_size, self._mini_sector, size)
        return self._chain_bytes(entry["start"], self.fat, self.sector_size, self._sector, size)
