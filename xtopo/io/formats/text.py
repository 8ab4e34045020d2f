"""Plain-text height data: matrices (optionally with a header) and two-column line scans.

Three formats share one parser:

``gwyddion-text``
    Gwyddion's ASCII matrix export with a comment header ``# Channel:``, ``# Width: 10.00 µm``,
    ``# Height: 10.00 µm``, ``# Value units: m``. ``Width`` is the physical size along ``x``
    (columns), ``Height`` along ``y`` (rows); values are in ``Value units``. Gwyddion translates
    the keys with its user interface (``# Breite:``, ``# Höhe:`` in German); the four lines come in
    a fixed order, so they are recognised by their place and form, in any language.
``dhm-text``
    ASCII matrix with the header ``h=<rows> w=<columns>``, ``pixel size=<Δ> m``,
    ``data unit=rad`` and ``height conversion factor (-> m)=<f>``: height = value × f metres
    (phase maps exported by digital holographic microscopes).
``text``
    Anything else that is a table of numbers (UTF-8, Latin-1 or UTF-16 with a byte-order mark;
    separated by blanks, tabs, commas or semicolons):

    * one column or one row → a uniform line scan;
    * two columns → a line scan ``(x, h)``: uniform if every ``x`` lies on one grid within the
      printed precision of the ``x`` column (:func:`~xtopo.io._text.uniform_spacing`), else
      ``grid="nonuniform"`` with the positions as printed;
    * three columns ``index, x, h`` (the first column counts the rows) → a line scan ``(x, h)``;
    * three columns ``x y z`` whose first two columns form a complete grid (written point by
      point, ``x`` or ``y`` varying fastest) → an areal map on that grid, its size from the
      coordinates (``N Δ``); x y z points that form no complete uniform grid (scattered points)
      are refused: interpolate them onto a grid first;
    * more columns → a matrix (rows are ``y``).

    Lines before the numbers (or starting with ``#``/``%``) are a header of ``key: value`` or
    ``key = value`` pairs; ``Width``/``Height``/``Value units`` are understood as in Gwyddion's
    export. A header line of length units only (``µm µm``, one per column) gives the unit of
    each column; column titles stating units (``x in µm``, ``X (nm)``, ``z [um]``) do too when
    every column used states one. A line holding a lone integer above a table of several columns (a count) is
    skipped. Size and units the file lacks come from ``physical_size=``/``file_units=``.
"""

from __future__ import annotations

import re

import numpy as np

from ...conventions import length_factor
from ...errors import OptionError, ReaderError
from .._generic import generic_measurement, single_channel
from .._text import (column_precision, header_value, is_number, looks_like_text, parse_quantity,
                     parse_table, read_text, uniform_spacing)
from ..registry import READ_OPTIONS, Format, register
from ._common import length_unit as unit_or_none

__all__ = ["read_text_measurement", "read_dhm", "split_header"]

_COMMENT = ("#", "%", "//")
_NUMBER_START = re.compile(r"^\s*[-+]?(?:\d|\.\d|nan\b|inf\b)", re.IGNORECASE)
#: names of the one channel of a text file (besides the index 0)
_CHANNEL_NAMES = ("0", "default", "Default")


def _is_data_line(line: str) -> bool:
    return bool(_NUMBER_START.match(line)) and all(is_number(t) for t in _fields(line))


