"""Length units: their UDUNITS spelling and conversion factors (pint). Layer 0: imports only ``errors``."""

from __future__ import annotations

import functools

from .errors import UnitsError

__all__ = ["normalize_units", "length_factor"]

_UNIT_ALIASES = {
    "µm": "um", "μm": "um", "micron": "um", "microns": "um", "micrometer": "um",
    "micrometre": "um", "nanometer": "nm", "nanometre": "nm", "millimeter": "mm",
    "millimetre": "mm", "meter": "m", "metre": "m", "meters": "m", "Å": "angstrom",
    "Angstrom": "angstrom", "picometer": "pm", "centimeter": "cm",
}


@functools.lru_cache(maxsize=1)
def _ureg():
    import pint

    return pint.UnitRegistry()


#: metres per unit of the common length units, equal to pint's factors: building pint's registry costs
#: 0.4-1 s, most of a fresh process's first analysis, and these units need none
_METRES = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "nm": 1e-9, "pm": 1e-12, "cm": 1e-2, "km": 1e3, "angstrom": 1e-10}


@functools.lru_cache(maxsize=256)
def _length_in_m(units: str) -> float:
    if units in _METRES:
        return _METRES[units]
    ureg = _ureg()
    try:
        q = ureg.Quantity(1.0, units)
    except Exception as exc:  # pint raises several unrelated types
        raise UnitsError(f"cannot parse the unit {units!r}: {exc}") from None
    if q.dimensionality != ureg.meter.dimensionality:
        raise UnitsError(f"{units!r} is not a length unit")
    return float(q.to("m").magnitude)


def normalize_units(units) -> str:
    """Return the UDUNITS ASCII spelling of a length unit (``"µm"`` → ``"um"``).

    Raises
    ------
    UnitsError
        If ``units`` is not a length unit.
    """
    if units is None:
        raise UnitsError("no length unit given")
    if not isinstance(units, str):  # str() made 5, True, b'um' or an array a unit pint failed to parse
        raise UnitsError(f"a length unit must be a string such as 'm' or 'um', not {type(units).__name__}")
    u = units.strip()
    u = _UNIT_ALIASES.get(u, u).replace("µ", "u").replace("μ", "u")
    _length_in_m(u)
    return u


def length_factor(from_units: str, to_units: str) -> float:
    """Factor that converts a length in ``from_units`` to ``to_units``."""
    f, t = normalize_units(from_units), normalize_units(to_units)
    return 1.0 if f == t else _length_in_m(f) / _length_in_m(t)
