"""Bruker Dektak stylus profilometer CSV export.

The file is a list of sections (``Scan Parameters``, ``Analytical Results``, ``Scan Data``)
of comma-separated ``key,value`` lines, written in Latin-1 (``µ`` as byte 0xB5). The
``Scan Data`` section starts with a column header such as ``Lateral um,Raw Micrometer``
naming the unit of each column, followed by ``position,height`` rows. Positions are printed
with a fixed number of decimals; the grid is uniform when they match ``x_0 + m Δ`` to that
precision. The stylus radius (``Stylus,Radius: 2.5 µm``) becomes ``tip_radius``.
"""

from __future__ import annotations

import re

from ...conventions import length_factor
from ...errors import ReaderError
from .._generic import single_channel
from .._text import (column_precision, length_unit, line_measurement, looks_like_text, parse_quantity, parse_table,
                     read_text)
from ..registry import Format, register

__all__ = ["read_dektak"]

_SECTIONS = ("Scan Parameters", "Analytical Results", "Scan Data")


def _column_unit(path, name: str) -> str:
    """Unit word of a column title (``"Lateral um"`` → ``"um"``, ``"Raw Micrometer"`` → ``"um"``)."""
    word = name.strip().split()[-1] if name.strip() else ""
    for cand in (word, word.lower()):
        try:
            return length_unit(path, cand, f"column {name!r}")
        except ReaderError:
            continue
    raise ReaderError(path, f"column title {name!r} does not end with a length unit")


def _check_length(path, params, x, xu):
    """Refuse scan data covering clearly less than the stated scan ``Length`` (a truncated file)."""
    m = re.match(r"^\s*([-+]?[\d.]+(?:[eE][-+]?\d+)?\s*\S*)", params.get("Length", ""))
    if not m or x.size < 2:
        return
    try:
        length, lu = parse_quantity(path, m.group(1), "scan length")
    except ReaderError:
        return
    length *= length_factor(lu or xu, xu)
    covered = (x[-1] - x[0]) * x.size / (x.size - 1)
    if length > 0 and covered < 0.99 * length:
        raise ReaderError(path, f"the scan data cover {covered:.6g} {xu} of the {length:.6g} {xu} scan length "
                                f"({x.size} points; truncated file?)")


def read_dektak(path, *, channel=None):
    """Read a Dektak CSV export into a line scan (see the module docstring)."""
    single_channel(path, channel)
    lines = [ln.strip() for ln in read_text(path).splitlines()]
    try:
        start = lines.index("Scan Data")
    except ValueError:
        raise ReaderError(path, "no 'Scan Data' section") from None
    params = {}
    for ln in lines[:start]:
        key, _, value = ln.partition(",")
        if value and key not in _SECTIONS:
            params.setdefault(key.strip(), value.strip())
    rest = [ln for ln in lines[start + 1:] if ln]  # Dektak ends section titles with "\r\r\n"
    titles = [t for t in (rest[0].split(",") if rest else []) if t.strip()]
    if len(titles) < 2:
        raise ReaderError(path, "the 'Scan Data' section has no 'position,height' column header")
    xu, hu = _column_unit(path, titles[0]), _column_unit(path, titles[1])
    data = rest[1:]
    if len(data) < 2:
        raise ReaderError(path, "the 'Scan Data' section has fewer than 2 rows")
    table = parse_table(path, data, sep=",", what="scan data")
    if table.shape[1] < 2:
        raise ReaderError(path, "scan data need two columns (position, height)")
    _check_length(path, params, table[:, 0], xu)
    precision = column_precision(ln.split(",", 1)[0] for ln in data)
    attrs = {"instrument": "Bruker Dektak stylus profilometer", "vendor": "Bruker"}
    m = re.search(r"Radius:\s*(.+)$", params.get("Stylus", ""))
    if m:
        r, ru = parse_quantity(path, m.group(1), "stylus radius")
        if r > 0:
            attrs["tip_radius"] = r * length_factor(ru or xu, xu)
    for key in ("Scan Type", "Length", "Duration", "Resolution", "Force", "Profile"):
        if key in params:
            attrs[f"dektak_{key.lower().replace(' ', '_')}"] = params[key]
    return line_measurement(path, table[:, 0], table[:, 1] * length_factor(hu, xu), xu, precision=precision, **attrs)


def _sniff(head: bytes, path: str) -> bool:
    return looks_like_text(head) and head.lstrip().startswith(b"Scan Parameters") or (
        looks_like_text(head) and b"\nScan Data" in head and b"Lateral" in head)


register(Format("dektak-csv", "Bruker Dektak stylus profilometer CSV export", (".csv",), _sniff, read_dektak,
                priority=10))
