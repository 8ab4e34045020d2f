"""``open_topography``: detect the format, read, and normalise to the data model."""

from __future__ import annotations

import hashlib
import os

import numpy as np

from ..conventions import append_history, convert_length, normalize_units, validate
from ..errors import ReaderError, UnsupportedFormatError, XtopoError
from .registry import detect

__all__ = ["open_topography", "sha256"]


def sha256(path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def open_topography(path, *, channel=None, units: str | None = "m", periodic: bool | None = None,
                    tip_radius: float | None = None, resolution: float | None = None, format: str | None = None):
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
    path = os.fspath(path)
    candidates = detect(path, format)
    errors = []
    for fmt in candidates:
        try:
            ds = fmt.read(path, channel=channel)
            break
        except XtopoError as exc:
            errors.append(exc)
            if len(candidates) == 1:
                raise
        except (MemoryError, RecursionError) as exc:
            raise ReaderError(path, f"{fmt.name} reader gave up: {type(exc).__name__}") from None
        except Exception as exc:  # defensive: a reader bug must not escape as a random type
            raise ReaderError(path, f"{fmt.name} reader failed on malformed content: "
                                    f"{type(exc).__name__}: {exc}") from exc
    else:
        raise errors[0]
    if "height" in ds and ds["height"].attrs.get("quantity") == "signal":  # e.g. phase, amplitude, current
        raise UnsupportedFormatError(
            path, f"channel {ds.attrs.get('channel')!r} holds {ds['height'].attrs.get('units')!r} values, not "
                  f"heights; pick a height channel, or read the signal with "
                  f"xtopo.io.list_formats()[{fmt.name!r}].read(path, channel=...)")
    own = fmt.name == "netcdf" and "xtopo_version" in ds.attrs  # an archive written by xtopo: keep as is
    if not own:
        ds.attrs.setdefault("source_file", os.path.basename(path))
        ds.attrs.setdefault("source_format", fmt.name)
        ds.attrs.setdefault("source_sha256", sha256(path))
    if units is not None:
        ds = convert_length(ds, normalize_units(units))
    if periodic is not None:
        ds.attrs["periodic"] = int(bool(periodic))
    u = ds["height"].attrs.get("units")
    for key, val in (("tip_radius", tip_radius), ("resolution", resolution)):
        if val is not None:
            val = float(val)
            if not (np.isfinite(val) and val > 0):
                raise XtopoError(f"{key} must be a positive length, got {val!r}")
            ds.attrs[key] = val
            ds.attrs[f"{key}_units"] = u
    if not own:
        ds = append_history(ds, f"open_topography({os.path.basename(path)!r}, format={fmt.name!r}, channel={channel!r})")
    return validate(ds)
