"""Units and physical size for generic formats (text, npy, MATLAB, HDF5, NetCDF) that may not store them.

The caller's options (see :func:`xtopo.open_topography`) fill what the file lacks:
``physical_size`` (in the lateral unit), ``file_units`` (lateral unit, and height unit
unless ``height_units`` differs). A file that states a unit refuses ``file_units``.
"""

from __future__ import annotations

import numbers

import numpy as np

from ..conventions import length_factor, make_measurement, normalize_units
from ..errors import OptionError, ReaderError, UnitsError, UnsupportedFormatError
from ._text import length_unit, line_measurement
from .registry import READ_OPTIONS, ChannelInfo, Format, register

__all__ = ["resolve_units", "stated_or_given", "generic_measurement", "single_channel", "stated_length_unit",
           "container_format"]


def resolve_units(path, *, found_units=None, found_height_units=None, file_units=None, height_units=None):
    """Return ``(lateral_unit, height_factor)``: the dataset's length unit and the factor that converts
    the stored height values into it.

    Raises
    ------
    ReaderError
        If no unit is known (pass ``file_units``), or the file states one and ``file_units`` is given too.
    """
    lateral = stated_or_given(path, found_units, file_units, "file_units")
    if lateral is None:
        raise ReaderError(path, "the file stores no length unit; pass file_units= (e.g. file_units='m' or 'um') "
                                "to open_topography (command line: --file-units)")
    lateral = length_unit(path, lateral, "length unit")
    hu = stated_or_given(path, found_height_units, height_units, "height_units", "the unit of its values") or lateral
    hu = length_unit(path, hu, "height unit")
    return lateral, length_factor(hu, lateral)


def stated_or_given(path, stated: str | None, given: str | None, option: str, what: str = "its length unit"):
    """The unit the file ``stated``, else the one the caller has ``given`` (its option ``option``), else None.

    Raises
    ------
    OptionError
        If the file states ``what`` and the caller gives ``option`` too (no other reader is tried).
    """
    if stated is not None and given is not None:
        raise OptionError(path, f"the file states {what} ({stated!r}); do not pass {option}")
    return stated or given


def stated_length_unit(path, attrs, name: str, height_units=None) -> str | None:
    """The length unit an array's ``units`` (or ``unit``) attribute states (None: it states none).

    ``attrs`` is the array's attribute mapping (text or bytes values). A stated unit that is not a
    length (``"V"``, ``"deg"``) marks a channel that holds no heights: it is refused unless the
    caller says what the values are (``height_units``), rather than read as lengths.

    Raises
    ------
    ReaderError
        For a unit that is not a length when ``height_units`` is not given.
    """
    for key in ("units", "unit"):
        if key in attrs:
            val = attrs[key]
            val = val.decode("utf-8", "replace") if isinstance(val, bytes) else str(val)
            try:
                return normalize_units(val)
            except UnitsError:
                if height_units is None:
                    raise ReaderError(path, f"dataset {name!r} states units {val!r}, which is not a length: it holds "
                                            "no heights (pick another dataset with channel=), or pass height_units= "
                                            "if its values are lengths") from None
                return None
    return None


