"""Names, units and grid helpers of the xtopo data model (DESIGN.md §2).

A *measurement* is an :class:`xarray.Dataset` with

* a ``height`` variable on dims ``("y", "x")`` (area scan) or ``("x",)`` (line scan),
* coordinates ``x`` (and ``y``) at the pixel starts, ``x_m = m Δx``, so that the
  physical size is ``L = N Δx``,
* one length unit (UDUNITS string, e.g. ``"m"``, ``"um"``, ``"nm"``) shared by
  ``x``, ``y`` and ``height``,
* an optional boolean ``mask`` (``True`` where the instrument gave no data),
* attributes ``periodic`` (0/1), ``tip_radius``/``resolution`` (in the dataset's
  length unit), ``instrument``, ``vendor``, ``acquisition_time``, ``source_file``,
  ``source_sha256``, ``history`` and ``Conventions``.

Nonuniform line scans have a strictly increasing, non-equidistant ``x`` and the
attribute ``grid="nonuniform"``.
"""

from __future__ import annotations

import numbers
import re
import unicodedata
from typing import Annotated

import numpy as np
import xarray as xr

from ._checks import per_axis, real_array
from ._units import length_factor, normalize_units  # noqa: F401 - part of conventions' API
from .errors import GridError, UnitsError, ValidationError
from .params import Flag, LengthUnit, Positive, Real, checked

__all__ = [
    "HEIGHT", "MASK", "X", "Y", "LATERAL_DIMS", "CONVENTIONS",
    "LENGTH_ATTRS", "MEASUREMENT_ATTRS",
    "normalize_units", "length_factor", "convert_length",
    "spacing", "physical_size", "is_uniform", "is_periodic", "length_attr", "is_nonuniform",
    "lateral_dims", "height_of", "make_measurement", "validate", "append_history", "length_units_of",
    "shared_length_unit",
    "PROVENANCE_ATTRS", "provenance_of", "periodic_flag",
]

HEIGHT = "height"
MASK = "mask"
X = "x"
Y = "y"
LATERAL_DIMS = (Y, X)
CONVENTIONS = "CF-1.12, ACDD-1.3"

#: Dataset attributes that hold a length in the dataset's length unit.
LENGTH_ATTRS = ("tip_radius", "resolution")
#: Attributes that describe the measurement as a whole and travel with ``height`` (and key cached results).
MEASUREMENT_ATTRS = ("periodic", "tip_radius", "resolution", "grid", "instrument", "tip_radius_units",
                     "resolution_units")

_LONG_NAMES = {X: "position x", Y: "position y", HEIGHT: "height"}

#: attributes of a coordinate or a length variable that hold lengths in its ``units`` (converted with it)
_LENGTH_VALUED = ("valid_min", "valid_max", "actual_range", "spacing")


def _scale_attr_units(attrs: dict, factor_units: str, to: str) -> dict:
    """``attrs`` of a length variable in ``factor_units`` moved to ``to``: ``units`` and every length-valued attr
    (``spacing`` too: left in the file's unit, di-3 read in m had spacing 0.039 against positions 3.9e-8 apart)."""
    out = dict(attrs)
    for key in _LENGTH_VALUED:
        if key in out:
            out[key] = np.asarray(out[key]) * length_factor(factor_units, to)
    out["units"] = to
    return out


