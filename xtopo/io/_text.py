"""Defensive helpers shared by the text-based readers.

Text files are untrusted like binary ones: every helper turns malformed content into a
:class:`~xtopo.errors.ReaderError` naming the file, never a bare ``ValueError``.
"""

from __future__ import annotations

import os
import re

import numpy as np

from ..conventions import make_measurement, normalize_units
from ..errors import ReaderError, UnitsError, UnsupportedFormatError

__all__ = [
    "MAX_TEXT_BYTES", "looks_like_text", "read_text", "parse_table", "parse_quantity",
    "length_unit", "column_precision", "uniform_spacing", "line_measurement", "header_value",
    "is_number",
]

#: Refuse text files larger than this (a text matrix of 2e7 values).
MAX_TEXT_BYTES = 512 * 1024 * 1024

_CONTROL = bytes(range(0, 9)) + bytes(range(14, 32))


_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")


def looks_like_text(head: bytes) -> bool:
    """True if ``head`` (the start of a file) is plausibly text: no NUL byte, few control characters.

    UTF-8 or Latin-1 (one byte per character) encodings are accepted, and UTF-16 with a byte-order
    mark (spreadsheet exports).
    """
    if head[:2] in _UTF16_BOMS:
        text = head[:len(head) & ~1].decode("utf-16", errors="replace")
        return bool(text[1:]) and looks_like_text(text[1:].encode("utf-8"))
    if not head or b"\0" in head:
        return False
    n_control = len(head) - len(head.translate(None, _CONTROL))
    if n_control > max(2, len(head) // 100):
        return False
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 4:  # not just a multi-byte sequence cut at the end of the head
            # Latin-1 text: bytes >= 0x80 must be rare
            return sum(b >= 0x80 for b in head) <= max(4, len(head) // 50)
    return True


def read_text(path, limit: int = MAX_TEXT_BYTES) -> str:
    """Decode the whole file: UTF-16 if it starts with a UTF-16 byte-order mark, else UTF-8 (BOM stripped)
    or, failing that, Latin-1."""
    try:
        size = os.path.getsize(path)
        if size > limit:
            raise ReaderError(path, f"text file of {size} bytes exceeds the limit of {limit} bytes")
        with open(path, "rb") as f:
            data = f.read()
    except OSError as exc:
        raise ReaderError(path, f"cannot be read: {exc}") from None
    if data[:2] in _UTF16_BOMS:
        try:
            text = data.decode("utf-16")
        except UnicodeDecodeError:
            raise ReaderError(path, "starts with a UTF-16 byte-order mark but is not UTF-16 text") from None
        if "\0" in text:
            raise UnsupportedFormatError(path, "contains NUL characters; it is not a text file")
        return text
    if b"\0" in data:
        raise UnsupportedFormatError(path, "contains NUL bytes; it is not a text file")
    if data.startswith(b"\xef\xbb\xbf"):
        data = data[3:]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def parse_table(path, lines, sep: str | None = None, what: str = "data", ncols: int | None = None) -> np.ndarray:
    """Parse lines of numbers into a 2D float array (rows × columns).

    Parameters
    ----------
    path : str
        For error messages.
    lines : sequence of str
        Data lines; blank lines are skipped, trailing empty fields (``"1,2,,"``) dropped.
    sep : str, optional
        Field separator; ``None`` splits on whitespace.
    ncols : int, optional
        Expected number of columns.

    Raises
    ------
    ReaderError
        On ragged rows or tokens that are not numbers.
    """
    rows = [ln for ln in lines if ln and not ln.isspace()]
    if not rows:
        raise ReaderError(path, f"no {what} found")
    body = "\n".join(rows)
    if sep is not None:
        body = _TRAILING_SEPS[sep].sub("", body)  # trailing empty fields ("1,2,,")
    counts = _fields_per_line(body, sep, len(rows))
    if sep is not None:
        body = body.replace(sep, " ")
    n = counts[0] if ncols is None else ncols
    for i, c in enumerate(counts):
        if c != n:
            raise ReaderError(path, f"{what} row {i + 1} has {c} values, expected {n} (ragged or corrupt table)")
    try:  # numpy's C parser; exact token accounting below catches anything it skipped
        arr = np.fromstring(body, dtype=float, sep=" ")
    except ValueError:
        arr = None
    if arr is None or arr.size != n * len(rows):
        toks = body.split()
        bad = next((t for t in toks if not is_number(t)), None)
        if bad is not None:
            raise ReaderError(path, f"{what} contains a token that is not a number: {bad[:40]!r}")
        if len(toks) != n * len(rows):
            raise ReaderError(path, f"{what} has empty fields (expected {n} values per row)")
        arr = np.array(toks, dtype=float)
    return arr.reshape(len(rows), n)


_TRAILING_SEPS = {c: re.compile(rf"[{re.escape(c)} \t]+$", re.M) for c in ",;\t"}
_WHITESPACE = np.zeros(256, dtype=bool)
_WHITESPACE[[9, 10, 11, 12, 13, 32]] = True


def _fields_per_line(body: str, sep, n_lines: int) -> np.ndarray:
    """Number of fields on each line of ``body`` (vectorised; ``sep=None``: whitespace-separated tokens)."""
    b = np.frombuffer(body.encode("utf-8", "surrogateescape"), dtype=np.uint8)
    newlines = np.flatnonzero(b == 10)
    if sep is None:
        space = _WHITESPACE[b]
        starts = np.flatnonzero(~space[1:] & space[:-1]) + 1
        if b.size and not space[0]:
            starts = np.concatenate([[0], starts])
        return np.bincount(np.searchsorted(newlines, starts), minlength=n_lines)
    return np.bincount(np.searchsorted(newlines, np.flatnonzero(b == ord(sep))), minlength=n_lines) + 1


def is_number(tok: str) -> bool:
    try:
        float(tok)
        return True
    except ValueError:
        return False


_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*(\S.*?)?\s*$")


def length_unit(path, unit: str, what: str) -> str:
    """``unit`` normalised as a length unit; a :class:`ReaderError` naming ``what`` otherwise."""
    try:
        return normalize_units(unit)
    except UnitsError as exc:
        raise ReaderError(path, f"{what}: {exc}") from None


def parse_quantity(path, text: str, what: str) -> tuple[float, str | None]:
    """Split ``"10.00 µm"`` into ``(10.0, "um")``; the unit is ``None`` when absent."""
    m = _QUANTITY.match(text)
    if not m:
        raise ReaderError(path, f"{what} is not a number with unit: {text[:60]!r}")
    value = float(m.group(1))
    unit = m.group(2)
    if unit is not None:
        unit = length_unit(path, unit, what)
    return value, unit


def header_value(path, header: dict, key: str, kind=float):
    """``kind(header[key])`` with a :class:`ReaderError` if missing or malformed."""
    if key not in header:
        raise ReaderError(path, f"header field {key!r} is missing")
    try:
        val = kind(str(header[key]).strip())
    except (ValueError, OverflowError):
        raise ReaderError(path, f"header field {key!r} is not a valid {kind.__name__}: {header[key]!r}") from None
    if kind is float and not np.isfinite(val):
        raise ReaderError(path, f"header field {key!r} is not finite: {header[key]!r}")
    return val


_TOKENS = re.compile(r"^\s*[-+]?\d*(?:\.(\d*))?(?:[eE]([-+]?\d+))?\s*$", re.M)


def column_precision(tokens) -> float:
    """The coarsest printed precision among number ``tokens``: the largest unit in the last printed place
    (``"1.25e-3"`` → ``1e-5``).

    Positions printed with different numbers of decimals (``0.5``, ``0.25``) are only as precise
    as the coarsest of them. Tokens that are not plain numbers count as 0 (unknown).
    """
    text = "\n".join(t.strip() for t in tokens)
    raw = text.encode("utf-8", "replace")
    if not raw.strip():
        return 0.0
    if not raw.translate(None, b"0123456789+-.\n"):  # the common case, vectorised: no exponent, no name
        b = np.frombuffer(raw, dtype=np.uint8)
        ends = np.append(np.flatnonzero(b == 10), b.size)
        dots = np.flatnonzero(b == 46)
        decimals = np.zeros(ends.size, dtype=np.int64)
        decimals[np.searchsorted(ends, dots)] = ends[np.searchsorted(ends, dots)] - dots - 1
        return 10.0 ** -int(decimals.min())
    shapes = set(_TOKENS.findall(text))  # (decimals, exponent) of each number: one regex pass
    ulps = [10.0 ** (int(exp or 0) - len(dec)) for dec, exp in shapes if abs(int(exp or 0)) <= 300]
    return max(ulps, default=0.0)


#: A grid is never accepted when positions stray from it by this fraction of a step or more.
MAX_GRID_DEVIATION = 0.4


def uniform_spacing(x: np.ndarray, precision: float = 0.0) -> float | None:
    """Spacing of ``x`` if it is a uniform grid within its printed ``precision``, else None.

    ``precision`` is the unit in the last printed place of the positions (:func:`column_precision`;
    0 for positions stored as binary numbers). Rounding to it moves a position by up to half of it,
    so a step between neighbours by up to ``precision`` and a position off the least-squares line
    ``x_0 + m Δ`` by about half of it. Every step and every position is checked against
    ``min(precision, 0.4 Δ)`` (plus floating-point slack): a missing or inserted sample changes one
    step by a whole ``Δ`` and is never mistaken for rounding, while positions printed too coarsely
    to tell a grid from a scan with gaps are read as nonuniform, as printed.
    """
    x = np.asarray(x, dtype=float)
    n = x.size
    if n < 2:
        return None
    m = np.arange(n, dtype=float)
    mc = m - m.mean()
    with np.errstate(over="ignore", invalid="ignore"):  # positions near the float limit: no grid, no warning
        d = float(np.dot(mc, x - x.mean()) / np.dot(mc, mc))
        if not (np.isfinite(d) and d > 0):
            return None
        slack = max(1e-9 * d * n, 1e-12 * float(np.max(np.abs(x))))
        tol = min(float(precision), MAX_GRID_DEVIATION * d) + slack
        steps = np.abs(np.diff(x) - d)
        dev = np.abs(x - x.mean() - d * mc)
    return d if float(np.max(steps)) <= tol and float(np.max(dev)) <= tol else None


def line_measurement(path, x, h, units: str, *, precision: float = 0.0, mask=None, **attrs):
    """A line scan from positions and heights: uniform (``size=N Δ``) when ``x`` is a grid within its
    printed ``precision`` (:func:`uniform_spacing`), nonuniform (``x=``, ``grid="nonuniform"``) otherwise.

    Raises
    ------
    ReaderError
        If the positions are not finite and strictly increasing.
    """
    x = np.asarray(x, dtype=float)
    h = np.asarray(h, dtype=float)
    if x.size < 2:
        raise ReaderError(path, f"a line scan needs at least 2 points, found {x.size}")
    if not np.all(np.isfinite(x)) or np.any(np.diff(x) <= 0):
        raise ReaderError(path, "the positions (first column) must be finite and strictly increasing")
    d = uniform_spacing(x, precision)
    if d is not None:
        return make_measurement(h, size=x.size * d, units=units, mask=mask, **attrs)
    return make_measurement(h, x=x, units=units, mask=mask, **attrs)
