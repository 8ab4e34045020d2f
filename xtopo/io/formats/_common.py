"""Helpers shared by the instrument readers (not a format module: the leading
underscore keeps the registry from importing it as one).

* :func:`reading` (a context manager) and :func:`guarded` (the decorator built on it)
  turn any failure while parsing a file into a :class:`~xtopo.errors.ReaderError`
  naming the file.
* :func:`zip_member` reads a named member of a zip archive.
* :func:`sniff_magic` makes the sniffer of a format recognised by its first bytes.
* :func:`channel_format` registers a format from a ``parse`` (the channels) and a ``load`` (one channel).
* :func:`pick_channel` resolves ``channel=`` (index or name) against a list of channel
  names or :class:`ChannelInfo`.
* :func:`to_float` / :func:`to_int` / :func:`clean_text` convert header fields defensively.
* :func:`length_unit` / :func:`value_unit` spell instrument units the xtopo way.
* :func:`iso_time`, :func:`parse_time`, :func:`unix_time` give acquisition times as ISO 8601.
* :func:`measurement` builds the Dataset, also for channels whose values are not lengths.
* :func:`metres_assumed`: files that may state no length unit are read in metres.
"""

from __future__ import annotations

import contextlib
import datetime
import functools
import math
import numbers
import re

import numpy as np

from ..._units import _ureg
from ...conventions import make_measurement, normalize_units
from ...errors import MetadataWarning, ReaderError, UnitsError, UnsupportedFormatError, XtopoError, warn
from .._zip import read_member
from ..registry import ChannelInfo, Format, register

__all__ = ["reading", "guarded", "pick_channel", "to_float", "to_int", "clean_text", "length_unit", "value_unit",
           "unit_factor", "channel_info", "measurement", "unique_name", "iso_time", "parse_time", "unix_time",
           "sniff_magic", "channel_format", "zip_member", "ChannelInfo", "HEIGHT_NAME_RE", "metres_assumed"]

#: Channel names that denote topography (heights) rather than an auxiliary signal.
HEIGHT_NAME_RE = re.compile(r"height|topo|zsensor|z[ _-]?sensor|z[ _-]?axis|^z$|^z[ _(]", re.IGNORECASE)

_UNIT_SPELLINGS = {
    "~m": "um", "µm": "um", "μm": "um", "um": "um", "micron": "um", "microns": "um",
    "nm": "nm", "m": "m", "mm": "mm", "pm": "pm", "cm": "cm", "å": "angstrom", "Å": "angstrom",
    "angstrom": "angstrom", "º": "deg", "°": "deg", "deg": "deg", "degree": "deg",
    "degrees": "deg",
}


@contextlib.contextmanager
def reading(path, what: str):
    """Context in which every failure to parse ``path`` becomes a :class:`ReaderError`.

    Floating-point warnings are silenced inside: raw instrument data may hold signalling
    NaNs and extreme values, and casting them is not an error of the reader (scale
    overflows are checked in :func:`measurement`).

    Parameters
    ----------
    path : str or os.PathLike
        The file being read (named in the message).
    what : str
        The format, e.g. ``"Wyko OPD"``, used in the message.
    """
    try:
        with np.errstate(all="ignore"):
            yield
    except ReaderError:
        raise
    except XtopoError as exc:  # e.g. a unit or grid the header states that makes no sense
        raise ReaderError(path, f"invalid {what} header: {exc}") from None
    except (MemoryError, RecursionError) as exc:
        raise ReaderError(path, f"{what} reader gave up on malformed content: {type(exc).__name__}") from None
    except Exception as exc:  # any parse failure of untrusted content
        raise ReaderError(path, f"malformed {what} content ({type(exc).__name__}: {exc})") from exc


def guarded(what: str):
    """Decorate ``func(path, ...)`` so that it runs inside :func:`reading` ``(path, what)``."""

    def deco(func):
        @functools.wraps(func)
        def wrapper(path, *args, **kwargs):
            with reading(path, what):
                return func(path, *args, **kwargs)

        return wrapper

    return deco


