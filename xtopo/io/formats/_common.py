"""Helpers shared by the instrument readers (not a format module: the leading
underscore keeps the registry from importing it as one).

* :func:`guarded` turns any stray exception of a reader into a
  :class:`~xtopo.errors.ReaderError` naming the file.
* :func:`pick_channel` resolves ``channel=`` (index or name) against a channel list.
* :func:`to_float` / :func:`to_int` convert header text defensively.
* :func:`length_unit` / :func:`value_unit` spell instrument units the xtopo way.
* :func:`measurement` builds the Dataset, also for channels whose values are not lengths.
"""

from __future__ import annotations

import datetime
import functools
import math
import os
import re

import numpy as np

from ...conventions import make_measurement, normalize_units
from ...errors import ReaderError, UnitsError, UnsupportedFormatError, XtopoError
from ..registry import ChannelInfo

__all__ = ["guarded", "pick_channel", "to_float", "to_int", "length_unit", "value_unit",
           "unit_factor", "channel_info", "measurement", "iso", "unique_name", "parse_time", "ChannelInfo",
           "HEIGHT_NAME_RE"]

#: Channel names that denote topography (heights) rather than an auxiliary signal.
HEIGHT_NAME_RE = re.compile(r"height|topo|zsensor|z[ _-]?sensor|z[ _-]?axis|^z$|^z[ _(]", re.IGNORECASE)

_UNIT_SPELLINGS = {
    "~m": "um", "µm": "um", "μm": "um", "um": "um", "micron": "um", "microns": "um",
    "nm": "nm", "m": "m", "mm": "mm", "pm": "pm", "cm": "cm", "å": "angstrom", "Å": "angstrom",
    "angstrom": "angstrom", "º": "deg", "°": "deg", "deg": "deg", "degree": "deg",
    "degrees": "deg",
}


def guarded(fmt_name: str):
    """Decorate ``func(path, ...)`` so that only :class:`XtopoError` subclasses escape.

    Floating-point warnings are silenced inside: casting raw data that hold signalling
    NaNs or huge values is not an error of the reader.
    """

    def deco(func):
        @functools.wraps(func)
        def wrapper(path, *args, **kwargs):
            try:
                # raw instrument data may hold signalling NaNs and extreme values: casting them is
                # not an error of the reader (scale overflows are checked in `measurement`)
                with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
                    return func(path, *args, **kwargs)
            except XtopoError:
                raise
            except (MemoryError, RecursionError) as exc:
                raise ReaderError(path, f"{fmt_name} reader gave up on malformed content: "
                                        f"{type(exc).__name__}") from None
            except Exception as exc:  # a parse failure on corrupt content
                raise ReaderError(path, f"malformed {fmt_name} content ({type(exc).__name__}: {exc})") from exc

        return wrapper

    return deco


def to_float(path, text, what: str, default=None) -> float:
    """``float(text)`` (finite) or ``default``; :class:`ReaderError` if neither."""
    try:
        val = float(str(text).strip().replace(",", ".") if isinstance(text, (str, bytes)) else text)
        if math.isfinite(val):
            return val
    except (TypeError, ValueError, OverflowError):
        pass
    if default is not None:
        return default
    raise ReaderError(path, f"header field {what} is not a finite number: {text!r}")


def to_int(path, text, what: str, default=None, minimum: int = 0) -> int:
    """``int(text)`` (``>= minimum``) or ``default``; :class:`ReaderError` if neither."""
    try:
        val = int(str(text).strip()) if isinstance(text, (str, bytes)) else int(text)
        if val >= minimum:
            return val
    except (TypeError, ValueError, OverflowError):
        pass
    if default is not None:
        return default
    raise ReaderError(path, f"header field {what} is not an integer >= {minimum}: {text!r}")


def value_unit(text) -> str:
    """An instrument's unit string in xtopo spelling (``"~m"`` → ``"um"``, ``"º"`` → ``"deg"``)."""
    u = str(text or "").strip()
    return _UNIT_SPELLINGS.get(u, _UNIT_SPELLINGS.get(u.lower(), u))


def length_unit(text) -> str | None:
    """The normalised length unit of ``text``, or ``None`` if it is not a length."""
    u = value_unit(text)
    if not u or u == "A":  # instrument files spell angstrom "Å"; a bare "A" is ampere
        return None
    try:
        return normalize_units(u)
    except UnitsError:
        return None


