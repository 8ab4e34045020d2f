"""The NetCDF layout of SurfaceTopography / contact.engineering: read and write.

Layout (as documented by SurfaceTopography's NetCDF reader):

* a variable ``heights``; dims ``(x, y)`` for a map — note the order, the first index is
  ``x`` — ``(x,)`` for a uniform line scan, ``(n,)`` for a nonuniform line scan whose
  positions are the variable ``x(n)``;
* optional variables ``x(x)``, ``y(y)`` with attributes ``length`` (physical size),
  ``periodic`` (0/1) and ``unit`` (length unit; ``heights`` may carry the same ``unit``);
* an optional variable ``mask`` (same dims as ``heights``, nonzero = undefined);
* an optional global attribute ``json`` holding the ``info`` dictionary as JSON.

SurfaceTopography validates ``info`` (``SurfaceTopography.Metadata.InfoModel``): ``instrument``
is a dictionary ``{name, vendor, serial, parameters: {tip_radius, resolution: {value, unit}}}``,
where contact.engineering looks up the tip radius and the resolution for its reliability
analysis, ``acquisition_time`` a date and ``channel_name`` the channel. The writer and the
reader translate between these fields and the attributes of an xtopo measurement
(``instrument``, ``vendor``, ``instrument_serial``, ``tip_radius``/``resolution`` with their
``*_units``, ``acquisition_time``, ``channel``); the other attributes travel as they are.

:func:`to_surfacetopography_netcdf` writes this layout (NetCDF-3 64-bit offset, as
SurfaceTopography does), so files can be uploaded to contact.engineering.
"""

from __future__ import annotations

import datetime
import json
import math
from collections.abc import Mapping
from typing import Annotated

import numpy as np
import xarray as xr

from ...conventions import (height_of, is_nonuniform, is_periodic, lateral_dims, length_factor, normalize_units,
                            periodic_flag, physical_size, shared_length_unit)
from ...errors import ReaderError, UnitsError, UnsupportedFormatError, ValidationError
from .._generic import check_array_bytes, generic_measurement, single_channel
from ..netcdf import atomic_write, read_engine
from ...params import Path, checked
from ..registry import READ_OPTIONS, Format, register
from ._common import sniff_magic

__all__ = ["read_st_netcdf", "to_surfacetopography_netcdf", "instrument_info", "instrument_attrs"]

_OPEN_ERRORS = (OSError, ValueError, KeyError, RuntimeError, TypeError, IndexError, AttributeError, OverflowError)


def _open(path):
    """The file through the engine that reads it safely (:func:`xtopo.io.netcdf.read_engine`)."""
    engine = read_engine(path)  # a NetCDF-3 header claiming more than the file holds: ReaderError
    try:
        return xr.open_dataset(path, engine=engine, mask_and_scale=True, decode_times=False)
    except _OPEN_ERRORS:
        raise UnsupportedFormatError(path, "not a NetCDF file any installed engine can open") from None


def _attr(var, key, default=None):
    val = var.attrs.get(key, default) if var is not None else default
    if isinstance(val, bytes):
        val = val.decode("utf-8", "replace")
    if isinstance(val, np.ndarray) and val.size == 1:
        val = val.item()
    return val


#: xtopo attribute <-> key of ``info["instrument"]`` (SurfaceTopography's InstrumentModel)
_INSTRUMENT = (("instrument", "name"), ("vendor", "vendor"), ("instrument_serial", "serial"))
#: xtopo attributes (each with ``*_units``) <-> keys of ``info["instrument"]["parameters"]``
_PARAMETERS = ("tip_radius", "resolution")
#: xtopo attribute <-> top-level key of ``info`` validated by SurfaceTopography
_TOP = (("acquisition_time", "acquisition_time"), ("channel", "channel_name"))


def _is_time(value) -> bool:
    try:
        datetime.datetime.fromisoformat(str(value))
    except ValueError:
        return False
    return True


def instrument_info(attrs: Mapping, keys: tuple, unit: str) -> dict:
    """The ``instrument`` entry of SurfaceTopography's ``info`` (and of contact.engineering's metadata): the
    text ``attrs`` named in ``keys`` (``(attr, key)`` pairs), then the tip radius and resolution in their
    ``*_units`` (else in ``unit``)."""
    out = {key: str(attrs[a]) for a, key in keys if attrs.get(a) not in (None, "")}
    parameters = {p: {"value": float(attrs[p]), "unit": str(attrs.get(f"{p}_units") or unit) or None}
                  for p in _PARAMETERS if p in attrs}
    return {**out, "parameters": parameters} if parameters else out


