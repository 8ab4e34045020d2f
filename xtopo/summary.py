"""Per-measurement summary of a twin: what ``xtopo analyze`` prints and stores."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping

import numpy as np
import xarray as xr

from .analysis.scalars import scalars
from .conventions import HEIGHT, MEASUREMENT_ATTRS, convert_length, height_of, is_nonuniform, lateral_dims, physical_size
from ._format import format_length
from ._tree import measurements as tree_measurements
from ._tree import name_of, unique_name
from .errors import GridError, ValidationError

__all__ = ["summary_table", "format_table", "format_percent", "table_rows", "text_table"]


#: the variables of :func:`summary_table` and their attrs, in order
_VARIABLES = {
    "kind": {"long_name": "kind of scan"},
    "instrument": {"long_name": "instrument"},
    "size_x": {"units": "m", "long_name": "physical size in x"},
    "size_y": {"units": "m", "long_name": "physical size in y"},
    "nx": {"units": "1", "long_name": "points in x"},
    "ny": {"units": "1", "long_name": "points in y"},
    "tip_radius": {"units": "m", "long_name": "tip radius"},
    "missing_percent": {"units": "%", "long_name": "missing data"},
    "rms_height": {"units": "m", "long_name": "root mean square height (Sq areas, Rq lines)"},
    "rms_slope": {"units": "1", "long_name": "root mean square gradient (SΔq areas, RΔq lines)"},
    "rms_curvature": {"units": "m-1", "long_name": "root mean square curvature (SΔ²q areas, RΔ²q lines)"},
}


def _row(name: str, ds: xr.Dataset) -> dict:
    """The :data:`_VARIABLES` of one measurement."""
    extra = [d for d in ds[HEIGHT].dims if d not in lateral_dims(ds[HEIGHT])]
    if extra:
        raise GridError(f"measurement {name!r} has extra dims {tuple(extra)}: a summary row is one measurement; "
                        "give each one separately (e.g. one .isel per item of the batch)")
    ds = convert_length(ds, "m")
    h = ds[HEIGHT]
    s = scalars(ds)
    area = h.ndim == 2
    row = {"kind": "area" if area else ("line (nonuniform)" if is_nonuniform(ds) else "line"),
           "size_y": physical_size(ds, "y") if area else np.nan, "size_x": physical_size(ds, "x"),
           "nx": int(h.shape[-1]), "ny": int(h.shape[0]) if area else 1,
           "tip_radius": float(ds.attrs["tip_radius"]) if "tip_radius" in ds.attrs else np.nan,
           "missing_percent": 100 * float((~np.isfinite(height_of(ds))).mean())}  # masked, NaN or inf
    r = s if area else s.sel(direction="x")
    row.update(rms_height=float(r.Sq if area else r.Rq), rms_slope=float(r.Sdq if area else r.Rdq),
               rms_curvature=float(r.Sddq if area else r.Rddq), instrument=str(ds.attrs.get("instrument", "")))
    return row


def _as_measurement(key, m) -> xr.Dataset:
    if isinstance(m, xr.DataArray):  # a height DataArray: the measurement attrs it carries go to the Dataset
        ds = m.to_dataset(name=HEIGHT)
        ds.attrs = {k: m.attrs[k] for k in MEASUREMENT_ATTRS if k in m.attrs}
        return ds
    if not isinstance(m, xr.Dataset) or HEIGHT not in m.data_vars:
        got = type(m).__name__ if not isinstance(m, xr.Dataset) else f"a Dataset without {HEIGHT!r}"
        raise ValidationError(f"measurement {key!r} must be a measurement (xarray.Dataset with a {HEIGHT!r} "
                              f"variable, or its height DataArray), got {got}")
    return m


def _named(measurements) -> dict:
    """Name → measurement Dataset from a mapping, a twin, one measurement or a sequence of them."""
    if isinstance(measurements, xr.DataTree):
        return tree_measurements(measurements)
    if isinstance(measurements, (xr.Dataset, xr.DataArray)):  # one measurement (a Dataset is a Mapping too)
        items = [(None, measurements)]
    elif isinstance(measurements, Mapping):
        return {key: _as_measurement(key, m) for key, m in measurements.items()}
    elif isinstance(measurements, Iterable) and not isinstance(measurements, (str, bytes, os.PathLike)):
        items = [(None, m) for m in measurements]
    else:
        raise ValidationError("summary_table takes measurements as a mapping of name to Dataset, a list of "
                              f"Datasets, one Dataset or a twin (DataTree), got {type(measurements).__name__}")
    out: dict = {}
    for i, (_, m) in enumerate(items):
        ds = _as_measurement(i, m)
        out[unique_name(name_of(ds, i), out)] = ds  # title, source file or instrument, else measurement_<i>
    return out


def summary_table(measurements) -> xr.Dataset:
    """Scalars and grid facts of each measurement, along a ``measurement`` dim (lengths in m).

    Parameters
    ----------
    measurements : dict of str to xarray.Dataset, list of xarray.Dataset, xarray.Dataset or xarray.DataTree
        Name → measurement; or measurements named by their ``title`` (else ``source_file``,
        ``instrument``, else ``measurement_<i>``, made unique with ``_2``, ``_3``, ...); or
        one measurement; or a twin (its measurements). Height DataArrays are accepted in
        place of Datasets.

    Raises
    ------
    ValidationError
        If ``measurements`` or one of them is none of these.
    GridError
        If a measurement has dims other than ``y``/``x`` (a batch).
    """
    named = _named(measurements)
    rows = [_row(name, ds) for name, ds in named.items()]
    data = {k: ("measurement", [r[k] for r in rows], attrs) for k, attrs in _VARIABLES.items()}
    coords = {"measurement": ("measurement", list(named), {"long_name": "measurement"})}
    return xr.Dataset(data, coords=coords, attrs={"title": "measurement summary"})


def format_percent(p: float) -> str:
    """A share in percent with one decimal; a share above 0 that would print as ``0.0 %`` prints ``<0.1 %``
    (116 undefined pixels of 480 × 640 are not "0.0 %" missing: a contact calculation refuses them)."""
    return "<0.1 %" if 0 < p < 0.05 else f"{p:.1f} %"


def table_rows(table: xr.Dataset) -> tuple[list[str], list[list[str]]]:
    """Header and formatted cells of :func:`summary_table` (lengths in readable units)."""
    header = ["measurement", "kind", "size", "grid", "tip radius", "missing", "Sq/Rq", "SΔq/RΔq", "SΔ²q/RΔ²q"]
    if not isinstance(table, xr.Dataset) or "measurement" not in table.dims:
        raise ValidationError(f"expected a table made by summary_table (a Dataset along 'measurement'), "
                              f"got {type(table).__name__}")
    lines = []
    for i in range(table.sizes["measurement"]):
        t = table.isel(measurement=i)
        if t.kind.item() == "area":
            size = f"{format_length(float(t.size_y))} × {format_length(float(t.size_x))}"
            grid = f"{int(t.ny)} × {int(t.nx)}"
        else:
            size, grid = format_length(float(t.size_x)), f"{int(t.nx)}"
        lines.append([str(t.measurement.item()), str(t.kind.item()), size, grid, format_length(float(t.tip_radius)),
                      format_percent(float(t.missing_percent)), format_length(float(t.rms_height)),
                      f"{float(t.rms_slope):.3g}", f"{float(t.rms_curvature):.3g} m⁻¹"])
    return header, lines


def format_table(table: xr.Dataset) -> str:
    """A plain-text table of :func:`summary_table` for the terminal."""
    return text_table(*table_rows(table))


def text_table(header: list[str], lines: list[list[str]]) -> str:
    """Columns of text cells padded to a common width, the header underlined (a terminal table)."""
    widths = [max(len(r[k]) for r in [header] + lines) for k in range(len(header))]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    return "\n".join(fmt.format(*r) for r in [header, ["-" * w for w in widths], *lines])