def zip_member(path, zf, name: str, what: str, missing: str, **options) -> bytes:
    """The bytes of member ``name`` of the open archive ``zf`` (:func:`~xtopo.io._zip.read_member` with
    ``options``); :class:`ReaderError` ``missing`` where the archive has no such member."""
    try:
        info = zf.getinfo(name)
    except KeyError:
        raise ReaderError(path, missing) from None
    return read_member(path, zf, info, what, **options)


def sniff_magic(*magics: bytes):
    """Sniffer ``(head, path) -> bool`` for a format whose files start with one of ``magics``."""

    def sniff(head: bytes, path: str) -> bool:
        return head.startswith(magics)

    return sniff


def channel_format(name: str, description: str, suffixes: tuple, sniff, what: str, parse, load, *,
                   priority: int = 10, options: tuple = (), empty: str | None = None) -> Format:
    """Register (and return) the :class:`Format` ``name`` whose ``read`` and ``channels`` share one parser.

    ``parse(path, **options)`` returns ``(channels, *state)``: the file's :class:`ChannelInfo`, then what
    ``load(path, info, *state, **options)`` needs to build the Dataset of the channel ``info`` that
    :func:`pick_channel` chose. Both run inside :func:`reading` ``(path, what)``; ``empty`` is the
    message for a file without channels (default: :func:`pick_channel`'s).
    """

    @guarded(what)
    def channels(path, **opts):
        return parse(path, **opts)[0]

    @guarded(what)
    def read(path, *, channel=None, **opts):
        infos, *state = parse(path, **opts)
        if not infos and empty:
            raise ReaderError(path, empty)
        return load(path, infos[pick_channel(path, infos, channel)], *state, **opts)

    return register(Format(name, description, suffixes, sniff, read, channels, priority, options))


def _header_number(path, text, what: str, default, parse, ok, expected: str):
    """``parse(text)`` where ``ok`` accepts it, else ``default``; :class:`ReaderError` (``expected``) if neither."""
    try:
        val = parse(str(text).strip() if isinstance(text, (str, bytes)) else text)
        if ok(val):
            return val
    except (TypeError, ValueError, OverflowError):
        pass
    if default is not None:
        return default
    raise ReaderError(path, f"header field {what} is not {expected}: {text!r}")


def to_float(path, text, what: str, default=None) -> float:
    """``float(text)`` (finite; a decimal comma read as a point) or ``default``; :class:`ReaderError` if neither."""
    return _header_number(path, text, what, default, lambda t: float(t.replace(",", ".") if isinstance(t, str) else t),
                          math.isfinite, "a finite number")


def to_int(path, text, what: str, default=None, minimum: int = 0) -> int:
    """``int(text)`` (``>= minimum``) or ``default``; :class:`ReaderError` if neither."""
    return _header_number(path, text, what, default, int, lambda v: v >= minimum, f"an integer >= {minimum}")


def clean_text(raw: bytes, encoding: str = "latin-1") -> str:
    """Decode a NUL-padded fixed-size header string and strip blanks."""
    return raw.split(b"\0", 1)[0].decode(encoding, errors="replace").strip()


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


