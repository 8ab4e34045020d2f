"""Plain-text height data: matrices (optionally with a header) and two-column line scans.

Three formats share one parser:

``gwyddion-text``
    Gwyddion's ASCII matrix export with a comment header ``# Channel:``, ``# Width: 10.00 µm``,
    ``# Height: 10.00 µm``, ``# Value units: m``. ``Width`` is the physical size along ``x``
    (columns), ``Height`` along ``y`` (rows); values are in ``Value units``.
``dhm-text``
    ASCII matrix with the header ``h=<rows> w=<columns>``, ``pixel size=<Δ> m``,
    ``data unit=rad`` and ``height conversion factor (-> m)=<f>``: height = value × f metres
    (phase maps exported by digital holographic microscopes).
``text``
    Anything else that is a table of numbers: one column or one row → a uniform line scan,
    two columns → a line scan ``(x, h)`` (uniform if ``x`` is equidistant within its printed
    precision, else ``grid="nonuniform"``), more columns → a matrix (rows are ``y``). Lines
    before the numbers (or starting with ``#``/``%``) are a header of ``key: value`` or
    ``key = value`` pairs; ``Width``/``Height``/``Value units`` are understood as in Gwyddion's
    export. Size and units the file lacks come from ``physical_size=``/``file_units=``.
"""

from __future__ import annotations

import re

from ...conventions import length_factor
from ...errors import ReaderError
from .._generic import generic_measurement, resolve_units, single_channel
from .._text import (header_value, is_number, line_measurement, looks_like_text, parse_quantity, parse_table,
                     read_text, token_ulp)
from ..registry import Format, register

__all__ = ["read_text_measurement", "read_dhm", "split_header"]

_COMMENT = ("#", "%", "//")
_NUMBER_START = re.compile(r"^\s*[-+]?(?:\d|\.\d|nan\b|inf\b)", re.IGNORECASE)
_OPTIONS = ("physical_size", "file_units", "height_units")
#: names of the one channel of a text file (besides the index 0)
_CHANNEL_NAMES = ("0", "default", "Default")


def _is_data_line(line: str) -> bool:
    return bool(_NUMBER_START.match(line)) and all(is_number(t) for t in _fields(line))


def split_header(lines, path=None):
    """Split lines into ``(header dict, data lines)``.

    Header lines are the lines before the first all-numeric line, and any comment lines;
    ``key: value`` or ``key = value`` pairs are collected (keys stripped of comment marks).

    Raises
    ------
    ReaderError
        If the (non-comment) line just before the data has as many fields as a data row,
        most of them numbers (half of them if it starts with one, as ``0x10 1``): a corrupt first row,
        which must not silently become a header.
    """
    header = {}
    start = len(lines)
    previous = None  # the last non-comment header line
    for i, line in enumerate(lines):
        s = line.strip()
        if not s:
            continue
        if s.startswith(_COMMENT):
            s = s.lstrip("#%/ \t")
        elif _is_data_line(s):
            start = i
            break
        else:
            previous = s
        m = re.match(r"^([^:=]{1,80}?)\s*[:=]\s*(.*)$", s)
        if m:
            header.setdefault(m.group(1).strip(), m.group(2).strip())
    data = [ln for ln in lines[start:] if ln.strip() and not ln.lstrip().startswith(_COMMENT)]
    if previous is not None and data:
        fields = _fields(previous)
        numbers = sum(is_number(t) for t in fields)
        numeric = numbers > len(fields) / 2 or (_NUMBER_START.match(previous) and numbers >= len(fields) / 2)
        if len(fields) == len(_fields(data[0])) and numeric:
            bad = next(t for t in fields if not is_number(t))
            raise ReaderError(path, f"the first data row contains a token that is not a number: {bad[:40]!r} "
                                    "(corrupt row)")
    return header, data


def _fields(line: str) -> list:
    return [t for t in re.split(r"[\s,;]+", line.strip()) if t]


def _separator(line: str):
    if ";" in line:
        return ";"
    if "," in line and "." in line or line.count(",") >= 1 and " " not in line.strip():
        return ","
    if "\t" in line:
        return "\t"
    return None