def container_format(name: str, description: str, suffixes: tuple, sniff, what: str, open_file, arrays, read, errors,
                     priority: int) -> Format:
    """Register (and return) the :class:`Format` ``name`` of container files (HDF5, NetCDF) whose 1D/2D arrays are
    the channels: its ``read`` opens the file, chooses an array, reads it and settles its units.

    Parameters
    ----------
    name, description, suffixes, sniff, priority
        As in :class:`~xtopo.io.registry.Format`.
    what : str
        The kind of file, named in error messages (``"HDF5"``).
    open_file : callable
        ``open_file(path)``: a context manager holding the open file.
    arrays : callable
        ``arrays(f)``: ``[(name, array)]`` of the candidate arrays (objects with a ``shape``), in file order.
    read : callable
        ``read(path, array, name)``: ``(values, attrs)``, the values as a numpy array and the array's attributes.
    errors : tuple of exception types
        What the file library raises on a damaged file (reported as a corrupt ``what`` file).
    """

    def read_array(path, *, channel=None, physical_size=None, file_units=None, height_units=None):
        with open_file(path) as f:
            try:
                entries = arrays(f)
                _, array = pick_array(path, [(n, a.shape) for n, a in entries], channel)
                values, attrs = read(path, dict(entries)[array], array)
                found = stated_length_unit(path, attrs, array, height_units)
            except ReaderError:  # already names the file and the problem (a ValueError too)
                raise
            except errors as exc:
                raise ReaderError(path, f"corrupt {what} file: {exc}") from None
        return generic_measurement(path, values, physical_size=physical_size, file_units=file_units,
                                   height_units=height_units, found_units=found, channel=array)

    def channels(path, **options):
        with open_file(path) as f:
            try:
                return channel_infos(path, [(n, a.shape) for n, a in arrays(f)], **options)
            except ReaderError:
                raise
            except errors as exc:
                raise ReaderError(path, f"corrupt {what} file: {exc}") from None

    return register(Format(name, description, suffixes, sniff, read_array, channels, priority, READ_OPTIONS))


def generic_measurement(path, heights, *, physical_size=None, found_size=None, file_units=None, height_units=None,
                        found_units=None, found_height_units=None, x=None, mask=None, height_scale: float = 1.0,
                        **attrs):
    """A measurement from an array whose metadata come partly from the file, partly from the caller.

    Parameters
    ----------
    heights : numpy.ndarray, 1D or 2D (rows are ``y``)
    physical_size, file_units, height_units
        The caller's options; ``physical_size`` (in the lateral unit) wins over ``found_size``.
    found_size, found_units, found_height_units
        What the file itself states (``None`` where it says nothing).
    x : array_like, optional
        Positions of a line scan (then no size is needed).
    height_scale : float
        Extra factor applied to the values (e.g. a phase-to-height conversion).
    """
    h = np.asarray(heights)
    if h.ndim not in (1, 2) or h.size < 2:  # one value is no measurement (a 1x1 map had a spacing of its size)
        raise ReaderError(path, f"expected a 1D or 2D array of at least 2 heights, got shape {h.shape}")
    if h.dtype.kind not in "fiu":
        raise ReaderError(path, f"heights must be numeric, got dtype {h.dtype}")
    lateral, factor = resolve_units(path, found_units=found_units, found_height_units=found_height_units,
                                    file_units=file_units, height_units=height_units)
    scale = factor * height_scale
    if x is not None:
        if physical_size is not None:
            raise OptionError(path, "the file stores the positions of its line scan; do not pass physical_size")
        return line_measurement(path, x, h.astype(float) * scale, lateral, mask=mask, **attrs)
    size = physical_size if physical_size is not None else found_size
    if size is None:
        shape = "(Ly, Lx)" if h.ndim == 2 else "Lx"
        raise ReaderError(path, f"the file stores no physical size; pass physical_size={shape} "
                                f"(in {lateral}) to open_topography (command line: --physical-size "
                                f"{shape.strip('()').replace(',', '')})")
    try:
        sz = np.broadcast_to(np.asarray(size, dtype=float), (h.ndim,))
    except ValueError:
        raise ReaderError(path, f"physical_size {size!r} does not match a {h.ndim}D measurement") from None
    if not np.all(np.isfinite(sz)) or np.any(sz <= 0):
        raise ReaderError(path, f"physical size must be positive and finite, got {tuple(sz)}")
    if np.any(sz / np.asarray(h.shape) < np.finfo(float).tiny):  # the pixel size underflows: no distinct positions
        raise ReaderError(path, f"physical_size {tuple(sz.tolist())} is too small for {h.shape} pixels "
                                f"(a pixel below {np.finfo(float).tiny:g} {lateral})")
    return make_measurement(h, size=tuple(sz), units=lateral, mask=mask,
                            height_scale=scale, **attrs)


