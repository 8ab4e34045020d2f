"""The ISO parameter sets that the command line (``--iso``), ``xtopo info`` and the report show: one lookup.

:data:`ISO_SETS` names each set, the scans it applies to and its function; a new set is one more
entry. Not public API.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from .._format import format_length
from ..conventions import HEIGHT, X, convert_length, lateral_dims
from ..errors import XtopoError
from .iso21920 import iso21920
from .iso25178 import iso25178

__all__ = ["ISO_SETS", "iso_values", "iso_table", "format_iso_table"]

#: set name → (what it is, the scans it applies to, its function)
ISO_SETS = {
    "iso21920": ("ISO 21920-2 profile parameters (profiles along x; maps: mean over the lines)", ("line", "area"),
                 iso21920),
    "iso25178": ("ISO 25178-2 areal parameters", ("area",), iso25178),
}


def _scalar_vars(res: xr.Dataset, profiles: str | None) -> dict:
    """The 0-d values of ``res``; per-profile values are averaged over ``profiles`` (the other lateral dim)."""
    out = {}
    for name, v in res.data_vars.items():
        if profiles is not None and profiles in v.dims:
            v = v.mean(profiles).assign_attrs(v.attrs, long_name=f"{v.attrs.get('long_name', name)}, mean over "
                                                                   "the profiles")
        if v.ndim == 0:
            out[name] = v
    return out


def iso_values(ds: xr.Dataset, name: str, *, lambda_s=None, lambda_c=None) -> xr.Dataset:
    """The parameters of the ISO set ``name`` of one measurement as 0-d variables (empty if it does not apply).

    Parameters
    ----------
    ds : xarray.Dataset
        One measurement (no batch dims).
    name : str
        A set of :data:`ISO_SETS`.
    lambda_s, lambda_c : float, str or None
        Nesting indices for the profile set (see :func:`xtopo.analysis.iso21920.iso21920`).

    Returns
    -------
    xarray.Dataset
        One variable per parameter, with ``units`` and ``long_name``.
    """
    kind = "area" if len(lateral_dims(ds[HEIGHT])) == 2 else "line"
    if kind not in ISO_SETS[name][1]:
        return xr.Dataset()
    func = ISO_SETS[name][2]
    if name == "iso21920":
        res = func(ds, dim=X, lambda_s=lambda_s, lambda_c=lambda_c)
        used = {k: xr.DataArray(float(res.attrs[k]), attrs={"units": res.attrs["length_units"], "long_name": text})
                for k, text in (("lambda_s", "S-filter nesting index used (NaN: none)"),
                                ("lambda_c", "L-filter cut-off used (NaN: none)"))}  # "auto" says which
        return xr.Dataset({**used, **_scalar_vars(res, "y" if kind == "area" else None)})
    return xr.Dataset(_scalar_vars(func(ds), None))


def iso_table(measurements: dict, *, lambda_s=None, lambda_c=None) -> tuple[xr.Dataset, dict]:
    """The ISO parameters of each measurement along a ``measurement`` dim (lengths in m), and the errors.

    Parameters
    ----------
    measurements : dict of str to xarray.Dataset
        Name → measurement.
    lambda_s, lambda_c : float, str or None
        As :func:`iso_values`; a bare number is in metres (the table's unit).

    Returns
    -------
    tuple
        The table (NaN where a parameter does not apply or could not be computed) and
        ``{name: message}`` for each measurement and set that failed (e.g. a cut-off longer
        than the measurement); the other sets of that measurement are still in the table.
    """
    rows, errors = {}, {}
    columns = {iso: {} for iso in ISO_SETS}  # per set, its variables in order (a dict as ordered set)
    for name, ds in measurements.items():
        ds = convert_length(ds, "m")
        parts = []
        for iso in columns:
            try:
                parts.append(iso_values(ds, iso, lambda_s=lambda_s, lambda_c=lambda_c))
                columns[iso].update(dict.fromkeys(parts[-1].data_vars))
            except XtopoError as exc:
                errors[name] = f"{errors[name]}; {exc}" if name in errors else str(exc)
        # each variable stands in one part, whose attrs (units, long_name) it keeps; the parts have no attrs of their own
        rows[name] = xr.merge(parts, combine_attrs="override") if parts else xr.Dataset()
    names = list(rows)
    table = xr.concat([rows[n].expand_dims(measurement=[n]) for n in names], dim="measurement", join="outer",
                      combine_attrs="drop") if names else xr.Dataset()
    # columns set by set, whichever measurement a set failed for (the first row decides concat's order)
    table = table[[v for cols in columns.values() for v in cols if v in table.data_vars]] if names else table
    for n in table.data_vars:  # concat keeps the attrs of the first; take them from any row that has the variable
        table[n].attrs = next(rows[m][n].attrs for m in names if n in rows[m].data_vars)
    table.attrs = {"title": "ISO parameters", "lambda_s": str(lambda_s), "lambda_c": str(lambda_c)}
    return table, errors


def format_iso_table(table: xr.Dataset) -> tuple[list[str], list[list[str]]]:
    """Header and cells of :func:`iso_table`, one row per measurement.

    Lengths are in readable units, material ratios in %; ``-`` where a value is missing.
    """
    names = list(table.data_vars)
    header = ["measurement"] + [f"{n}/%" if table[n].attrs.get("units") == "%" else n for n in names]
    rows = []
    for i in range(table.sizes.get("measurement", 0)):
        cells = [str(table.measurement.values[i])]
        for n in names:
            v = float(table[n].values[i])
            cells.append("-" if not np.isfinite(v) else format_length(v) if table[n].attrs.get("units") == "m"
                         else f"{v:.3g}")
        rows.append(cells)
    return header, rows