def instrument_attrs(instrument, keys: tuple, units: str | None = None) -> dict:
    """The attributes an ``instrument`` entry stands for (the inverse of :func:`instrument_info`): its
    non-empty text ``keys``, and the tip radius and resolution that are positive lengths with a unit
    (converted to ``units`` where given); anything else is left out."""
    if not isinstance(instrument, dict):
        return {}
    out = {a: instrument[key] for a, key in keys if isinstance(instrument.get(key), str) and instrument[key]}
    parameters = instrument.get("parameters")
    for p in _PARAMETERS:
        entry = parameters.get(p) if isinstance(parameters, dict) else None
        if not isinstance(entry, dict):
            continue
        try:
            unit = normalize_units(entry.get("unit"))
            value = float(entry.get("value")) * (1.0 if units is None else length_factor(unit, units))
        except (TypeError, ValueError, UnitsError):  # no number, or no length unit
            continue
        if math.isfinite(value) and value > 0:
            out.update({p: value, f"{p}_units": units or unit})
    return out


def _info_from_attrs(attrs: dict) -> dict:
    """SurfaceTopography's ``info`` from the plain (text/number) attributes of an xtopo measurement."""
    info = {k: v for k, v in attrs.items()
            if k not in {a for a, _ in _INSTRUMENT + _TOP} | {f"{p}{u}" for p in _PARAMETERS for u in ("", "_units")}}
    instrument = instrument_info(attrs, _INSTRUMENT, attrs.get("units", ""))
    if instrument:
        info["instrument"] = instrument
    for a, key in _TOP:
        if a in attrs:
            # SurfaceTopography refuses an acquisition_time that is no date: keep such text under its own key
            info[key if a != "acquisition_time" or _is_time(attrs[a]) else "acquisition_time_text"] = attrs[a]
    return info


def _attrs_from_info(info: dict) -> dict:
    """The xtopo attributes that the fields SurfaceTopography knows in ``info`` stand for (others are left out)."""
    out = instrument_attrs(info.get("instrument"), _INSTRUMENT)  # other values: the JSON (attr st_info) holds them
    for a, key in _TOP:
        if isinstance(info.get(key), str) and info[key]:
            out[a] = info[key]
    return out


def read_st_netcdf(path, *, channel=None, physical_size=None, file_units=None, height_units=None):
    """Read a SurfaceTopography NetCDF file (see the module docstring)."""
    single_channel(path, channel)
    with _open(path) as nc:
        if "heights" not in nc.variables:
            raise UnsupportedFormatError(path, "NetCDF file has no 'heights' variable (not the SurfaceTopography "
                                               "layout)")
        hv = nc["heights"]
        dims = hv.dims
        if dims not in (("x", "y"), ("x",), ("n",)):
            raise UnsupportedFormatError(path, f"'heights' has dims {dims}, not ('x', 'y'), ('x',) or ('n',) "
                                               "(not the SurfaceTopography layout)")
        try:
            check_array_bytes(path, hv.shape, 8, None, "heights")
            h = np.asarray(hv.values, dtype=float)
            mask = np.asarray(nc["mask"].values) != 0 if "mask" in nc.variables else None
            xv, yv = nc.get("x"), nc.get("y")
            xpos = np.asarray(xv.values, dtype=float) if dims == ("n",) and xv is not None else None
        except _OPEN_ERRORS as exc:
            raise ReaderError(path, f"cannot read the data: {exc}") from None
        unit = _attr(xv, "unit") or _attr(hv, "unit")
        hunit = _attr(hv, "unit")
        stored = _attr(xv, "periodic", 0)
        periodic = periodic_flag(stored or 0)
        if periodic is None:
            raise ReaderError(path, f"'x' has periodic={stored!r}; expected 0 or 1 (or the text 'false'/'true')")
        info = nc.attrs.get("json")
    if mask is not None and mask.shape != h.shape:
        raise ReaderError(path, f"'mask' has shape {mask.shape}, 'heights' {h.shape}")
    attrs = {"periodic": periodic}
    if isinstance(info, str):
        try:
            parsed = json.loads(info)
            attrs["st_info"] = info
        except ValueError:
            parsed = None
        if isinstance(parsed, dict):
            attrs.update(_attrs_from_info(parsed))
    common = dict(physical_size=physical_size, file_units=file_units, height_units=height_units,
                  found_units=unit, found_height_units=hunit if hunit and hunit != unit else None, mask=None, **attrs)
    if dims == ("n",):
        if xpos is None:
            raise ReaderError(path, "nonuniform line scan without the position variable 'x'")
        if periodic:
            raise ReaderError(path, "a nonuniform line scan cannot be periodic")
        common.pop("periodic")
        return generic_measurement(path, np.where(mask, np.nan, h) if mask is not None else h, x=xpos, **common)
    lengths = [_attr(v, "length") for v in ((xv, yv) if dims == ("x", "y") else (xv,))]
    found = None
    if all(v is not None for v in lengths):
        found = tuple(float(v) for v in lengths[::-1])  # (Ly, Lx) / (Lx,)
    common["mask"] = mask.T if mask is not None else None
    return generic_measurement(path, h.T, found_size=found, **common)