@checked
def convert_length(ds: xr.Dataset | xr.DataArray, units: Annotated[str, LengthUnit()]):
    """Convert coordinates, heights and length attributes to ``units``.

    Works on a measurement Dataset or on a height DataArray whose coords carry
    ``units``. Each length is converted from its own unit (heights in nm on positions in µm
    end up in one unit); the original units are recorded in ``history``.

    Parameters
    ----------
    ds : xarray.Dataset or xarray.DataArray
        A measurement or a height DataArray (lengths in any unit pint knows).
    units : str
        Target length unit (UDUNITS spelling: ``"m"``, ``"um"``, ``"nm"``, ...); ``x``, ``y``,
        the length-valued variables (``height``) and the length attributes (``tip_radius``,
        ``resolution``, in their ``*_units`` or else the positions' unit) are converted together.
    """
    to = units
    obj = _xarray(ds).copy(deep=False)
    current = length_units_of(obj)  # the unit of whatever length carries no label of its own
    sources = set()

    def own(label):
        """The normalised length unit ``label`` (None: not a length, so not converted)."""
        if label is None:
            return current
        try:
            return normalize_units(label)
        except UnitsError:
            return None

    for name in (X, Y):
        if name in obj.coords:
            c = obj.coords[name]
            u = own(c.attrs.get("units"))
            if u is not None and u != to:
                sources.add(u)
                obj = obj.assign_coords({name: c.copy(data=c.values * length_factor(u, to))})
                obj.coords[name].attrs = _scale_attr_units(c.attrs, u, to)
    variables = [obj] if isinstance(obj, xr.DataArray) else [obj[v] for v in obj.data_vars]
    for var in variables:
        u = own(var.attrs["units"]) if var.attrs.get("units") is not None and var.dtype.kind == "f" else None
        if u is not None and u != to:
            sources.add(u)
            scaled = (var * length_factor(u, to)).assign_attrs(_scale_attr_units(var.attrs, u, to))
            if isinstance(obj, xr.DataArray):
                obj = scaled  # arithmetic keeps the name
            else:
                obj[var.name] = scaled
    for key in LENGTH_ATTRS:
        if obj.attrs.get(key) is not None:
            u = own(obj.attrs.get(f"{key}_units"))
            if u is None:
                raise UnitsError(f"convert_length: attribute {key}_units={obj.attrs[f'{key}_units']!r} is not a "
                                 "length unit")
            if u != to:
                sources.add(u)
                obj.attrs[key] = float(obj.attrs[key]) * length_factor(u, to)
            obj.attrs[f"{key}_units"] = to
    if not sources:
        return obj
    return append_history(obj, f"convert_length(units={to!r}) from {', '.join(map(repr, sorted(sources)))}")


def _xarray(obj):
    """``obj`` if it is an xarray object (Dataset, DataArray or DataTree), else a :class:`ValidationError`."""
    if not isinstance(obj, (xr.Dataset, xr.DataArray, xr.DataTree)):
        raise ValidationError(f"expected a topography (xarray Dataset with a {HEIGHT!r} variable, or its DataArray), "
                              f"got {type(obj).__name__}")
    return obj


def length_units_of(obj) -> str:
    """The length unit of ``obj``: its lateral coordinates' ``units``, else its heights'.

    Raises
    ------
    UnitsError
        If neither carries one.
    """
    _xarray(obj)
    for name in (X, Y):
        if name in obj.coords and "units" in obj.coords[name].attrs:
            return normalize_units(obj.coords[name].attrs["units"])
    h = obj if isinstance(obj, xr.DataArray) else obj.get(HEIGHT)
    if h is not None and "units" in h.attrs:
        return normalize_units(h.attrs["units"])
    raise UnitsError("the data carry no length unit (coordinate attr 'units')")


def _one_unit_hint(height_units, coord_units) -> str:
    """How to make heights in ``height_units`` and coordinates in ``coord_units`` share one unit (advice)."""
    try:
        coord_units = normalize_units(coord_units)
    except UnitsError:
        return (f"label the coordinates with the length unit of their values, e.g. "
                f"ds.x.attrs['units'] = {height_units!r} (.topo.to_units needs that label to convert them)")
    return (f"convert them to one, e.g. ds.topo.to_units({coord_units!r}) (each length from its own unit), "
            "or read the file with open_topography(..., height_units=...)")


def shared_length_unit(h: xr.DataArray, what: str = "topography") -> str:
    """The one length unit of the heights ``h`` and their lateral coordinates (``"1"`` when none is labelled).

    Heights and positions in different units would be mixed by any analysis (a height in nm
    read as µm: Sq 1000x, slopes 1000x), so they must agree where both are labelled.

    Parameters
    ----------
    h : xarray.DataArray
        Heights (e.g. from :func:`height_of`).
    what : str
        Names the data in the error (``"topography"``, ``"counter"``, the analysis).

    Returns
    -------
    str
        The normalised unit (UDUNITS ASCII, e.g. ``"um"``).

    Raises
    ------
    UnitsError
        If a label is not a length unit, or the labels disagree.
    """
    labelled = {}
    for name, var in [("height", h)] + [(f"coordinate {d!r}", h.coords[d]) for d in LATERAL_DIMS if d in h.coords]:
        if var.attrs.get("units"):
            try:
                labelled[name] = normalize_units(var.attrs["units"])
            except UnitsError as exc:
                raise UnitsError(f"{what}: the {name} has units {var.attrs['units']!r}, which is not a length unit "
                                 f"({exc})") from None
    if len(set(labelled.values())) > 1:
        found = ", ".join(f"{name} in {u!r}" for name, u in labelled.items())
        coord = next(u for name, u in labelled.items() if name != "height")
        raise UnitsError(f"{what}: {found}; heights and positions need one length unit: "
                         f"{_one_unit_hint(labelled.get('height'), coord)}")
    return next(iter(labelled.values()), "1")