def unit_factor(from_unit: str, to_unit: str) -> float | None:
    """Factor converting ``from_unit`` to ``to_unit`` (any dimension), ``None`` if incompatible."""
    if from_unit == to_unit:
        return 1.0
    try:
        from ...conventions import _ureg

        return float(_ureg().Quantity(1.0, from_unit).to(to_unit).magnitude)
    except Exception:  # pint raises several types for unknown/incompatible units
        return None


def channel_info(index: int, name: str, shape, size, units: str, value_units: str, hint: str | None = None,
                 height: bool | None = None) -> ChannelInfo:
    """A :class:`ChannelInfo`; a channel is a height channel when its values are lengths and
    its name (or ``hint``) looks like topography (``height=True`` skips the name test)."""
    lu = length_unit(value_units)
    looks = bool(HEIGHT_NAME_RE.search(hint if hint is not None else name)) if height is None else height
    return ChannelInfo(index=index, name=name, shape=tuple(shape), size=tuple(size), units=units,
                       height_units=lu or value_units, is_height=bool(lu) and looks)


def pick_channel(path, infos: list[ChannelInfo], channel) -> int:
    """Index into ``infos`` for ``channel`` (``None``: first height channel, then the first one).

    Names match case-insensitively; an ``int`` is a position in ``infos``.
    """
    if not infos:
        raise ReaderError(path, "the file holds no readable image channel")
    listing = ", ".join(f"{i}: {c.name!r}" for i, c in enumerate(infos))
    if channel is None:
        for i, c in enumerate(infos):
            if c.is_height:
                return i
        return 0
    if isinstance(channel, (int, np.integer)) and not isinstance(channel, bool):
        if 0 <= int(channel) < len(infos):
            return int(channel)
        raise UnsupportedFormatError(path, f"channel index {channel} out of range; channels are {listing}")
    want = str(channel).strip().lower()
    for i, c in enumerate(infos):
        if c.name.lower() == want:
            return i
    raise UnsupportedFormatError(path, f"no channel named {channel!r}; channels are {listing}")


def unique_name(label: str, seen: set) -> str:
    """``label``, or ``label #2``, ``#3``, ... if already in ``seen`` (case-insensitive); adds it to ``seen``."""
    name, k = label, 2
    while name.lower() in seen:
        name, k = f"{label} #{k}", k + 1
    seen.add(name.lower())
    return name


def iso(dt: datetime.datetime | None) -> str | None:
    """ISO 8601 text of a datetime (``None`` passes through)."""
    return None if dt is None else dt.isoformat()


def parse_time(text, *formats) -> str | None:
    """ISO 8601 text of ``text`` parsed with the first matching ``strptime`` format, else ``None``."""
    s = " ".join(str(text or "").split())
    for fmt in formats:
        try:
            return datetime.datetime.strptime(s, fmt).isoformat()
        except ValueError:
            continue
    return None


def measurement(path, values, info: ChannelInfo, *, size, lateral_units: str, value_units: str,
                height_scale: float = 1.0, mask=None, **attrs):
    """Build the measurement for one channel.

    Height channels (``value_units`` a length) are converted to ``lateral_units`` so that the
    Dataset has one length unit.  Other channels (phase, amplitude, current, ...) keep their
    values in ``value_units``: the ``height`` variable then carries that unit (and
    ``quantity="signal"``); such a Dataset is not a topography:
    :func:`xtopo.open_topography` refuses it with an :class:`UnsupportedFormatError` that
    names the file, while the format's own ``read`` returns it.
    """
    lat = normalize_units(lateral_units)
    vlen = length_unit(value_units)
    scale = float(height_scale)
    if vlen is not None:
        scale *= unit_factor(vlen, lat) or 1.0
    values = np.asarray(values, dtype=np.float64)
    finite = values[np.isfinite(values)]
    biggest = float(np.max(np.abs(finite))) if finite.size else 0.0
    if not (math.isfinite(scale) and math.isfinite(biggest * scale)):
        raise ReaderError(path, f"height scale {scale!r} overflows (corrupt scale field)")
    attrs = {"channel": info.name, "channel_index": info.index, **attrs}
    if vlen is None:
        attrs["height_units"] = value_units
    else:
        attrs["original_height_units"] = vlen
    attrs["original_lateral_units"] = lat
    ds = make_measurement(values, size=size, units=lat, height_scale=scale, mask=mask, **attrs)
    if vlen is None:
        ds["height"].attrs.update(units=value_units or "1", long_name=info.name, quantity="signal")
    else:
        ds["height"].attrs["long_name"] = "height"
    return ds


def file_size(path) -> int:
    try:
        return os.path.getsize(path)
    except OSError as exc:
        raise ReaderError(path, f"cannot be read: {exc}") from None