#: Refuse arrays larger than this many bytes (a corrupt or hostile shape field).
MAX_ARRAY_BYTES = 1 << 31
#: Preferred variable names when a container holds several arrays and no channel is given.
PREFERRED_NAMES = ("heights", "height", "topography", "data", "z", "Z", "h")


def pick_array(path, entries, channel=None):
    """Choose one array among ``entries`` (a list of ``(name, shape)``) of a container file.

    ``channel`` is a name or an index into the 1D/2D numeric entries; by default the first
    entry with a :data:`PREFERRED_NAMES` name, else the first 1D/2D entry.

    Returns
    -------
    (int, str)
        Index among the candidates and name.

    Raises
    ------
    UnsupportedFormatError
        No 1D/2D array, or ``channel`` does not exist.
    """
    cands = [(n, s) for n, s in entries if len(s) in (1, 2) and int(np.prod(s)) > 1]
    if not cands:
        raise UnsupportedFormatError(path, "contains no 1D or 2D array of heights")
    names = [n for n, _ in cands]
    if channel is None:
        name = next((pref for pref in PREFERRED_NAMES if pref in names), names[0])
        return names.index(name), name
    if isinstance(channel, (int, np.integer)) and not isinstance(channel, bool):
        if 0 <= channel < len(names):
            return int(channel), names[channel]
    elif str(channel) in names:
        return names.index(str(channel)), str(channel)
    raise UnsupportedFormatError(path, f"channel {channel!r} does not exist; arrays: {names}")


def single_channel(path, channel, names=()) -> None:
    """Refuse any ``channel`` of a single-channel file but ``None``, the index 0 or one of ``names``.

    Raises
    ------
    UnsupportedFormatError
        For any other channel (``0.0`` or ``False`` too, which equal 0 but are no index).
    """
    index = isinstance(channel, numbers.Integral) and not isinstance(channel, (bool, np.bool_))
    if channel is None or (index and channel == 0) or (isinstance(channel, str) and channel in names):
        return
    raise UnsupportedFormatError(path, f"has a single channel; channel {channel!r} does not exist")


def check_array_bytes(path, shape, itemsize: int, available: int | None, what: str) -> None:
    """Refuse an array whose ``shape`` would need more bytes than the file can hold (or than 2 GiB)."""
    try:
        dims = [int(s) for s in shape]
        n = int(np.prod(dims, dtype=object)) * int(itemsize)
    except (TypeError, ValueError, OverflowError):
        raise ReaderError(path, f"invalid shape {shape!r} for {what}") from None
    if any(d < 0 for d in dims):  # read as a negative byte count ("read length must be non-negative")
        raise ReaderError(path, f"invalid shape {tuple(shape)} for {what}: negative size (corrupt header)")
    if n > MAX_ARRAY_BYTES or (available is not None and n > available):
        raise ReaderError(path, f"{what} of shape {tuple(shape)} needs {n} bytes, more than the file holds "
                                "(truncated or corrupt)")


def channel_infos(path, entries, *, physical_size=None, file_units=None, height_units=None, found_units=None):
    """:class:`ChannelInfo` list for the 1D/2D arrays among ``entries`` ``(name, shape)``."""
    units = found_units or file_units
    given = None if physical_size is None else np.atleast_1d(np.asarray(physical_size, dtype=float))
    out = []
    for name, shape in entries:
        if len(shape) in (1, 2) and int(np.prod(shape)) > 1:
            size = None  # also where the given size does not fit (two lengths, a 1D array): reading it refuses them
            if given is not None and given.size in (1, len(shape)):
                size = tuple(np.broadcast_to(given, (len(shape),)).tolist())
            out.append(ChannelInfo(index=len(out), name=str(name), shape=tuple(int(s) for s in shape), size=size,
                                   units=units, height_units=height_units or units))
    return out