def lateral_dims(obj) -> tuple[str, ...]:
    """The lateral dims present, in canonical order: ``("y", "x")`` or ``("x",)``."""
    dims = _xarray(obj).dims
    present = tuple(d for d in LATERAL_DIMS if d in dims)
    if X not in present:
        raise GridError(f"no 'x' dimension (dims are {tuple(dims)}); rename your lateral dims to 'x'/'y'")
    return present


def is_nonuniform(obj) -> bool:
    """True for a nonuniform line scan (``grid="nonuniform"``)."""
    return _xarray(obj).attrs.get("grid") == "nonuniform"


@checked
def is_uniform(coord, rtol: Annotated[float, Real(0.0)] = 1e-6) -> bool:
    """True if the coordinate values are equally spaced within ``rtol``."""
    v = real_array(coord)
    if v is None or v.ndim != 1:
        raise GridError(f"is_uniform needs a 1D sequence of positions (a coordinate), got {coord!r}")
    if v.size < 3:
        return True
    d = np.diff(v)
    return bool(np.all(np.abs(d - d[0]) <= rtol * abs(d[0])))


def spacing(obj, dim: str = X) -> float:
    """Grid spacing Δ along ``dim`` from the coordinate (never assumed to be 1).

    A single-pixel axis takes the coordinate attribute ``spacing``.

    Raises
    ------
    GridError
        If the coordinate is missing, nonuniform, or not increasing.
    """
    if not isinstance(dim, str):
        raise GridError(f"dim must be the name of a lateral dimension ('x' or 'y'), got {dim!r}")
    if dim not in _xarray(obj).coords:
        raise GridError(f"dimension {dim!r} has no coordinate; assign physical positions first")
    c = obj.coords[dim]
    v = np.asarray(c.values, dtype=float)
    if v.size < 2:
        if "spacing" in c.attrs:
            return float(c.attrs["spacing"])
        raise GridError(f"cannot infer the spacing of {dim!r} from a single point; set coord attr 'spacing'")
    d = (v[-1] - v[0]) / (v.size - 1)
    if not d > 0 or not np.isfinite(d):
        raise GridError(f"coordinate {dim!r} must be strictly increasing and finite")
    if not is_uniform(v):
        raise GridError(f"coordinate {dim!r} is not uniformly spaced; this operation needs a uniform grid "
                        "(interpolate explicitly, e.g. with .interp)")
    return float(d)


def physical_size(obj, dim: str = X) -> float:
    """Physical size ``L = N Δ`` along ``dim`` (for nonuniform scans: last minus first position)."""
    if is_nonuniform(obj) and isinstance(dim, str) and dim in obj.coords:
        v = np.asarray(obj.coords[dim].values, dtype=float)
        return float(v[-1] - v[0])
    return spacing(obj, dim) * obj.sizes[dim]  # spacing checks obj and dim first


def is_periodic(obj) -> bool:
    """The ``periodic`` attribute as a bool (absent means nonperiodic).

    Accepted: 0 or 1 as any integer, float or bool type (a one-element array too), and the
    text ``"0"``, ``"1"``, ``"false"``, ``"true"`` (any case; NetCDF has no boolean attribute).
    :func:`validate` accepts exactly what this accepts.

    Raises
    ------
    ValidationError
        If the attribute is anything else (``2``, ``0.5``, ``"yes"``, ...).
    """
    value = _xarray(obj).attrs.get("periodic", 0)
    periodic = periodic_flag(value)
    if periodic is None:
        raise ValidationError(f"attr 'periodic' must be 0 or 1 (a bool, or the text '0', '1', 'false' or 'true'), "
                              f"got {value!r}")
    return periodic


_PERIODIC_TEXT = {"0": False, "1": True, "false": False, "true": True}


