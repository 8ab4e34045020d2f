"""Contact mechanics of many measurements at many loads: :func:`contact` and its item function.

Each task builds an :class:`xtopo.contact.Scene` in its worker (:func:`_contact_item`), in
the batch's one length unit, and solves its items; each solved item carries its kind of
scan (``scan``), from which the result is settled (:mod:`xtopo.batch._scans`).
"""

from __future__ import annotations

import functools
from typing import Annotated

import numpy as np
import xarray as xr

from ..conventions import append_history, convert_length, height_of, length_units_of, normalize_units
from ..errors import ContactError, UnitsError, XtopoError
from ..contact import Scene
from ..contact.models import scene_models
from ..contact.solve import ONE_SEQUENCE, control_value, load_and_area, solver_parameters
from ..params import Flag, LengthUnit, checked
from ._engine import run_batch
from ._inputs import (Progress, ReadOptions, Retries, StorePath, Workers, checked_read_options, names_and_sources,
                      run_options)
from ._scans import SCAN, one_scan, scan_variable, wrong_scan_message

__all__ = ["contact"]


def _contact_units(units, sources, read_options) -> str:
    """The one length unit of a contact batch: ``units``, else the first measurement's (a file's: the unit it
    is read in, metres unless ``read_options`` say otherwise); ``"1"`` when the first measurement has none."""
    if units is not None:
        return units
    first = sources[0]
    if not isinstance(first, xr.Dataset):
        return normalize_units(read_options.get("units") or "m")
    try:
        return length_units_of(first)
    except UnitsError:  # unitless data: solved as they are
        return "1"


def _in_batch_units(ds, units):
    """``ds`` in the batch's length unit (None: as it is; ``"1"``: a batch of unitless data, which a
    measurement with a length unit cannot join)."""
    if units is None:
        return ds
    if units != "1":
        return convert_length(ds, units)
    try:
        found = length_units_of(ds)
    except UnitsError:
        return ds
    raise UnitsError(f"this measurement is in {found!r}, but the batch is solved without a length unit (its "
                     "first measurement has none); give batch.contact(units=...) and units to every one")


def _require_heights(ds) -> None:
    """A :class:`~xtopo.errors.ContactError` naming the preprocessing that fills them where ``ds`` has missing
    heights (the Scene's own error names a Python function, which a batch or command cannot call)."""
    n = int((~np.isfinite(height_of(ds))).sum())
    if n:
        raise ContactError(f"{ds.attrs.get('source_file') or 'the measurement'}: {n} points have no height; a "
                           "contact calculation needs a height at every pixel: fill them (--fill-missing on the "
                           "command line, preprocess={'fill_missing': True} in xtopo.batch)")


def _contact_item(ds, values, *, control, scene, solve, maps, units=None, required_scan=None):
    """Contact solutions of one measurement for each value of ``control`` (runs in the worker).

    Parameters
    ----------
    ds : xarray.Dataset
        The measurement.
    values : list of float
        The loads (``E*·units²``, ``E*·units`` on a line scan), mean pressures (``E*``) or
        penetrations (``units``).
    control : {"load", "mean_pressure", "penetration"}
        What ``values`` are.
    scene, solve : dict
        Keywords of :class:`xtopo.contact.Scene` and of ``Scene.solve``.
    maps : bool
        Keep the pressure/displacement/gap/contact maps.
    units : str, optional
        The length unit the measurement is converted to before solving (None: as it is;
        ``"1"``: a batch of unitless data, which a measurement with a length unit cannot join).
    required_scan : {"line", "area"}, optional
        The only kind of scan the batch's loads mean something for (None: any); a
        measurement of the other kind fails.

    Returns
    -------
    xarray.Dataset
        The solves stacked along ``control``, with a ``scan`` variable (``"line"`` or
        ``"area"`` for each) and the input's history plus one line for the contact.
    """
    _require_heights(ds)
    ds = _in_batch_units(ds, units)
    sc = Scene(ds, **scene)
    kind = "line" if sc.line else "area"
    if required_scan is not None and kind != required_scan:
        raise XtopoError(wrong_scan_message(control, kind, required_scan, "its other measurements", units))
    out = []
    for v in values:
        r = sc.solve(**{control: v}, **solve)
        if not maps:
            r = r.drop_vars([n for n, var in r.variables.items() if {"x", "y"} & set(var.dims)])
        attrs = dict(r[control].attrs) if control in r.variables else {}
        r = r.drop_vars(control, errors="ignore").expand_dims({control: [v]})
        r[control].attrs = attrs
        out.append(r)
    out = xr.concat(out, dim=control, combine_attrs="drop_conflicts", data_vars="all")
    out[SCAN] = scan_variable(kind, control, len(values))
    # the solves' own history lines differ by load (and were dropped): the input's history plus one line for all
    out.attrs["history"] = ds.attrs.get("history", "")
    out = append_history(out, _contact_line(sc, control, out[control].attrs.get("units", "?"), scene, solve))
    return _snap_grid(out) if maps else out


