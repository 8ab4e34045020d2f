"""Semicolon-separated line scans with a unit row and a validity column (``.hfm``).

Layout::

    X;Y;valid
    [mm];[mm];[1/0]
    8.672200;106.606853;1
    ...

``X`` is the position, ``Y`` the height, ``valid`` is 1 for measured and 0 for missing
points (stored as ``mask``). Units come from the bracketed second row.
"""

from __future__ import annotations

import re

import numpy as np

from ...conventions import length_factor
from ...errors import ReaderError
from .._generic import single_channel
from .._text import column_precision, length_unit, line_measurement, looks_like_text, parse_table, read_text
from ..registry import Format, register

__all__ = ["read_hfm"]

_UNIT_ROW = re.compile(rb"^\s*\[[^\]\r\n]*\](\s*;\s*\[[^\]\r\n]*\])+\s*$")


def read_hfm(path, *, channel=None):
    """Read an ``X;Y;valid`` semicolon CSV line scan (see the module docstring)."""
    single_channel(path, channel)
    lines = read_text(path).splitlines()
    if len(lines) < 4:
        raise ReaderError(path, "too short: needs a name row, a unit row and at least 2 data rows")
    names = [n.strip() for n in lines[0].split(";")]
    units = [u.strip().strip("[]").strip() for u in lines[1].split(";")]
    if len(names) < 2 or len(units) != len(names):
        raise ReaderError(path, f"name row {lines[0][:60]!r} and unit row {lines[1][:60]!r} do not match")
    table = parse_table(path, lines[2:], sep=";", ncols=len(names), what="data")
    xu = length_unit(path, units[0], f"unit of column {names[0]!r}")
    hu = length_unit(path, units[1], f"unit of column {names[1]!r}")
    mask = None
    lower = [n.lower() for n in names]
    if "valid" in lower:
        v = table[:, lower.index("valid")]
        if not np.all((v == 0) | (v == 1)):
            raise ReaderError(path, "the 'valid' column must contain only 0 and 1")
        mask = v == 0
    precision = column_precision(ln.split(";", 1)[0] for ln in lines[2:] if ln.strip())
    return line_measurement(path, table[:, 0], table[:, 1] * length_factor(hu, xu), xu, precision=precision,
                            mask=mask, columns=";".join(names))


def _sniff(head: bytes, path: str) -> bool:
    if not looks_like_text(head):
        return False
    lines = head.splitlines()
    return (len(lines) >= 3 and b";" in lines[0] and re.match(rb"^[A-Za-z_ ;]+$", lines[0].strip()) is not None
            and _UNIT_ROW.match(lines[1]) is not None)


register(Format("hfm", "semicolon CSV line scan with [unit] row and validity column (HFM)", (".hfm", ".csv"),
                _sniff, read_hfm, priority=10))