def periodic_flag(value) -> bool | None:
    """``value`` as a bool if it spells 0 or 1, else None.

    Files store the flag in many ways: ints of any width, bools, a one-element array
    (some HDF5 writers), or text ("1", "true"; NetCDF has no boolean attribute type).
    Numbers other than 0 and 1 (2, 0.5) and any other text ("yes", "1.0") are refused.
    """
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(()).item()
    if isinstance(value, (bytes, np.bytes_)):
        try:
            value = value.decode("ascii")
        except UnicodeDecodeError:
            return None
    if isinstance(value, str):
        return _PERIODIC_TEXT.get(value.strip().lower())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, numbers.Real) and value in (0, 1):
        return bool(value)
    return None


def length_attr(obj, key: str):
    """A length attribute (``tip_radius``, ``resolution``) as a positive float, or None when absent.

    Raises
    ------
    ValidationError
        If the attribute is not a positive finite number.
    """
    if not isinstance(key, str):
        raise ValidationError(f"key must be the name (str) of a length attribute, e.g. 'tip_radius', got {key!r}")
    value = obj.attrs.get(key)
    if value is None:
        return None
    try:
        val = float(value)
    except (TypeError, ValueError, OverflowError):
        val = np.nan
    if not (np.isfinite(val) and val > 0):
        raise ValidationError(f"attr {key!r} must be a positive length, got {value!r}")
    return val


def _check_height_values(h, error: type[ValidationError | GridError] = ValidationError):
    """``h`` (a DataArray or an array) if it holds real numbers (not complex, text or bool) and at least one point,
    else an ``error``."""
    if h.dtype.kind not in "iuf":
        raise error(f"{HEIGHT!r} must hold real numbers, got dtype {h.dtype}")
    if h.size == 0:
        raise error(f"{HEIGHT!r} has no points (shape {h.shape})")
    return h


def height_of(obj) -> xr.DataArray:
    """The height DataArray of a measurement, with missing data as NaN.

    For a Dataset, the measurement attributes (``periodic``, ``tip_radius``, ...)
    are copied onto the returned DataArray so that functions on DataArrays see them.

    Raises
    ------
    ValidationError
        If ``obj`` is not a Dataset with a ``height`` variable or a DataArray, or its heights
        are not real numbers (complex, text, bool) or have no points.
    """
    if isinstance(obj, xr.DataArray):
        return _check_height_values(obj)
    if not isinstance(_xarray(obj), xr.Dataset):
        raise ValidationError(f"expected a topography (xarray Dataset with a {HEIGHT!r} variable, or its DataArray), "
                              f"got a {type(obj).__name__}")
    if HEIGHT not in obj:
        raise ValidationError(f"the Dataset has no {HEIGHT!r} variable (variables: {list(obj.data_vars)})")
    h = _check_height_values(obj[HEIGHT])
    if MASK in obj:
        h = h.where(~obj[MASK].astype(bool))
    else:  # a new variable: the attrs set below must not land on the Dataset's own height
        h = h.copy(deep=False)
    own = obj[HEIGHT].attrs
    h.attrs = {**own, **{k: obj.attrs[k] for k in MEASUREMENT_ATTRS if k in obj.attrs and k not in own}}
    h.name = HEIGHT
    return h


#: Attributes that say where a measurement came from and what was done to it: every result computed
#: from it (analyses, contact solutions) carries them on.
PROVENANCE_ATTRS = ("source_file", "source_sha256", "history")


def provenance_of(obj) -> dict:
    """The :data:`PROVENANCE_ATTRS` that ``obj`` (a Dataset or DataArray) has set."""
    attrs = getattr(obj, "attrs", {})
    return {k: attrs[k] for k in PROVENANCE_ATTRS if attrs.get(k)}


def append_history(obj, line: str):
    """Return ``obj`` with ``line`` appended to its ``history`` attribute (one line per step)."""
    obj = _xarray(obj).copy(deep=False)
    hist = obj.attrs.get("history", "")
    if isinstance(hist, np.ndarray):  # some readers give text attrs as arrays of lines
        hist = "\n".join(str(v) for v in hist.ravel())
    hist = str(hist).rstrip("\n") if hist is not None else ""
    obj.attrs["history"] = f"{hist}\n{line}" if hist else line
    return obj