def _contact_line(sc, control, units, scene, solve) -> str:
    """The history line of a contact computation: what was modelled and how it was solved."""
    boundary = "periodic" if sc.periodic else "free"
    boundary += " (as requested)" if "periodic" in scene else " (from the data)"
    settings = ", ".join(f"{k}={v:g}" for k, v in solve.items()) or "default tol and maxiter"
    scan = "a line scan (plane strain)" if sc.line else "an area scan"
    models = ", ".join(m.label for m in sc.models)
    return (f"xtopo contact of {scan} at each {control} of the {control!r} coordinate ({units}): "
            f"Scene({models}, boundary {boundary}, "
            f"no counter surface (rigid rough surface), lengths in {sc.length_units}); "
            f"Polonsky-Keer solve, {settings}")


def _snap_grid(ds):
    """``x``/``y`` as ``x0 + m·Δ`` with ``Δ`` rounded to 10 significant digits (and ``x0`` to 1e-6 of it).

    A grid converted from another unit is off by rounding (0.0625 µm from nm: 0.06250000000000001),
    and maps on it would not align with those of the same grid given in µm (an outer join of both).
    """
    snapped = {}
    for d in ("x", "y"):
        if d in ds.coords and ds.sizes.get(d, 0) > 1:
            c = ds.coords[d]
            v = np.asarray(c.values, dtype=float)
            step = float(f"{(v[-1] - v[0]) / (v.size - 1):.10g}")
            q = 10.0 ** (np.floor(np.log10(abs(step))) - 6) if step else 1.0
            snapped[d] = c.copy(data=np.round(v[0] / q) * q + np.arange(v.size) * step)
    return ds.assign_coords(snapped)