@checked
def to_surfacetopography_netcdf(ds, path: Annotated[str, Path("file path")], *, info: dict | None = None) -> str:
    """Write a measurement in the SurfaceTopography/contact.engineering NetCDF layout.

    Parameters
    ----------
    ds : xarray.Dataset
        A single measurement (no batch dims): area scan, uniform or nonuniform line scan.
    path : str or os.PathLike
        Target file (NetCDF-3 64-bit offset), written atomically.
    info : dict, optional
        Stored as the global ``json`` attribute (default: the dataset's string/number attrs, those
        SurfaceTopography validates in its own structure: see the module docstring).

    Returns
    -------
    str
        The path written.
    """
    if info is not None and not isinstance(info, Mapping):
        raise ValidationError(f"info must be a dict (written as the file's JSON 'info'), got {type(info).__name__}")
    h = height_of(ds)
    shared_length_unit(h, "to_surfacetopography_netcdf")  # the layout has one unit for heights and positions
    extra = [d for d in h.dims if d not in ("x", "y")]
    if extra:
        raise ValidationError(f"to_surfacetopography_netcdf writes one measurement; select along {extra} first")
    dims = lateral_dims(h)
    unit = h.attrs.get("units") or ds["x"].attrs.get("units")
    values = np.asarray(h.values, dtype=np.float64)
    missing = ~np.isfinite(values)
    periodic = int(is_periodic(ds))
    if info is None:
        info = _info_from_attrs({k: (v.item() if isinstance(v, np.generic) else v) for k, v in ds.attrs.items()
                                 if isinstance(v, (str, int, float, np.integer, np.floating))})
    variables = {}
    if is_nonuniform(ds):
        if missing.any():
            raise ValidationError("a nonuniform line scan with missing data cannot be written in the "
                                  "SurfaceTopography layout; fill or drop the missing points first")
        variables["x"] = xr.Variable(("n",), np.asarray(ds["x"].values, dtype=np.float64), {"unit": unit})
        variables["heights"] = xr.Variable(("n",), values, {"unit": unit})
    else:
        st_dims = ("x", "y") if dims == ("y", "x") else ("x",)
        data = values.T if dims == ("y", "x") else values
        variables["heights"] = xr.Variable(st_dims, data, {"unit": unit})
        if missing.any():
            variables["mask"] = xr.Variable(st_dims, (missing.T if dims == ("y", "x") else missing).astype(np.int8))
        for d in st_dims:
            n = ds.sizes[d]
            L = physical_size(ds, d)
            variables[d] = xr.Variable((d,), np.arange(n) * (L / n),
                                       {"length": float(L), "periodic": periodic, "unit": unit})
    out = xr.Dataset(variables, attrs={"json": json.dumps(info, default=str)})
    encoding = {name: {"_FillValue": None} for name in out.variables}
    return atomic_write(path, lambda tmp: out.to_netcdf(tmp, format="NETCDF3_64BIT", engine="scipy",
                                                        encoding=encoding))


register(Format("st-netcdf", "SurfaceTopography / contact.engineering NetCDF layout", (".nc",),
                sniff_magic(b"CDF", b"\x89HDF\r\n\x1a\n"), read_st_netcdf, priority=1, options=READ_OPTIONS))