def length_coord(name: str, values, units: str, long_name: str, **attrs) -> xr.Variable:
    """The coordinate variable ``name`` of ``values`` (float) with ``units``, ``long_name`` and further ``attrs``."""
    return xr.Variable((name,), np.asarray(values, dtype=float), {"units": units, "long_name": long_name, **attrs})


_ATTR_LENGTH = Positive(error=ValidationError)


@checked
def make_measurement(height, *, size=None, spacing=None, x=None, units: Annotated[str, LengthUnit()] = "m",
                     periodic: Annotated[bool, Flag(error=ValidationError)] = False, mask=None,
                     tip_radius: Annotated[float | None, _ATTR_LENGTH] = None,
                     resolution: Annotated[float | None, _ATTR_LENGTH] = None,
                     height_scale: Annotated[float, Real()] = 1.0, name: str | None = None, **attrs) -> xr.Dataset:
    """Build a measurement Dataset from a height array.

    Parameters
    ----------
    height : array_like, shape (ny, nx) or (nx,)
        Heights in ``units`` (after multiplication by ``height_scale``).
    size : float or tuple of float, optional
        Physical size ``(Ly, Lx)`` (or ``Lx`` for a line scan) in ``units``.
    spacing : float or tuple of float, optional
        Pixel size ``(Δy, Δx)`` (or ``Δx``) in ``units``; alternative to ``size``.
    x : array_like, optional
        Explicit positions of a (possibly nonuniform) line scan in ``units``.
    units : str
        Length unit of positions and heights (UDUNITS string).
    periodic : bool
        Whether the measurement is periodic.
    mask : array_like of bool, optional
        ``True`` where data are missing; NaNs in ``height`` are masked too.
    tip_radius, resolution : float, optional
        Probe tip radius and lateral resolution in ``units``.
    height_scale : float
        Factor applied to ``height`` (e.g. a raw-count-to-length scale).
    name : str, optional
        Stored as attribute ``title``.
    **attrs
        Further attributes (``instrument``, ``vendor``, ...).

    Returns
    -------
    xarray.Dataset
    """
    h = np.asarray(height)
    if h.ndim not in (1, 2):
        raise GridError(f"height must be 1D or 2D, got shape {h.shape}")
    _check_height_values(h, GridError)
    h = h.astype(np.float64 if h.dtype.kind in "iu" or h.dtype.itemsize > 4 else h.dtype, copy=False)
    if height_scale == 0:
        raise ValidationError("height_scale must be a finite number other than 0 (it multiplies the heights), got 0")
    if height_scale != 1.0:
        h = h * height_scale
    dims = (Y, X) if h.ndim == 2 else (X,)
    coords = {}
    grid_attrs = {}
    if x is not None:
        if h.ndim != 1:
            raise GridError("explicit x positions are only supported for line scans")
        xv = np.asarray(x, dtype=float)
        if xv.shape != h.shape:
            raise GridError(f"x has shape {xv.shape} but height has shape {h.shape}")
        if not np.all(np.isfinite(xv)) or np.any(np.diff(xv) <= 0):
            raise GridError("x positions must be finite and strictly increasing")
        coords[X] = length_coord(X, xv, units, _LONG_NAMES[X], axis="X")
        if not is_uniform(xv):
            grid_attrs["grid"] = "nonuniform"
    else:
        if (size is None) == (spacing is None):
            raise GridError("give exactly one of size= or spacing= (or x= for a line scan)")
        n = h.shape
        if spacing is not None:
            sp = per_axis(spacing, h.ndim, "spacing")
        else:
            sp = per_axis(size, h.ndim, "size") / np.asarray(n, dtype=float)
        for dim, ni, d in zip(dims, n, sp):
            coords[dim] = length_coord(dim, np.arange(ni) * d, units, _LONG_NAMES[dim], axis=dim.upper(),
                                       spacing=float(d))
    missing = ~np.isfinite(h)
    if mask is not None:
        m = np.asarray(mask, dtype=bool)
        if m.shape != h.shape:
            raise GridError(f"mask has shape {m.shape} but height has shape {h.shape}")
        missing = missing | m
    data_vars = {HEIGHT: (dims, h, {"units": units, "long_name": "height"})}
    if missing.any():
        h = np.where(missing, np.nan, h)
        data_vars[HEIGHT] = (dims, h, {"units": units, "long_name": "height"})
        data_vars[MASK] = (dims, missing, {"long_name": "missing data", "flag_meanings": "missing"})
    ds_attrs = {"Conventions": CONVENTIONS, "periodic": int(periodic), **grid_attrs}
    if name is not None:
        ds_attrs["title"] = str(name)
    for key, value in (("tip_radius", tip_radius), ("resolution", resolution)):
        if value is not None:
            ds_attrs.update({key: value, f"{key}_units": units})
    ds_attrs.update({k: v for k, v in attrs.items() if v is not None})
    return xr.Dataset(data_vars, coords=coords, attrs=ds_attrs)