def pick_channel(path, channels, channel) -> int:
    """Position in ``channels`` of the requested ``channel``.

    Parameters
    ----------
    path : str or os.PathLike
        The file (named in error messages).
    channels : sequence of str or ChannelInfo
        The file's channels, by name or described.
    channel : int, str or None
        A position in ``channels``; a name (exact, else case-insensitive); or ``None`` for the
        first height channel (:attr:`ChannelInfo.is_height`), else the first channel.

    Raises
    ------
    ReaderError
        If ``channels`` is empty.
    UnsupportedFormatError
        If ``channel`` names no channel or is out of range; the message lists the channels.
    """
    names = [c if isinstance(c, str) else c.name for c in channels]
    if not names:
        raise ReaderError(path, "the file holds no readable channel")
    listing = ", ".join(f"{i}: {n!r}" for i, n in enumerate(names))
    if channel is None:
        return next((i for i, c in enumerate(channels) if getattr(c, "is_height", False)), 0)
    if isinstance(channel, str):
        lowered = [n.lower() for n in names]
        if channel in names:
            return names.index(channel)
        if channel.strip().lower() in lowered:
            return lowered.index(channel.strip().lower())
        raise UnsupportedFormatError(path, f"no channel named {channel!r}; channels are {listing}")
    if not isinstance(channel, numbers.Integral) or isinstance(channel, bool):
        raise UnsupportedFormatError(path, f"channel must be an index or a name, got {channel!r}; "
                                           f"channels are {listing}")
    if 0 <= int(channel) < len(names):
        return int(channel)
    raise UnsupportedFormatError(path, f"channel index {channel} out of range; channels are {listing}")


def unique_name(label: str, seen: set) -> str:
    """``label``, or ``label #2``, ``#3``, ... if already in ``seen`` (case-insensitive); adds it to ``seen``."""
    name, k = label, 2
    while name.lower() in seen:
        name, k = f"{label} #{k}", k + 1
    seen.add(name.lower())
    return name


def iso_time(year, month=1, day=1, hour=0, minute=0, second=0) -> str | None:
    """ISO 8601 text of a date/time, or ``None`` where the fields do not form a valid date."""
    try:
        return datetime.datetime(int(year), int(month), int(day), int(hour), int(minute),
                                 int(second)).isoformat()
    except (TypeError, ValueError, OverflowError):
        return None


def parse_time(text, *formats) -> str | None:
    """ISO 8601 text of ``text`` parsed with the first matching ``strptime`` format, else ``None``."""
    s = " ".join(str(text or "").split())
    for fmt in formats:
        try:
            return datetime.datetime.strptime(s, fmt).isoformat()
        except ValueError:
            continue
    return None


def unix_time(seconds) -> str | None:
    """ISO 8601 (UTC) text of a POSIX timestamp; ``None`` for 0/unset or out-of-range values."""
    try:
        s = int(seconds)
        if s <= 0 or s >= 0xFFFFFFFF:
            return None
        return datetime.datetime.fromtimestamp(s, tz=datetime.timezone.utc).isoformat()
    except (TypeError, ValueError, OverflowError, OSError):
        return None


def measurement(path, values, info: ChannelInfo, *, value_units: str | None = None, height_scale: float = 1.0,
                mask=None, **attrs):
    """Build the measurement for one channel (of ``info``'s size; ``value_units``: by default ``info``'s).

    Height channels (``value_units`` a length) are converted to the lateral unit (``info.units``) so that the
    Dataset has one length unit.  Other channels (phase, amplitude, current, ...) keep their
    values in ``value_units``: the ``height`` variable then carries that unit (and
    ``quantity="signal"``); such a Dataset is not a topography:
    :func:`xtopo.open_topography` refuses it with an :class:`UnsupportedFormatError` that
    names the file, while the format's own ``read`` returns it.
    """
    value_units = info.height_units if value_units is None else value_units
    lat = normalize_units(info.units)
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
    ds = make_measurement(values, size=info.size, units=lat, height_scale=scale, mask=mask, **attrs)
    if vlen is None:
        ds["height"].attrs.update(units=value_units or "1", long_name=info.name, quantity="signal")
    else:
        ds["height"].attrs["long_name"] = "height"
    return ds


def metres_assumed(path, what: str) -> dict:
    """Warn (:class:`~xtopo.errors.MetadataWarning`) that ``path`` states no length unit and was read in
    metres; return the ``units_assumed`` attribute that records it."""
    warn(f"{path}: the {what} states no length unit; read as metres. Pass file_units= (e.g. "
         "file_units='um') to say what it is in, and physical_size= if its size is not right", MetadataWarning)
    return {"units_assumed": f"the {what} states no length unit; metres assumed"}
