"""A bounded reading of a NetCDF-3 header (classic and 64-bit offset), before a library sees the file.

scipy's ``netcdf_file`` trusts the header: a count or a dimension length claiming billions
allocated that much (a 530 KB file took 1.8 GB before it was refused; a dimension count of
2**31 crashed the interpreter). :func:`check_netcdf3_header` walks the header as the format
specification lays it out (Unidata, "The NetCDF Classic Format Specification") and refuses the
file unless every list fits in the bytes that remain and every variable's data lies inside
the file, so what a reader then allocates is bounded by the file's size.
"""

from __future__ import annotations

import math
import os

from ..errors import ReaderError

__all__ = ["check_netcdf3_header"]

_DIMENSION, _VARIABLE, _ATTRIBUTE = 0x0A, 0x0B, 0x0C
#: bytes per value of each nc_type (byte, char, short, int, float, double)
_SIZES = {1: 1, 2: 1, 3: 2, 4: 4, 5: 4, 6: 8}
_STREAMING = 0xFFFFFFFF


class _Header:
    def __init__(self, path, data: bytes, file_size: int):
        self.path, self.data, self.pos, self.file_size = path, data, 0, file_size

    def fail(self, what: str):
        raise ReaderError(self.path, f"damaged NetCDF-3 header: {what} (the file holds {self.file_size} bytes)")

    def uint(self, size: int = 4) -> int:
        if self.pos + size > len(self.data):
            self.fail("it ends inside the header")
        value = int.from_bytes(self.data[self.pos:self.pos + size], "big")
        self.pos += size
        return value

    def count(self, what: str, min_bytes: int, tag: int | None = None) -> int:
        """A list length, refused when its entries (``min_bytes`` each, at least) cannot fit in the file.

        ``tag``: the list is tagged (dimensions, attributes, variables): a tag and a length, both 0 when absent.
        """
        found = None if tag is None else self.uint()
        n = self.uint()
        if found is not None and (found, n) == (0, 0):
            return 0
        if found != tag or n > 0x7FFFFFFF or n * min_bytes > len(self.data) - self.pos:
            self.fail(f"{what} (tag {found:#x}) claims {n} entries" if tag else f"{what} claims {n} entries")
        return n

    def skip(self, n: int, what: str) -> None:
        padded = (n + 3) // 4 * 4
        if self.pos + padded > len(self.data):
            self.fail(f"{what} of {n} bytes runs past the end of the file")
        self.pos += padded

    def name(self) -> None:
        self.skip(self.count("a name", 1), "a name")

    def attributes(self) -> None:
        for _ in range(self.count("an attribute list", 12, _ATTRIBUTE)):
            self.name()
            size = _SIZES.get(self.uint())
            if size is None:
                self.fail("an attribute has an unknown type")
            self.skip(self.count("an attribute", size) * size, "an attribute")


def check_netcdf3_header(path) -> None:
    """Raise :class:`~xtopo.errors.ReaderError` unless ``path``'s NetCDF-3 header is consistent with its size.

    Checks every list count and name length against the bytes left, dimension ids against the
    dimensions, and each variable's extent (``begin`` + its size, record variables times the number
    of records) against the file size. Reads at most the file's size (a header is a few kB).
    """
    file_size = os.path.getsize(path)
    with open(path, "rb") as f:
        data = f.read(min(file_size, 1 << 24))  # headers beyond 16 MB are refused below as running past the end
    h = _Header(path, data, file_size)
    magic = h.uint()
    version = magic & 0xFF
    if magic >> 8 != 0x434446 or version not in (1, 2):
        h.fail("no CDF-1/CDF-2 signature")
    numrecs = h.uint()
    dims = []
    for _ in range(h.count("the dimension list", 8, _DIMENSION)):
        h.name()
        dims.append(h.uint())
    h.attributes()
    record_bytes = 0
    records = []
    for _ in range(h.count("the variable list", 24, _VARIABLE)):
        h.name()
        ids = [h.uint() for _ in range(h.count("a variable's dimensions", 4))]
        if any(i >= len(dims) for i in ids):
            h.fail("a variable names a dimension that does not exist")
        h.attributes()
        size = _SIZES.get(h.uint())
        if size is None:
            h.fail("a variable has an unknown type")
        h.uint()  # vsize: recomputed below (it wraps for variables over 4 GiB)
        begin = h.uint(4 if version == 1 else 8)
        shape = [dims[i] for i in ids]
        is_record = bool(shape) and shape[0] == 0
        n = size * math.prod(shape[1:] if is_record else shape)
        if begin > file_size:
            h.fail(f"a variable's data begin at byte {begin}")
        if is_record:
            record_bytes += n
            records.append(begin)
        elif begin + n > file_size:
            h.fail(f"a variable of {n} bytes at byte {begin} runs past the end")
    if records and numrecs != _STREAMING and min(records) + numrecs * record_bytes > file_size:
        h.fail(f"{numrecs} records of {record_bytes} bytes run past the end")
