"""Line and area scans in one contact batch: which kind each item solved, and what a mix of both means.

A load is a force on an area scan (``E*·units²``) but a force per unit length on a line
scan (``E*·units``), and a contact "area" is an area or a length: one ``load`` coordinate
and one ``contact_area`` variable cannot label both kinds. Each solved item carries its
kind as data, the ``scan`` variable (``"line"`` or ``"area"``), from which
:func:`settle_scans` decides what a batch that mixes them reports. It is the last step of
assembling a contact batch's result, recorded in the store's manifest, so that a rerun and
:func:`xtopo.batch.open_store` give the same result from the same chunk files.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ..contact.solve import load_and_area
from ..errors import XtopoError
from ._results import ERROR, HISTORY, MEASUREMENT

__all__ = ["SCAN", "scan_variable", "one_scan", "wrong_scan_message", "settle_scans"]

SCAN = "scan"
_SCAN_ATTRS = {"long_name": "kind of scan the item solved: 'line' (plane strain) or 'area' ('' where it failed)"}
#: result variables whose units differ between line scans (force per unit length, contact length) and area
#: scans (force, contact area): one variable cannot label both, so a batch that mixes the two drops them
_SCAN_DEPENDENT = ("load", "contact_area")
_MIXED_COMMENT = ("the batch mixes line and area scans: load and contact_area (force per unit length and contact "
                  "length for a line scan, force and contact area for an area scan) are left out; mean_pressure, "
                  "area_fraction and penetration mean the same on both")


def scan_variable(kind: str, control: str, n: int) -> xr.DataArray:
    """The ``scan`` variable of one measurement's ``n`` solves along ``control``: ``kind`` for each."""
    return xr.DataArray(np.full(n, kind, dtype=object), dims=control, attrs=dict(_SCAN_ATTRS))


def _scan_of(ds: xr.Dataset) -> str | None:
    """``"line"`` or ``"area"`` for a measurement Dataset (None where it has no height: its item fails)."""
    h = ds.get("height")
    return None if h is None else ("area" if "y" in h.dims else "line")


def _a(scan: str) -> str:
    return f"an {scan} scan" if scan == "area" else f"a {scan} scan"


def _mixed_scans_message(control: str, found: str, units: str) -> str:
    return (f"{found}: a load is a force on an area scan (a pressure times {units}²) but a force per unit length on "
            f"a line scan (a pressure times {units}), so one {control!r} coordinate cannot label both; solve line and "
            "area scans in separate batches, or give mean_pressures= or penetrations=, which mean the same on both")


def wrong_scan_message(control: str, kind: str, scan: str, whose: str, units: str) -> str:
    """Why an item of kind ``kind`` fails in a batch whose loads are for ``scan`` scans (``whose`` says why)."""
    return _mixed_scans_message(control, f"this measurement is {_a(kind)}, but the loads of this batch are for "
                                         f"{scan} scans ({whose})", units)


def one_scan(control: str, names, sources, units: str) -> str | None:
    """The one kind of scan the in-memory measurements of a ``loads=`` batch are (None: no loads, or no
    in-memory measurement); a mix of both kinds is refused (an :class:`~xtopo.errors.XtopoError`)."""
    if control != "load":
        return None
    scans = {n: k for n, s in zip(names, sources) if isinstance(s, xr.Dataset) and (k := _scan_of(s)) is not None}
    if not scans:
        return None
    first = next(iter(scans.items()))
    other = next(((n, k) for n, k in scans.items() if k != first[1]), None)
    if other is not None:
        raise XtopoError(_mixed_scans_message(control, f"loads= for a mix of line and area scans: measurement "
                                                       f"{first[0]!r} is {_a(first[1])}, {other[0]!r} "
                                                       f"{_a(other[1])}", units))
    return first[1]


def _solved_scans(ds: xr.Dataset) -> dict:
    """``{measurement: "line" | "area"}`` of the measurements with a solved item, in the batch's order."""
    if SCAN not in ds.data_vars:  # every item failed
        return {}
    solved = ds[SCAN].where(ds[ERROR] == "", "").transpose(MEASUREMENT, ...)
    rows = zip(ds[MEASUREMENT].values, solved.values.reshape(solved.shape[0], -1))
    return {str(name): str(next(k for k in row if k)) for name, row in rows if any(row)}


def _refuse(ds: xr.Dataset, wrong, message: str) -> xr.Dataset:
    """The solved items of the measurements ``wrong`` failed with ``message``: NaN results, '' strings."""
    keep = ~ds[MEASUREMENT].isin(wrong)
    refused = ~keep & (ds[ERROR] == "")
    for v in list(ds.data_vars):
        if v != ERROR and MEASUREMENT in ds[v].dims:
            ds[v] = ds[v].where(keep, "" if ds[v].dtype == object else np.nan)
    ds[ERROR] = ds[ERROR].where(~refused, message).astype(object)
    if HISTORY in ds.coords:  # as for any failed item
        ds = ds.assign_coords({HISTORY: ds[HISTORY].where(keep, "").astype(object)})
    return ds


def settle_scans(ds: xr.Dataset, *, control: str, units: str, pressure: str = "E*") -> xr.Dataset:
    """A contact batch's result, consistent about its line and area scans.

    Where the solved items are all line scans or all area scans, only the ``scan`` variable
    is completed. Where they mix both:

    * ``control="load"`` (only a batch of files gets here; in-memory measurements of both
      kinds are refused before anything is solved): the items of the other kind than the
      first solved measurement fail, with an error that says why, and the ``load``
      coordinate and ``contact_area`` are labelled for the kept kind;
    * ``"mean_pressure"`` or ``"penetration"`` (which mean the same on both kinds): ``load``
      and ``contact_area`` are left out (see the ``comment`` attribute).

    Parameters
    ----------
    ds : xarray.Dataset
        The assembled result of :func:`xtopo.batch.contact` (items carrying ``scan``).
    control : {"load", "mean_pressure", "penetration"}
        The batch's parameter dimension.
    units : str
        The batch's length unit (loads in ``pressure·units²`` or ``pressure·units``).
    pressure : str
        Units label of the pressures (the scene's modulus units: ``E*`` or ``Pa``).

    Returns
    -------
    xarray.Dataset
        With a ``scan`` variable along (``measurement``, ``control``): ``"line"``, ``"area"``,
        or '' for a failed item.
    """
    ds = ds.copy()
    if SCAN not in ds.data_vars:
        ds[SCAN] = xr.full_like(ds[ERROR], "", dtype=object).assign_attrs(_SCAN_ATTRS)
    kinds = _solved_scans(ds)
    if len(set(kinds.values())) < 2:
        return ds
    if control != "load":
        ds = ds.drop_vars([v for v in _SCAN_DEPENDENT if v in ds.data_vars])
        ds.attrs["comment"] = _MIXED_COMMENT
        return ds
    scan = next(iter(kinds.values()))
    other = "line" if scan == "area" else "area"
    ds = _refuse(ds, [m for m, k in kinds.items() if k != scan],
                 "XtopoError: " + wrong_scan_message(control, other, scan, "its first file solved", units))
    # the labels the items of the two kinds disagreed on (and lost when they were combined): the kept kind's
    load_attrs, area_attrs = load_and_area(scan == "line", units, pressure)
    ds[control].attrs.update(load_attrs)
    if "contact_area" in ds.data_vars:
        ds["contact_area"].attrs.update(area_attrs)
    return ds