def _read_table(path, data_lines):
    sep = _separator(data_lines[0])
    if sep == "\t":
        sep = None
    return parse_table(path, data_lines, sep=sep), sep


def read_text_measurement(path, *, channel=None, physical_size=None, file_units=None, height_units=None):
    """Read a ``text``/``gwyddion-text`` file (see the module docstring)."""
    single_channel(path, channel, _CHANNEL_NAMES)
    header, data = split_header(read_text(path).splitlines(), path)
    if not data:
        raise ReaderError(path, "contains no table of numbers")
    table, sep = _read_table(path, data)
    found_units = found_hu = None
    sizes = {}
    for key, dim in (("Width", "x"), ("Height", "y")):
        if key in header:
            val, unit = parse_quantity(path, header[key], f"header field {key!r}")
            sizes[dim] = val
            if unit is not None:
                found_units = found_units or unit
                if unit != found_units:  # convert to the first unit found
                    sizes[dim] = val * length_factor(unit, found_units)
    if "Value units" in header:
        found_hu = header["Value units"].strip() or None
    attrs = {"channel": header.get("Channel")} if header.get("Channel") else {}
    common = dict(physical_size=physical_size, file_units=file_units, height_units=height_units,
                  found_units=found_units, found_height_units=found_hu, **attrs)
    nrows, ncols = table.shape
    if ncols == 2 and nrows > 2:  # (x, h) line scan
        first = data[0].split(sep) if sep else data[0].split()
        last = data[-1].split(sep) if sep else data[-1].split()
        tol = max(token_ulp(first[0]), token_ulp(last[0]))
        return _line_xy(path, table[:, 0], table[:, 1], tol, common)
    if nrows == 1 or ncols == 1:
        h = table.ravel()
        size = sizes.get("x")
        return generic_measurement(path, h, found_size=size, **common)
    found_size = (sizes["y"], sizes["x"]) if "x" in sizes and "y" in sizes else None
    return generic_measurement(path, table, found_size=found_size, **common)


def _line_xy(path, x, h, tolerance, common):
    lateral, factor = resolve_units(path, found_units=common["found_units"],
                                    found_height_units=common["found_height_units"],
                                    file_units=common["file_units"], height_units=common["height_units"])
    if common["physical_size"] is not None:
        raise ReaderError(path, "the file stores the positions of its line scan; do not pass physical_size")
    return line_measurement(path, x, h * factor, lateral, tolerance=tolerance)


def read_dhm(path, *, channel=None):
    """Read a ``dhm-text`` matrix (``h= w=`` header; height = value × conversion factor, in m)."""
    single_channel(path, channel, _CHANNEL_NAMES)
    lines = read_text(path).splitlines()
    m = re.match(r"^\s*h\s*=\s*(\d+)\s+w\s*=\s*(\d+)\s*$", lines[0] if lines else "")
    if not m:
        raise ReaderError(path, "first line is not 'h=<rows> w=<columns>'")
    ny, nx = int(m.group(1)), int(m.group(2))
    header, data = split_header(lines[1:], path)
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


def _sniff_text(head: bytes, path: str) -> bool:
    return looks_like_text(head)


def _sniff_gwyddion(head: bytes, path: str) -> bool:
    return looks_like_text(head) and head.lstrip().startswith(b"#") and (
        b"# Width:" in head[:1024] and b"# Height:" in head[:1024])


def _sniff_dhm(head: bytes, path: str) -> bool:
    return looks_like_text(head) and re.match(rb"^\s*h\s*=\s*\d+\s+w\s*=\s*\d+\s*\r?\n", head) is not None


register(Format("gwyddion-text", "Gwyddion ASCII matrix export (# Width/Height/Value units header)",
                (".txt", ".asc"), _sniff_gwyddion, read_text_measurement, priority=5, options=_OPTIONS))
register(Format("dhm-text", "ASCII matrix with h=/w=, pixel size and height conversion factor header (DHM)",
                (".txt",), _sniff_dhm, read_dhm, priority=5))
register(Format("text", "plain-text matrix or (x, height) columns, optional key: value header",
                (".txt", ".asc", ".dat", ".csv", ".xyz"), _sniff_text, read_text_measurement, priority=-10,
                options=_OPTIONS))