def split_header(lines, path=None):
    """Split lines into ``(header dict, data lines, plain header lines)``.

    Header lines are the lines before the first all-numeric line, and any comment lines;
    ``key: value`` or ``key = value`` pairs are collected (keys stripped of comment marks);
    the other non-comment header lines (column titles, a unit line) are returned as they are.

    Raises
    ------
    ReaderError
        If the (non-comment) line just before the data has as many fields as a data row,
        most of them numbers (half of them if it starts with one, as ``0x10 1``): a corrupt first row,
        which must not silently become a header.
    """
    header = {}
    plain = []
    start = len(lines)
    previous = None  # the last non-comment header line
    for i, line in enumerate(lines):
        s = line.strip()
        if not s:
            continue
        comment = s.startswith(_COMMENT)
        if comment:
            s = s.lstrip("#%/ \t")
        elif _is_data_line(s):
            start = i
            break
        else:
            previous = s
        m = re.match(r"^([^:=]{1,80}?)\s*[:=]\s*(.*)$", s)
        if m:
            header.setdefault(m.group(1).strip(), m.group(2).strip())
        elif not comment:
            plain.append(s)
    data = [ln for ln in lines[start:] if ln.strip() and not ln.lstrip().startswith(_COMMENT)]
    if previous is not None and data:
        fields = _fields(previous)
        numbers = sum(is_number(t) for t in fields)
        numeric = numbers > len(fields) / 2 or (_NUMBER_START.match(previous) and numbers >= len(fields) / 2)
        if len(fields) == len(_fields(data[0])) and numeric:
            bad = next(t for t in fields if not is_number(t))
            raise ReaderError(path, f"the first data row contains a token that is not a number: {bad[:40]!r} "
                                    "(corrupt row)")
    return header, data, plain


def _fields(line: str) -> list:
    return [t for t in re.split(r"[\s,;]+", line.strip()) if t]


def _separator(line: str):
    if ";" in line:
        return ";"
    if "," in line and "." in line or line.count(",") >= 1 and " " not in line.strip():
        return ","
    return None  # blanks or tabs


#: Gwyddion's export keys as its translations spell them (its cs, de, es, fr, it, ko, ru catalogues; ja, pt as
#: SurfaceTopography's text reader lists them).
_GWYDDION_KEYS = {
    "Channel": ("channel", "kanál", "kanal", "canal", "canale", "チャネル", "채널", "канал"),
    "Width": ("width", "šířka", "breite", "anchura", "largeur", "larghezza", "幅", "폭", "largura", "ширина"),
    "Height": ("height", "výška", "höhe", "altura", "hauteur", "altezza", "高さ", "높이", "высота"),
    "Value units": ("value units", "jednotky hodnot", "einheiten", "unités", "unità valore", "値の単位", "값 단위",
                    "unidades de valor", "единицы измерения"),
}
_GWYDDION_LOOKUP = {k: canonical for canonical, keys in _GWYDDION_KEYS.items() for k in keys}
_COMMENT_PAIR = re.compile(r"^\s*#\s*([^:：]{1,40}?)\s*[:：]\s*(.*?)\s*$")  # Japanese: a full-width colon
#: a unit stated in a column title: "x in µm", "X_(microns)", "z [nm]", "Height (um)"
_TITLE_UNIT = re.compile(r"(?:\bin\s+|[\[(])\s*([^\[\]()\s]+)\s*[\])]?\s*$")


def _gwyddion_header(lines) -> dict:
    """The four header lines of a Gwyddion ASCII export under their English keys, in any language.

    Gwyddion writes ``# <Channel>: name``, ``# <Width>: value unit``, ``# <Height>: value unit`` and
    ``# <Value units>: unit`` in this order, the keys translated: a translated key is recognised by
    its catalogue spelling, an unknown translation by the place and form of its line.
    """
    pairs = [_COMMENT_PAIR.match(line) for line in lines[:4]]
    if len(pairs) < 4 or not all(pairs) or not all(_is_quantity(m.group(2)) for m in pairs[1:3]):
        return {}
    return {_GWYDDION_LOOKUP.get(m.group(1).lower(), canonical): m.group(2)
            for m, canonical in zip(pairs, _GWYDDION_KEYS)}


def _is_quantity(text: str) -> bool:
    fields = text.split()
    return len(fields) == 2 and is_number(fields[0]) and unit_or_none(fields[1]) is not None


def _column_units(path, plain, ncols):
    """Units of the table's columns from a unit line (``µm µm``) or column titles (``x in µm``), else None."""
    for line in reversed(plain):
        fields = _fields(line)
        if len(fields) == ncols and all(unit_or_none(f) for f in fields):
            return [unit_or_none(f) for f in fields]
        titles = [t.strip() for t in re.split(r"[,;\t]", line) if t.strip()] if re.search(r"[,;\t]", line) \
            else fields
        if len(titles) == ncols:
            found = [_TITLE_UNIT.search(t) for t in titles]
            units = [unit_or_none(m.group(1)) if m else None for m in found]
            return units if any(units) else None
    return None