@checked(ONE_SEQUENCE)
def contact(measurements, loads=None, *, mean_pressures=None, penetrations=None,
            modulus: float = 1.0, hardness: float | None = None,
            periodic: Annotated[bool | None, Flag(error=ContactError)] = None,
            tol: float | None = None, maxiter: int | None = None,
            maps: Annotated[bool, Flag()] = False, chunks=None, client=None, scheduler=None,
            workers: Workers = None, store: StorePath = None, progress: Progress = True, fft_threads: Workers = 1,
            retries: Retries = 1, read_options: ReadOptions = None, units: Annotated[str | None, LengthUnit()] = None,
            preprocess=None) -> xr.Dataset:
    """Contact of many measurements at many loads, as a chunked Dask batch (see :func:`run`).

    Exactly one of ``loads``, ``mean_pressures``, ``penetrations`` is given; it becomes the
    second dimension of the result (``load``, ``mean_pressure`` or ``penetration``). Each task
    builds an :class:`xtopo.contact.Scene` in its worker and solves its items.

    Every measurement is converted to one length unit (``units``) before it is solved, so
    that a load means the same force on each of them whatever unit it was given in (a load
    of 0.01 E*·µm² applied to a copy in nm would otherwise be 10⁶ times smaller) and the
    results share their labels (the ``load`` coordinate, contact areas, penetrations, the
    x/y coordinates of the maps).

    Parameters
    ----------
    measurements : mapping, DataTree, or sequence of Dataset / path
        The topographies (paths are read in the workers).
    loads, mean_pressures, penetrations : sequence of float
        The controlled quantity: load in units of ``E*`` × ``units``² (``E*`` × ``units``
        for line scans: force per unit length), mean pressure in units of ``E*``,
        penetration in ``units``.

        A load is a force on an area scan but a force per unit length on a line scan: the
        two are different quantities, and one ``load`` coordinate (one units label) cannot
        hold both. So ``loads=`` needs all measurements to be line scans or all area scans:
        a mix of in-memory Datasets is refused before anything is solved (an
        :class:`~xtopo.errors.XtopoError`); a file, whose kind is known only once it is
        read, of the other kind than the in-memory measurements (or, in a batch of files
        only, than the first file solved) fails as an item with an error saying so. A mean
        pressure (in ``E*``) and a penetration (a length) mean the same on both kinds, so
        ``mean_pressures=`` and ``penetrations=`` accept a mix; their results then leave out
        ``load`` and ``contact_area`` (force per length and contact length for line scans,
        force and contact area for area scans: one variable cannot label both) and keep
        ``mean_pressure``, ``area_fraction`` and ``penetration``, which they share.
    modulus, hardness, periodic
        Passed to :class:`xtopo.contact.Scene` (``periodic=None``: from the measurement).
        ``modulus`` is the contact modulus ``E*``; pressures, loads and ``hardness`` are in
        its units (labelled ``E*`` for the default modulus 1, else ``Pa``, as by the scene).
    tol, maxiter
        Passed to ``Scene.solve`` when given.
    maps : bool
        Keep the pressure/displacement/gap/contact maps (large); default only the scalars
        (load, mean pressure, area fraction, penetration, iterations, residual, converged).
    chunks, client, scheduler, workers, store, progress, fft_threads, retries, read_options, preprocess
        See :func:`run`. A measurement with missing points needs
        ``preprocess={"fill_missing": True}`` (after ``"detrend"``, if any): a contact
        calculation needs a height at every pixel.
    units : str, optional
        Length unit of the solves (``"um"``, ``"nm"``, ...). Default: the unit of the first
        measurement (for a file, the unit it is read in: metres unless ``read_options`` give
        ``units``), as :func:`xtopo.stitching.twin_psd` does.

    Returns
    -------
    xarray.Dataset
        Dims (``measurement``, ``load``, ...) plus ``error``; see :func:`run`. A string
        variable ``scan`` says which kind of scan each item solved (``"line"``, ``"area"``,
        '' where it failed). Where some item failed, ``iterations`` and ``converged`` are
        floats (1.0/0.0 for True/False, NaN for the failed items), as :func:`run` says.
    """
    # the one control (ONE_SEQUENCE, declared above); modulus, hardness, tol and maxiter are checked below by
    # the functions Scene and solve use, once here for every item, not N times in the workers
    control, values = next((k[:-1], v) for k, v in (("loads", loads), ("mean_pressures", mean_pressures),
                                                    ("penetrations", penetrations)) if v is not None)
    models = scene_models(modulus, hardness)
    tol, maxiter = solver_parameters(tol, maxiter)
    values = [control_value(control, v, models) for v in run_options(_contact_item, control, values)]  # 1D, not empty
    scene = {k: v for k, v in (("modulus", modulus), ("hardness", hardness), ("periodic", periodic)) if v is not None}
    solve = {k: v for k, v in (("tol", tol), ("maxiter", maxiter)) if v is not None}
    names, sources = names_and_sources(measurements)
    units = _contact_units(units, sources, checked_read_options(read_options, len(names))[0])
    # the in-memory measurements' kind (line or area scan) is known now; files' only once read
    scan = one_scan(control, names, sources, units)
    func = functools.partial(_contact_item, control=control, scene=scene, solve=solve, maps=maps, units=units,
                             required_scan=scan)
    pressure = models[0].units   # "E*" or "Pa", as each item's scene labels them
    load = load_and_area(scan == "line", units, pressure)[0]   # a load's labels depend on the scan (area or line)
    long_name = {"load": load["long_name"], "mean_pressure": "mean pressure", "penetration": "penetration"}[control]
    dim_attrs = {"long_name": f"{long_name} (imposed)"}
    # the coordinate's units when no item gives them (all failed)
    dim_units = {"mean_pressure": pressure, "penetration": units, "load": scan and load["units"]}[control]
    if dim_units is not None:
        dim_attrs["units"] = dim_units
    return run_batch(func, measurements, values, dim=control, dim_attrs=dim_attrs, chunks=chunks, client=client,
                     scheduler=scheduler, workers=workers, store=store, progress=progress, fft_threads=fft_threads,
                     retries=retries, read_options=read_options, preprocess=preprocess,
                     finish={"name": "settle_scans",
                             "kwargs": {"control": control, "units": units, "pressure": pressure}})
