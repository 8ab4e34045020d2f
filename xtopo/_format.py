"""Numbers with units for people: engineering prefixes (``20.08 µm``, ``50 MPa``) and aligned tables.

Used by the command line and the summary table; results keep SI values in their files, only the
printed text is scaled.
"""

from __future__ import annotations

import math

__all__ = ["format_quantities", "format_quantity", "format_length", "format_columns"]

#: prefixes from large to small (the first whose factor the value reaches is used)
_PREFIXES = (("G", 1e9), ("M", 1e6), ("k", 1e3), ("", 1.0), ("m", 1e-3), ("µ", 1e-6), ("n", 1e-9), ("p", 1e-12),
             ("f", 1e-15))
#: length units xtopo writes (UDUNITS ASCII) → metres
_LENGTHS = {"m": 1.0, "km": 1e3, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "nm": 1e-9, "pm": 1e-12, "Å": 1e-10,
            "angstrom": 1e-10}


def _base(units: str):
    """``(factor, base unit, power)`` so that ``value · factor`` is in ``base**power``; None when the unit takes
    no prefix (``"1"``, ``"E*"``, ``"m-1"``, ...)."""
    units = (units or "").strip()
    if units in _LENGTHS:
        return _LENGTHS[units], "m", 1
    if units[-1:] == "2" and units[:-1] in _LENGTHS:
        return _LENGTHS[units[:-1]] ** 2, "m", 2
    pressures = {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9}
    words = units.split()
    if words and words[0] in pressures:
        f = pressures[words[0]]
        rest = " ".join(words[1:])
        if not rest:
            return f, "Pa", 1
        if rest[-1:] == "2" and rest[:-1] in _LENGTHS:  # a load on an area scan: Pa·m² = N
            return f * _LENGTHS[rest[:-1]] ** 2, "N", 1
        if rest in _LENGTHS:  # a load per unit length on a line scan: Pa·m = N/m
            return f * _LENGTHS[rest], "N/m", 1
    return None


def _prefix(largest: float, power: int):
    shown = float(f"{largest:.4g}") if largest > 0 else 0.0
    name, f = next(((n, f) for n, f in _PREFIXES if shown >= f ** power * (1 - 1e-12)), _PREFIXES[-1])
    return name, f ** power


def format_quantities(values, units: str, *, digits: int = 4, sep: str = " … ") -> str:
    """Values of one unit with one engineering prefix chosen by the largest: ``-352.6 … -223.4 µm``.

    Parameters
    ----------
    values : sequence of float
        In ``units``.
    units : str
        Their unit (``"m"``, ``"um"``, ``"m2"``, ``"Pa"``, ``"Pa m2"`` (printed in N), ...); a unit
        without a prefix (``"1"``, ``"E*"``) prints the values as they are.
    digits : int
        Significant digits.
    sep : str
        Between the values.

    Returns
    -------
    str
    """
    values = [float(v) for v in values]
    base = _base(units)
    finite = [abs(v) for v in values if math.isfinite(v)]
    if base is None or not finite:
        tail = "" if units in (None, "", "1") or not finite else f" {units}"
        return sep.join("-" if not math.isfinite(v) else f"{v:.{digits}g}" for v in values) + tail
    factor, unit, power = base
    name, scale = _prefix(max(finite) * factor, power)
    text = sep.join("-" if not math.isfinite(v) else f"{v * factor / scale:.{digits}g}" for v in values)
    return f"{text} {name}{unit}{'²' if power == 2 else ''}"


def format_quantity(value, units: str, *, digits: int = 4) -> str:
    """One value with an engineering prefix: ``2.008e-05`` m → ``20.08 µm``; ``5e7`` Pa → ``50 MPa``."""
    return format_quantities([value], units, digits=digits)


def format_columns(columns) -> str:
    """An aligned plain-text table: ``columns`` is a sequence of ``(title, values, units)``; numeric columns
    share one prefix (named in the header, ``load [mN]``) and are right-aligned."""
    header, cells = [], []
    for title, values, units in columns:
        values = list(values)
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
        if numeric and units is not None and _base(units) is not None:
            body, _, unit = format_quantities(values, units, sep="\t").rpartition(" ")
            header.append(f"{title} [{unit}]")
            cells.append(body.split("\t"))
        elif numeric:
            header.append(f"{title} [{units}]" if units not in (None, "", "1") else title)
            cells.append([f"{v:.4g}" if isinstance(v, float) else str(v) for v in values])
        else:
            header.append(title)
            cells.append([str(v) for v in values])
    widths = [max([len(h)] + [len(c) for c in col]) for h, col in zip(header, cells)]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(row, widths)) for row in [header, *zip(*cells)])


def format_length(v: float) -> str:
    """A length in metres with three significant digits and its prefix (``0.9999996`` prints as ``1 m``)."""
    return format_quantity(v, "m", digits=3)