def _drop_count_line(data):
    """Data lines without a first line that holds a lone integer above a table of several columns (a count
    or a record number some exports write, ``23``)."""
    if len(data) > 2 and data[0].strip().isdigit() and len(_fields(data[1])) > 1:
        return data[1:]
    return data


def read_text_measurement(path, *, channel=None, physical_size=None, file_units=None, height_units=None):
    """Read a ``text``/``gwyddion-text`` file (see the module docstring)."""
    single_channel(path, channel, _CHANNEL_NAMES)
    lines = read_text(path).splitlines()
    header, data, plain = split_header(lines, path)
    header.update(_gwyddion_header(lines))
    data = _drop_count_line(data)
    if not data:
        raise ReaderError(path, "contains no table of numbers")
    sep = _separator(data[0])
    table = parse_table(path, data, sep=sep)
    found_units, found_hu = None, header.get("Value units", "").strip() or None
    sizes = {}
    for key, dim in (("Width", "x"), ("Height", "y")):
        if key in header:
            val, unit = parse_quantity(path, header[key], f"header field {key!r}")
            sizes[dim] = val
            if unit is not None:
                found_units = found_units or unit
                if unit != found_units:  # convert to the first unit found
                    sizes[dim] = val * length_factor(unit, found_units)
    attrs = {"channel": header.get("Channel")} if header.get("Channel") else {}
    nrows, ncols = table.shape
    units = _column_units(path, plain, ncols) if ncols in (2, 3) and not sizes else None
    if units and units[-2] and units[-1] and found_units is None and found_hu is None:
        found_units, found_hu = units[-2], units[-1]  # the x column (x h, index x h, x y z) and the heights
    common = dict(physical_size=physical_size, file_units=file_units, height_units=height_units,
                  found_units=found_units, found_height_units=found_hu, **attrs)
    if ncols in (2, 3) and nrows > 2 and not sizes:
        xcol = _positions(path, table, data, sep, common)
        if xcol is not None:
            return xcol
    if nrows == 1 or ncols == 1:
        return generic_measurement(path, table.ravel(), found_size=sizes.get("x"), **common)
    found_size = (sizes["y"], sizes["x"]) if "x" in sizes and "y" in sizes else None
    return generic_measurement(path, table, found_size=found_size, **common)


def _tokens(data, sep, column):
    return [(ln.split(sep) if sep else ln.split())[column] for ln in data]


def _positions(path, table, data, sep, common):
    """The measurement of a table whose columns hold positions: ``x h``, ``index x h`` or ``x y z``.

    ``None`` where three columns are no such table and were given a ``physical_size`` (a height
    matrix three pixels wide).
    """
    nrows, ncols = table.shape
    if ncols == 2:
        return generic_measurement(path, table[:, 1], x=table[:, 0], precision=column_precision(_tokens(data, sep, 0)),
                                   **common)
    first, second = table[:, 0], table[:, 1]
    if np.array_equal(first, first[0] + np.arange(nrows)) and np.all(np.diff(second) > 0):  # index, x, h
        return generic_measurement(path, table[:, 2], x=second, precision=column_precision(_tokens(data, sep, 1)),
                                   **common)
    grid = _xyz_grid(path, table, data, sep)
    if grid is None:
        if common["physical_size"] is not None:
            return None
        nx, ny = np.unique(first).size, np.unique(second).size
        raise ReaderError(path, f"three columns read as x y z points: {nrows} points with {nx} distinct x and "
                                f"{ny} distinct y do not form a complete grid (scattered points); interpolate "
                                "them onto a uniform grid first. If the columns are a height matrix three pixels "
                                "wide, pass physical_size=(Ly, Lx)")
    if common["physical_size"] is not None:
        raise OptionError(path, "the file stores x y z positions on a grid; do not pass physical_size")
    heights, size = grid
    return generic_measurement(path, heights, found_size=size, **common)


