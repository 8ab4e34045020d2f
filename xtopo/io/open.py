"""``open_topography``: detect the format, read, and normalise to the data model."""

from __future__ import annotations

import hashlib
import os
from typing import Annotated

import numpy as np

from .._checks import per_axis
from ..conventions import append_history, convert_length, lateral_dims, validate
from ..conventions import physical_size as _physical_size
from ..errors import OptionError, ReaderError, UnsupportedFormatError, XtopoError
from ..params import Flag, Lengths, LengthUnit, Positive, checked
from .registry import ChannelInfo, detect

__all__ = ["open_topography", "channels", "sha256"]

#: the declared kinds of the reading options (checked before a file is read; batch pre-flights them)
_SIZE, _UNIT = Lengths(empty=False), LengthUnit(optional=True)


def sha256(path) -> str:
    """Hex SHA-256 of a file's bytes."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


@checked
def open_topography(path, *, channel=None, units: Annotated[str | None, _UNIT] = "m",
                    periodic: Annotated[bool | None, Flag()] = None, tip_radius: Annotated[float | None, Positive()] = None,
                    resolution: Annotated[float | None, Positive()] = None, format: str | None = None,
                    physical_size: Annotated[np.ndarray | None, _SIZE] = None,
                    file_units: Annotated[str | None, _UNIT] = None, height_units: Annotated[str | None, _UNIT] = None):
    """Read a measurement file into an xtopo measurement Dataset.

    Parameters
    ----------
    path : str or os.PathLike
        The file. Its format is detected from its content; the suffix is a hint.
    channel : int or str, optional
        Channel index or name for multi-channel files (default: the first height channel).
    units : str or None
        Length unit of the result (``"m"`` by default); ``None`` keeps the file's unit.
    periodic : bool, optional
        Override the file's (or default nonperiodic) periodicity.
    tip_radius, resolution : float, optional
        Probe tip radius / lateral resolution **in the result's units**.
    format : str, optional
        Force a format by name (see :func:`xtopo.io.registry.formats`).
    physical_size : float or tuple of float, optional
        Physical size ``(Ly, Lx)`` (area) or ``Lx`` (line) in ``file_units`` for generic files, in the
        file's own length unit otherwise. Required for generic files that store none (plain text matrix,
        npy, MATLAB, HDF5); for files that do store one it replaces the stored size (recorded in
        ``history``).
    file_units : str, optional
        Length unit of positions and heights for generic files that store no unit (plain text,
        npy, MATLAB, HDF5). Files that state their unit refuse this option.
    height_units : str, optional
        Length unit of the stored height values when it differs from ``file_units``
        (e.g. positions in ``"mm"``, heights in ``"um"``).

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    ReaderError
        The file is unreadable or corrupt (the message names the file).
    UnsupportedFormatError
        No reader recognises the content.
    """
    path = _path(path)
    to, lengths = units, {k: v for k, v in (("tip_radius", tip_radius), ("resolution", resolution)) if v is not None}
    options = {"physical_size": physical_size, "file_units": file_units, "height_units": height_units}
    fmt, ds = _first_success(path, format, "read", channel=channel, **options)
    if physical_size is not None and "physical_size" not in fmt.options:
        ds = _override_size(ds, physical_size, path)
    if "height" in ds and ds["height"].attrs.get("quantity") == "signal":  # e.g. phase, amplitude, current
        raise UnsupportedFormatError(
            path, f"channel {ds.attrs.get('channel')!r} holds {ds['height'].attrs.get('units')!r} values, not "
                  f"heights; pick a height channel, or read the signal with "
                  f"xtopo.io.list_formats()[{fmt.name!r}].read(path, channel=...)")
    own = fmt.name == "netcdf" and "xtopo_version" in ds.attrs  # an archive written by xtopo: keep as is
    if not own or not ds.attrs.get("source_file"):  # an archive of data from no file (synthetic) is the source
        for key, value in (("source_file", lambda: os.path.basename(path)), ("source_format", lambda: fmt.name),
                           ("source_sha256", lambda: sha256(path))):
            if not ds.attrs.get(key):
                ds.attrs[key] = value()
    if to is not None:
        try:
            ds = convert_length(ds, to)
        except XtopoError as exc:
            raise ReaderError(path, f"cannot convert the {fmt.name} reader's result to {units!r}: {exc}") from exc
    if periodic is not None:
        ds.attrs["periodic"] = int(periodic)
    u = ds["height"].attrs.get("units")
    for key, val in lengths.items():
        ds.attrs[key] = val
        ds.attrs[f"{key}_units"] = u
    if not own:
        ds = append_history(ds, f"open_topography({os.path.basename(path)!r}, format={fmt.name!r}, channel={channel!r})")
    try:
        return validate(ds)
    except XtopoError as exc:
        raise ReaderError(path, f"the {fmt.name} reader produced an invalid measurement: {exc}") from exc


def _path(path) -> str:
    """``path`` as a str (a ReaderError for anything that is not a path)."""
    try:
        return os.fspath(path)
    except TypeError:
        raise ReaderError(None, f"expected a file path (str or os.PathLike), got {type(path).__name__}") from None


def _call(path, fmt, method: str, channel, options: dict):
    """Call ``fmt.read``/``fmt.channels`` with the options the format declares; refuse the others."""
    given = {k: v for k, v in options.items() if v is not None}
    refused = [k for k in given if k not in fmt.options and k != "physical_size"]
    if refused:
        # refused only if the file is of this format: otherwise its "not this format" reason counts
        # (an HDF5 file without heights was reported as a NetCDF file given file_units=)
        _call(path, fmt, method, channel, {})
        raise OptionError(path, f"the {fmt.name} format stores its own units; the option(s) {', '.join(refused)} "
                                "apply only to generic formats without units (text, npy, MATLAB, HDF5)")
    kwargs = {k: v for k, v in given.items() if k in fmt.options}
    if method == "read":
        return fmt.read(path, channel=channel, **kwargs)
    if fmt.channels is None:
        return [_describe(fmt.read(path, channel=None, **kwargs))]
    return fmt.channels(path, **kwargs)


def _first_success(path, format, method: str, channel=None, **options):
    """Try the candidate formats best first; return ``(format, result)`` of the first that works.

    Errors that say "not this format" (:class:`UnsupportedFormatError`) give way to a later
    candidate; if all fail, the most specific error (a corrupt-file error before a
    not-this-format one) is raised; when every candidate said "not this format", their reasons are
    listed. Non-xtopo exceptions of a reader become :class:`ReaderError`.
    """
    candidates = detect(path, format)
    errors = []
    for fmt in candidates:
        try:
            return fmt, _call(path, fmt, method, channel, options)
        except OptionError:  # this is the file's format: a more generic reader would misread it with the option
            raise
        except ReaderError as exc:
            errors.append((fmt.name, exc))
        except XtopoError as exc:  # e.g. a GridError from make_measurement: name the file
            errors.append((fmt.name, ReaderError(path, f"{fmt.name}: {exc}")))
        except (MemoryError, RecursionError) as exc:
            raise ReaderError(path, f"{fmt.name} reader gave up: {type(exc).__name__}") from None
        except Exception as exc:  # defensive: a reader bug must not escape as a random type
            raise ReaderError(path, f"{fmt.name} reader failed on malformed content: "
                                    f"{type(exc).__name__}: {exc}") from exc
    specific = [e for _, e in errors if not isinstance(e, UnsupportedFormatError)]
    reasons = {}
    for name, e in errors:
        reasons.setdefault(e.reason, []).append(name)
    if not specific and len(reasons) > 1:  # every candidate said "not this format": give each one's reason
        raise UnsupportedFormatError(path, "no reader accepts the content: " + "; ".join(
            f"{', '.join(names)}: {reason}" for reason, names in reasons.items()))
    raise (specific or [e for _, e in errors])[0]


def _override_size(ds, physical_size, path):
    """Replace the physical size of a uniform measurement (``physical_size`` in the reader's length unit)."""
    if ds.attrs.get("grid") == "nonuniform":
        raise ReaderError(path, "physical_size= cannot be given for a nonuniform line scan (its positions are stored)")
    dims = lateral_dims(ds["height"])
    size = per_axis(physical_size, len(dims), "physical_size")
    u = ds["height"].attrs["units"]
    for dim, L in zip(dims, size):
        n = ds.sizes[dim]
        c = ds.coords[dim]
        ds = ds.assign_coords({dim: (dim, np.arange(n) * (L / n), {**c.attrs, "spacing": float(L / n)})})
    return append_history(ds, f"physical size set to {tuple(float(v) for v in size)} {u} by the caller")


def _describe(ds) -> ChannelInfo:
    """A :class:`ChannelInfo` for a measurement Dataset (formats without a ``channels`` function)."""
    h = ds["height"]
    dims = lateral_dims(h)
    u = h.attrs.get("units")
    size = tuple(_physical_size(ds, d) for d in dims)  # a nonuniform scan: last minus first position
    return ChannelInfo(index=0, name=str(ds.attrs.get("channel", ds.attrs.get("title", "height"))),
                       shape=tuple(ds.sizes[d] for d in dims), size=size, units=u, height_units=u)


@checked
def channels(path, *, format: str | None = None, physical_size: Annotated[np.ndarray | None, _SIZE] = None,
             file_units: Annotated[str | None, _UNIT] = None,
             height_units: Annotated[str | None, _UNIT] = None) -> list[ChannelInfo]:
    """The channels of a measurement file, as :class:`~xtopo.io.registry.ChannelInfo` (one per channel).

    Formats with a single channel return one entry. Options as in :func:`open_topography`.

    Raises
    ------
    ReaderError, UnsupportedFormatError
        As :func:`open_topography`.
    """
    path = _path(path)
    _, out = _first_success(path, format, "channels", physical_size=physical_size, file_units=file_units,
                            height_units=height_units)
    return list(out)