def validate(ds: xr.Dataset) -> xr.Dataset:
    """Check that ``ds`` follows the measurement data model; return it unchanged.

    Parameters
    ----------
    ds : xarray.Dataset
        A measurement (``height`` on ``("y", "x")`` or ``("x",)``, coordinates with length
        ``units``, optional boolean ``mask``, attrs as in :mod:`xtopo.conventions`).

    Raises
    ------
    ValidationError
        Naming the first violation found.
    """
    if not isinstance(ds, xr.Dataset):
        raise ValidationError(f"expected an xarray.Dataset, got {type(ds).__name__}")
    if HEIGHT not in ds.data_vars:
        raise ValidationError(f"missing data variable {HEIGHT!r}")
    h = ds[HEIGHT]
    lat = tuple(d for d in h.dims if d in LATERAL_DIMS)
    if lat not in ((Y, X), (X,)):
        raise ValidationError(f"{HEIGHT!r} must have lateral dims ('y', 'x') or ('x',) in that order, got {h.dims}")
    _check_height_values(h)
    if h.chunks is None:  # lazy (dask) data are not read just to check them
        missing = np.isnan(np.asarray(h.values, dtype=float))
        if MASK in ds and ds[MASK].dtype == bool and ds[MASK].dims == h.dims:
            missing |= np.asarray(ds[MASK].values)
        if missing.all():
            raise ValidationError(f"{HEIGHT!r} has no valid value: all {h.size} points are NaN or masked; "
                                  "this is no measurement")
    try:
        units = normalize_units(h.attrs.get("units"))
    except UnitsError as exc:
        raise ValidationError(f"{HEIGHT!r} has no valid length 'units' attribute: {exc}") from None
    for dim in lat:
        if dim not in ds.coords:
            raise ValidationError(f"dimension {dim!r} has no coordinate")
        cu = ds.coords[dim].attrs.get("units")
        try:
            same = cu is not None and normalize_units(cu) == units
        except UnitsError:
            same = False
        if not same:
            raise ValidationError(f"coordinate {dim!r} has units {cu!r}, but heights are in {units!r}; one length "
                                  f"unit per dataset: {_one_unit_hint(units, cu)}")
        v = np.asarray(ds.coords[dim].values, dtype=float)
        if v.size > 1 and np.any(np.diff(v) <= 0):
            raise ValidationError(f"coordinate {dim!r} must be strictly increasing")
        if not is_nonuniform(ds) and not is_uniform(v):
            raise ValidationError(f"coordinate {dim!r} is nonuniform but attr grid='nonuniform' is not set")
    if is_nonuniform(ds) and lat != (X,):
        raise ValidationError("grid='nonuniform' is only allowed for line scans")
    if MASK in ds:
        if ds[MASK].dtype != bool:
            raise ValidationError(f"{MASK!r} must be boolean, got {ds[MASK].dtype}")
        if ds[MASK].dims != h.dims:
            raise ValidationError(f"{MASK!r} dims {ds[MASK].dims} differ from height dims {h.dims}")
    is_periodic(ds)
    for key in LENGTH_ATTRS:
        length_attr(ds, key)
    return ds


_NAME_RE = re.compile(r"[^\w.@+-]")  # \w: letters and digits of any script, and "_"


def safe_name(name: str) -> str:
    """A NetCDF/DataTree-safe variant of ``name`` (used for node and variable names).

    Letters and digits of any script are kept (netCDF-4 names are UTF-8, stored in Unicode
    normal form NFC, to which the name is normalised so that it reads back equal); spaces,
    ``/`` and other punctuation but ``. @ + -`` become ``_``.
    """
    s = _NAME_RE.sub("_", unicodedata.normalize("NFC", str(name))).strip("_")
    return s or "unnamed"