def _xyz_grid(path, table, data, sep):
    """``(heights (ny, nx), (Ly, Lx))`` when the x y z points of ``table`` form a complete uniform grid, else None.

    Raises
    ------
    ReaderError
        For a complete grid whose x or y positions are not equally spaced.
    """
    n = table.shape[0]
    ux, ix = np.unique(table[:, 0], return_inverse=True)
    uy, iy = np.unique(table[:, 1], return_inverse=True)
    if ux.size < 2 or uy.size < 2 or ux.size * uy.size != n:
        return None
    cell = iy.ravel() * ux.size + ix.ravel()
    if np.unique(cell).size != n:
        return None
    steps = []
    for axis, u in (("x", ux), ("y", uy)):
        d = uniform_spacing(u, column_precision(_tokens(data, sep, 0 if axis == "x" else 1)))
        if d is None:
            raise ReaderError(path, f"the x y z points form a grid whose {axis} positions are not equally spaced; "
                                    "xtopo reads areal maps on uniform grids only")
        steps.append(d)
    heights = np.empty(n)
    heights[cell] = table[:, 2]
    return heights.reshape(uy.size, ux.size), (uy.size * steps[1], ux.size * steps[0])


def read_dhm(path, *, channel=None):
    """Read a ``dhm-text`` matrix (``h= w=`` header; height = value × conversion factor, in m)."""
    single_channel(path, channel, _CHANNEL_NAMES)
    lines = read_text(path).splitlines()
    m = re.match(r"^\s*h\s*=\s*(\d+)\s+w\s*=\s*(\d+)\s*$", lines[0] if lines else "")
    if not m:
        raise ReaderError(path, "first line is not 'h=<rows> w=<columns>'")
    ny, nx = int(m.group(1)), int(m.group(2))
    header, data, _ = split_header(lines[1:], path)
    pixel, punit = parse_quantity(path, header.get("pixel size", ""), "header field 'pixel size'")
    factor_key = next((k for k in header if k.lower().startswith("height conversion factor")), None)
    if factor_key is None:
        raise ReaderError(path, "header field 'height conversion factor (-> m)' is missing")
    factor = header_value(path, header, factor_key)
    unit_m = re.search(r"->\s*([^)\s]+)", factor_key)
    hu = unit_m.group(1) if unit_m else "m"
    if len(data) != ny:
        raise ReaderError(path, f"header says h={ny} rows but the file has {len(data)} data rows")
    table = parse_table(path, data, ncols=nx)
    if pixel <= 0:
        raise ReaderError(path, f"pixel size must be positive, got {pixel}")
    return generic_measurement(path, table, found_size=(ny * pixel, nx * pixel), found_units=punit or "m",
                               found_height_units=hu, height_scale=factor,
                               data_unit=header.get("data unit"), height_conversion_factor=factor)


def _sniff_gwyddion(head: bytes, path: str) -> bool:
    if not (looks_like_text(head) and head.lstrip().startswith(b"#")):
        return False
    text = head[:1024].decode("utf-8", errors="replace")
    return (("# Width:" in text and "# Height:" in text)
            or bool(_gwyddion_header(text.lstrip().splitlines())))


def _sniff_dhm(head: bytes, path: str) -> bool:
    return looks_like_text(head) and re.match(rb"^\s*h\s*=\s*\d+\s+w\s*=\s*\d+\s*\r?\n", head) is not None


register(Format("gwyddion-text", "Gwyddion ASCII matrix export (# Width/Height/Value units header)",
                (".txt", ".asc"), _sniff_gwyddion, read_text_measurement, priority=5, options=READ_OPTIONS))
register(Format("dhm-text", "ASCII matrix with h=/w=, pixel size and height conversion factor header (DHM)",
                (".txt",), _sniff_dhm, read_dhm, priority=5))
register(Format("text", "plain-text matrix or (x, height) columns, optional key: value header",
                (".txt", ".asc", ".dat", ".csv", ".xyz"), lambda head, path: looks_like_text(head),
                read_text_measurement, priority=-10, options=READ_OPTIONS))
