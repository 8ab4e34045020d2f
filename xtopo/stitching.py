"""Averages of scale-dependent curves over a digital surface twin (paper §4.10).

Each measurement's curve (PSD, ACF, VBM, SDRP) is computed in its 1D (profile)
representation (or ``Ciso`` with ``twin_psd(areal=True)``) with its unreliable scales
(§4.9: resolution, tip radius) masked, brought onto common log-spaced collocation points
(PSD, ACF, VBM: mean of each curve's points in log bins, log-log interpolation between
points sparser than the bins; SDRP: evaluated at the points) and averaged with equal
weight per measurement at every point of its reliable range. The predicted statistical
uncertainty of each point is returned, not used to delete data (unless ``max_error``).
The four analyses are declared once in :data:`ANALYSES` (name, function, coordinate,
averaging, error model, labels), which the report, the CLI and the figure loop over.
Everything stays lazy on dask-backed twins: the graph is built from coordinates
alone, data are read and computed only by ``.compute()`` (threaded scheduler,
or the active ``distributed.Client``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import partial
from typing import Annotated

import numpy as np
import xarray as xr

from ._checks import MAX_SPARSE_BINS
from ._one_task import one_task, template
from .cache import remember
from ._kernels.collocation import collocate, collocate_error, collocation_points, equal_weight_mean, select_for_mean
from ._progress import progress_bar
from .analysis._scale import provenance
from .analysis.acf import acf
from .analysis.curvature_kurtosis import curvature_kurtosis, curvature_kurtosis_error
from .analysis.psd import WINDOWS, psd
from .analysis.reliability import reliability_cutoff
from .analysis.sdrp import sdrp
from .analysis.statistical_reliability import independent_samples, sampling_cutoff, stencil_error
from .analysis.vbm import vbm
from .conventions import MEASUREMENT_ATTRS, convert_length, height_of, lateral_dims, length_factor
from .errors import GridError, UnitsError, XtopoError
from .params import Choice, Count, Flag, Lengths, LengthUnit, Positive, checked
from .preprocess import fill_missing
from .summary import summary_table
from .twins import measurements as _measurements

__all__ = ["average_curves", "twin_average", "twin_psd", "twin_acf", "twin_vbm", "twin_sdrp", "ANALYSES",
           "TwinAnalysis"]

#: default density of collocation points
PER_DECADE = 10
#: coordinate holding the independent modes of each wavevector of a spectrum
_MODES = "independent_modes"
#: boolean coordinate of a curve marking points a stated long-scale criterion leaves out (attr ``criterion``)
UNRELIABLE = "unreliable"
#: ``left_out`` flags: why a value available on a measurement's range was not averaged
_FLAGS = {"long_scale_criterion": 1, "statistical_criterion": 2}


def _common_units(ms: dict, units=None) -> str:
    """``units`` (declared :class:`~xtopo.params.LengthUnit`), else the first measurement's length unit."""
    if units is not None:
        return units
    for ds in ms.values():
        return ds["x"].attrs.get("units", "m")
    raise XtopoError("the twin has no measurements")


def _curve_coord(curve: xr.DataArray) -> str:
    dims = [d for d in curve.dims if d in curve.coords and d not in ("x", "y")]
    if len(dims) != 1:
        raise XtopoError(f"expected a curve with one coordinate dimension, got dims {curve.dims}")
    return dims[0]


def _check_alike(curves: dict, coord: str) -> None:
    """Raise unless every curve is on ``coord`` with the same units (of the coordinate and of the values)."""
    first = next(iter(curves.values()))
    want = (first[coord].attrs.get("units"), first.attrs.get("units"))
    for name, c in curves.items():
        if _curve_coord(c) != coord:
            raise XtopoError(f"curves must share one coordinate: {name!r} is on {_curve_coord(c)!r}, "
                             f"the first on {coord!r}")
        got = (c[coord].attrs.get("units"), c.attrs.get("units"))
        if got != want:
            raise UnitsError(f"curves must be in the same units: {name!r} has {coord} in {got[0]!r} and values "
                             f"in {got[1]!r}, the first {want[0]!r} and {want[1]!r}; compute them from "
                             "measurements in one length unit (.topo.to_units)")


def _onto(curve: xr.DataArray, error, coord: str, grid: np.ndarray, method: str) -> xr.DataArray:
    """``curve`` on the collocation ``grid`` by :func:`_on_grid` (its points marked :data:`UNRELIABLE` left
    out), with its predicted relative error there and where the whole curve would reach: one apply_ufunc.

    Every collocation point inside the range of the curve's finite (reliable) points gets a
    value (:func:`~xtopo._kernels.collocation.collocate`). Spectra carry their independent
    modes: a bin holding ``N`` has ``1/√N``. Other curves: their ``error`` (on the curve's
    points, or None: unknown) brought onto the grid like the curve.
    """
    kw = {"x": np.asarray(curve[coord].values, dtype=float), "xnew": grid, "method": method}
    if UNRELIABLE in curve.coords:
        kw["unreliable"] = np.asarray(curve[UNRELIABLE].values)
    if method == "bin" and _MODES in curve.coords:  # spectra: independent modes add up within a bin
        kw["modes"], error = np.asarray(curve[_MODES].values, dtype=float), None
    args = [a.drop_vars([c for c in a.coords if c != coord]) for a in ((curve,) if error is None else (curve, error))]
    return xr.apply_ufunc(_on_grid, *args, input_core_dims=[[coord]] * len(args),
                          output_core_dims=[["_part", "_grid"]], exclude_dims={coord}, kwargs=kw,
                          dask="parallelized", output_dtypes=[float],
                          dask_gufunc_kwargs={"output_sizes": {"_part": 3, "_grid": grid.size}})


def _on_grid(y, err=None, *, x, xnew, method, unreliable=None, modes=None):
    """Values, predicted relative errors (NaN: unknown) and reach (1 where the curve with its ``unreliable``
    points would have a value, NaN elsewhere) of a curve ``y`` at ``x`` on ``xnew``, stacked on a first axis."""
    whole = y
    if unreliable is not None:
        y = np.where(unreliable, np.nan, y)
    value = collocate(y, x, xnew, method)
    if modes is not None:
        with np.errstate(divide="ignore"):
            err = np.where(modes > 0, 1 / np.sqrt(np.where(modes > 0, modes, 1.0)), np.nan)
    error = np.full_like(value, np.nan) if err is None else collocate_error(err, y, x, xnew, method, modes=modes)
    reach = value if unreliable is None else collocate(whole, x, xnew, method)
    return np.stack([value, error, np.where(np.isnan(reach), np.nan, 1.0)])


def _statistics(parts: xr.DataArray, *, tol, attrs: dict, name: str, reasons: list) -> xr.Dataset:
    """The average and its statistics (see :func:`average_curves`) of the curves on the collocation points in
    memory, stacked in ``parts`` (values, predicted relative errors, reach) along ``measurement``; of a lazy
    twin, one block of the grid (:func:`xarray.map_blocks`). ``attrs``: the curves' units and long_name,
    ``name`` the long_name of the average, ``reasons`` why ``unreliable`` points of a curve were left out."""
    stacked, err, reach = (parts.isel(_part=i, drop=True) for i in range(3))
    available, reach = stacked.notnull(), reach.notnull()  # reach: where the unreliable points would have reached
    if tol is not None:
        used, sigma = xr.apply_ufunc(select_for_mean, stacked, err, input_core_dims=[["measurement"]] * 2,
                                     output_core_dims=[["measurement"], []])
        stacked = stacked.where(used & (sigma <= tol))
        reasons = [*reasons, f"predicted relative standard error of the average above {tol:g}"]
    average, se, count = xr.apply_ufunc(equal_weight_mean, stacked, err, input_core_dims=[["measurement"]] * 2,
                                        output_core_dims=[[], [], []])
    units = attrs.get("units", "1")
    stacked.attrs = attrs
    average.attrs = {"units": units, "long_name": f"average {name}".strip()}
    count.attrs = {"units": "1", "long_name": "number of measurements averaged"}
    se.attrs = {"units": units, "long_name": "predicted standard error of the average"}
    rel = (se / average).assign_attrs(units="1", long_name="predicted relative standard error of the average")
    err = err.where(available)
    err.attrs = {"units": "1", "long_name": "predicted relative standard error of each curve"}  # not a curve's own
    left = xr.where(available & stacked.isnull(), np.int8(_FLAGS["statistical_criterion"]),
                    xr.where(reach & ~available, np.int8(_FLAGS["long_scale_criterion"]), np.int8(0)))
    left = left.astype(np.int8).assign_attrs(
        units="1", long_name="values left out of the average, and why (0: none)",
        flag_values=np.array(list(_FLAGS.values()), dtype=np.int8), flag_meanings=" ".join(_FLAGS),
        criterion="; ".join(reasons) or "none")
    return xr.Dataset({"average": average, "uncertainty": se, "relative_error": rel, "count": count,
                       "curves": stacked, "curve_error": err, "left_out": left})


#: collocation points per decade (10**30 raised numpy's 'Maximum allowed size exceeded')
_PER_DECADE = Count(1, MAX_SPARSE_BINS)
#: the largest predicted relative error of an average point (None: no statistical criterion)
_MAX_ERROR = Positive(infinite=True)


@checked
def average_curves(curves: dict, *, per_decade: Annotated[int, _PER_DECADE] = PER_DECADE,
                   points: Annotated[np.ndarray | None, Lengths(empty=False)] = None,
                   method: Annotated[str, Choice("interp", "bin")] = "interp", errors: dict | None = None,
                   max_error: Annotated[float | None, _MAX_ERROR] = None) -> xr.Dataset:
    """Average 1D curves of several measurements at common log-spaced points (paper §4.10).

    Every finite (reliable) point of every curve contributes: each curve is brought onto the
    collocation points (``method``) and, at every point inside the range of its finite
    points, enters the arithmetic mean with equal weight (the paper's weighting). A curve
    sparser than the collocation points (the long wavelengths of a spectrum) is interpolated
    log-log between its points, so overlapping measurements leave no empty point. The
    statistical uncertainty of the average is computed from the curves' predicted relative
    standard errors (``errors``, or the independent Fourier modes a spectrum from
    :func:`twin_psd` carries): ``σ = √(Σ (σ_i y_i)²)/n`` (measurements independent). It
    deletes nothing unless asked: with ``max_error``, at each point only the measurements of
    smallest predicted error are averaged as long as each lowers the predicted error of the
    mean, and points whose error stays above ``max_error`` are left out; ``left_out`` says
    which values that dropped. A curve may carry a boolean coordinate ``unreliable`` along its
    coordinate (attr ``criterion``: why; e.g. the lowest wavevector of a windowed spectrum, see
    :func:`twin_psd`): those points are not averaged, and the collocation points they would have
    reached are flagged in ``left_out`` too.

    Parameters
    ----------
    curves : dict of str to xarray.DataArray
        One curve per measurement, each with a single coordinate dim (``q``,
        ``distance`` or ``bandwidth``) in the same units; NaN marks scales a
        measurement may not be used at (short-scale reliability, paper §4.9).
    per_decade : int
        Density of collocation points when ``points`` is not given.
    points : array_like, optional
        Explicit collocation points (positive, in the units of the curves' coordinate).
    method : {"interp", "bin"}
        ``"interp"``: log-log interpolation of each curve (smooth or sparse curves:
        SDRP, VBM); ``"bin"``: mean of each curve's points in log bins around the
        collocation points (dense, noisy curves: PSD, ACF; paper §4.10), interpolated
        between points sparser than the bins.
    errors : dict of str to xarray.DataArray or None, optional
        Predicted relative standard error of each curve's points (same coordinate; None: unknown).
    max_error : float, optional
        Opt-in statistical criterion: largest predicted relative standard error of an
        average point (e.g. :data:`xtopo.analysis.statistical_reliability.MAX_RELATIVE_ERROR`). Default
        None: every reliable point is averaged.

    Returns
    -------
    xarray.Dataset
        On the collocation coordinate: ``average``, ``uncertainty`` (its predicted standard
        error, units of the average), ``relative_error`` (the same relative to the average)
        and ``count`` (measurements averaged). On (``measurement``, coordinate): ``curves``
        (the values averaged, NaN elsewhere), ``curve_error`` (each curve's predicted
        relative error) and ``left_out`` (CF flags: 1 where a curve's ``unreliable`` points would
        have given a value, 2 where ``max_error`` dropped one; attr ``criterion`` says why). Per measurement
        ``reliability_cutoff`` and ``reliability_criterion`` where the curves carry one (the criterion: a curve's
        0-d coordinate ``reliability_criterion``, else its cutoff's attr ``method``).
    """
    tol = max_error
    for what, given in (("curves", curves), ("errors", {} if errors is None else errors)):
        if not isinstance(given, Mapping):
            raise XtopoError(f"{what} must be a mapping of measurement name to DataArray, got {type(given).__name__}")
        bad = {n: type(c).__name__ for n, c in given.items()
               if not isinstance(c, xr.DataArray) and not (what == "errors" and c is None)}
        if bad:
            raise XtopoError(f"{what} must be xarray.DataArrays{' (or None)' if what == 'errors' else ''}, got {bad}")
    if not curves:
        raise XtopoError("no curves to average")
    first = next(iter(curves.values()))
    coord = _curve_coord(first)
    _check_alike(curves, coord)
    if points is None:  # a curve without positive abscissae (a single-point scan) adds nothing
        x = np.concatenate([np.asarray(c[coord].values, dtype=float).ravel() for c in curves.values()])
        x = x[x > 0]
        if not x.size:
            raise XtopoError(f"no curve has a point at positive {coord}: nothing to average")
        grid = collocation_points(x.min(), x.max(), per_decade)
    else:
        grid = points
    names = list(curves)
    dim = xr.DataArray(names, dims="measurement", name="measurement", attrs={"long_name": "measurement"})
    parts = xr.concat([_onto(curves[n], (errors or {}).get(n), coord, grid, method) for n in names], dim=dim)
    parts = parts.rename({"_grid": coord}).assign_coords({coord: (coord, grid, dict(first[coord].attrs))})
    kw = {"tol": tol, "attrs": {k: v for k, v in first.attrs.items() if k in ("units", "long_name")},
          "name": first.attrs.get("long_name", first.name or ""), "reasons": sorted(
              {str(c[UNRELIABLE].attrs.get("criterion", "unreliable points of a curve"))
               for c in curves.values() if UNRELIABLE in c.coords})}
    if parts.chunks is None:
        out = _statistics(parts, **kw)
    else:  # one task per grid block (pydata/xarray#11329 lost keys of many lazy variables derived from one source)
        like = _statistics(parts.copy(data=np.full(parts.shape, np.nan)), **kw)
        out = xr.map_blocks(_statistics, parts.chunk({"measurement": -1}), kwargs=kw,
                            template=like.chunk({coord: parts.chunksizes[coord]}))
    cuts = [c.coords["reliability_cutoff"].variable if "reliability_cutoff" in c.coords else xr.Variable((), np.nan)
            for c in curves.values()]
    cut_units = next((c.coords["reliability_cutoff"].attrs.get("units") for c in curves.values()
                      if "reliability_cutoff" in c.coords), None)
    if cut_units is not None and all(v.ndim == 0 for v in cuts):
        # the cutoffs' own attrs (method, tip radius) differ between measurements: their criterion becomes a variable
        cut = xr.concat([xr.DataArray(v) for v in cuts], dim="measurement").drop_attrs(deep=False).assign_attrs(
            units=cut_units, long_name="short reliability cutoff")
        crit = xr.DataArray(np.stack([  # np.stack: dask's on lazy curves (xr.concat cast each string: a task each)
            c.coords["reliability_criterion"].data if "reliability_criterion" in c.coords
            else np.array(str(v.attrs.get("method", "none"))) for c, v in zip(curves.values(), cuts)]),
            dims="measurement", attrs={"units": "1", "long_name": "criterion of the short reliability cutoff (paper §4.9)"})
        for var, v in (("reliability_cutoff", cut), ("reliability_criterion", crit)):  # lazy: one chunk, as the curves
            out[var] = v if v.chunks is None else v.chunk({"measurement": -1})
    out.attrs = {"title": f"twin average of {first.name or 'curves'}", "collocation_points_per_decade": per_decade,
                 "collocation_method": method,
                 "weighting": "arithmetic mean with equal weight per measurement over its reliable scales"
                              + ("" if tol is None else "; measurements in order of increasing predicted error while "
                                 f"each lowers the predicted error of the mean, points above {tol:g} left out")}
    if tol is not None:
        out.attrs["max_error"] = tol
    return out


def _complete(ds: xr.Dataset, name: str) -> xr.Dataset:
    """Measurements with missing data (``mask``, or NaN heights without one) are filled harmonically
    first (paper §3.2); lazy on dask, and a no-op for complete data.

    A measurement without any valid height raises a GridError that names it (in-memory data;
    on dask the fill's own error comes at ``.compute()``).
    """
    h = height_of(ds)
    if h.chunks is None and bool(np.isfinite(h.values).all()):
        return ds  # complete: no second fill_missing line after --fill-missing (issue 26)
    try:
        return fill_missing(ds)
    except GridError as exc:
        raise GridError(f"measurement {name!r}: {exc}") from None


def _predicted_error(curve: xr.DataArray, ds: xr.Dataset, coord: str, quantity):
    """Long-scale (statistical) information of a measurement's curve for the twin average.

    Spectra: each wavevector carries its independent Fourier modes (relative error ``1/√N``
    of a bin holding ``N``). ACF and SDRP: the predicted relative error of
    :func:`~xtopo.analysis.statistical_reliability.stencil_error`. VBM: ``1/(2√N)`` with ``N``
    independent windows. Returns the curve (spectra: with the modes as a coordinate)
    and the error on the curve's points (None for spectra, and for ``quantity=None``: no error model).
    A callable ``quantity`` is the error model of a :class:`TwinAnalysis` (its ``error``).
    """
    if quantity is None:
        return curve, None
    if callable(quantity):
        return curve, quantity(ds, curve).assign_coords({coord: curve[coord]})
    direction = curve.attrs.get("direction", "x")
    x = np.asarray(curve[coord].values, dtype=float)
    if coord == "q":
        n = independent_samples(ds, coord, x, dim=direction)
        return curve.assign_coords({_MODES: (coord, n, {"units": "1", "long_name": "independent Fourier modes"})}), None
    if quantity == "vbm":
        n = independent_samples(ds, coord, x, dim=direction)
        with np.errstate(divide="ignore"):
            err = xr.DataArray(np.where(n > 0, 0.5 / np.sqrt(np.where(n > 0, n, 1.0)), np.inf), dims=coord)
    else:
        # the zero lag (ACF) has no relative error: NaN there
        err = stencil_error(ds, x[x > 0], quantity=quantity, dim=direction).reindex(distance=x)
        if err.chunks is not None:  # reindexing a lazy array splits it where the new lag sits
            err = err.chunk({"distance": -1})
        err = err.rename(distance=coord).drop_vars(coord)
    return curve, err.assign_coords({coord: curve[coord]})


def _mask_short_scales(y, cut, *, x, spectrum: bool):
    """``y`` (abscissae ``x`` on its last axis) with the points below the short cutoff ``cut`` set to NaN
    (spectra: above the wavevector ``2π/cut``); a cutoff that is not positive masks nothing."""
    cut = np.asarray(cut)[..., np.newaxis]
    keep = (x <= 2 * np.pi / cut) if spectrum else (x >= cut)
    return np.where(keep | ~(cut > 0), y, np.array(np.nan, dtype=y.dtype))


def _reliable_part(curve: xr.DataArray, ds: xr.Dataset, coord: str, reliable: bool) -> xr.DataArray:
    """Mask (never drop) the unreliable scales so every backend yields the same coordinates.

    Short-scale criteria: tip radius or resolution (paper §4.9) and, for spectra, the
    sampling criterion :func:`~xtopo.analysis.statistical_reliability.sampling_cutoff`.
    """
    if not reliable:
        return curve
    cut = remember(reliability_cutoff, ds, _shape(ds))  # once for all averages of the twin
    criterion = cut.attrs.pop("method", "none")
    if coord == "q":  # spectra also end where aliasing sets in; which criterion wins is data (lazy: at compute)
        sampling = sampling_cutoff(ds, curve.attrs.get("direction", "x"))
        criterion = np.where(cut.data >= sampling, criterion, "sampling")  # dask's where on a lazy cutoff
        cut = np.fmax(cut, sampling)
    out = xr.apply_ufunc(_mask_short_scales, curve, cut, input_core_dims=[[coord], []], output_core_dims=[[coord]],
                         kwargs={"x": np.asarray(curve[coord].values), "spectrum": coord == "q"},
                         dask="parallelized", output_dtypes=[curve.dtype])  # one dask array, not seven
    out = out.transpose(*curve.dims, ...)
    out.attrs = dict(curve.attrs, reliable=1)
    return out.assign_coords(reliability_cutoff=cut.variable, reliability_criterion=((), criterion))


def _setting(ds: xr.Dataset) -> tuple:
    """Instrument and scan setting of a measurement: replicates (same instrument, points, extent,
    tip and resolution) share one predicted error in the twin averages (see :func:`_pool_errors`)."""
    def sig(v):  # 6 significant digits: digitised positions and derived lengths agree to rounding
        return None if v is None else float(f"{float(v):.6g}")

    dims = lateral_dims(ds["height"])
    return (ds.attrs.get("instrument"), ds.attrs.get("tip_radius_units"), ds["x"].attrs.get("units"),
            tuple(ds.sizes[d] for d in dims), tuple(sig(ds[d].values[-1] - ds[d].values[0]) for d in dims),
            sig(ds.attrs.get("tip_radius")), sig(ds.attrs.get("resolution")))


def _replicate_median(a: np.ndarray) -> np.ndarray:
    """Median over the last axis (replicates), NaN where none is finite (where the stencil does not fit:
    numpy's nanmedian warned "All-NaN slice" there on every lazy twin)."""
    out = np.full(a.shape[:-1], np.nan)
    some = ~np.isnan(a).all(axis=-1)
    out[some] = np.nanmedian(a[some], axis=-1)
    return out


def _pool_errors(errors: dict, settings: dict) -> dict:
    """Replace each measurement's plug-in predicted error by the median over its replicates.

    The plug-in error of :func:`~xtopo.analysis.statistical_reliability.stencil_error` rests on the
    measurement's own curve, one realisation: it is itself noisy, and a selection by it
    (:func:`average_curves`) would favour the scans that happen to look precise (a scan whose
    long wavelengths happen to be weak shows a low curve *and* a low predicted error). The
    error of an estimator is a property of the instrument's setting, not of the realisation:
    replicates (same :func:`_setting`) share the median of their plug-in errors (robust to the
    scan whose own long-wavelength tilt inflates its plug-in variogram), so they enter an average
    together or not at all.
    """
    groups: dict = {}
    for name, err in errors.items():
        if err is not None:
            groups.setdefault(settings[name], []).append(name)
    out = dict(errors)
    for names in groups.values():
        if len(names) < 2:
            continue
        first = errors[names[0]]
        coord = first.dims[0]
        if any(errors[n].sizes != first.sizes or not np.allclose(errors[n][coord].values, first[coord].values,
                                                                  rtol=1e-9) for n in names[1:]):
            continue
        stack = xr.Variable.concat([errors[n].variable for n in names], dim="_replicate")
        if stack.chunks is not None:
            stack = stack.chunk({"_replicate": -1})
        pooled = xr.apply_ufunc(_replicate_median, stack, input_core_dims=[["_replicate"]], dask="parallelized",
                                output_dtypes=[float])
        for n in names:
            out[n] = errors[n].copy(data=pooled.data)
    return out


def _curve(ds: xr.Dataset, *, name: str, func, extra: dict, reliable: bool, quantity, post, kw: dict):
    """A measurement's curve (reliable scales marked, ``post`` applied) and its predicted error (or None); ``ds``
    in the twin's length ``units`` already."""
    ds = _complete(ds, name)
    curve = func(ds, **extra, **kw, reliable=False)
    coord = _curve_coord(curve)
    curve, err = _predicted_error(_reliable_part(curve, ds, coord, reliable), ds, coord, quantity)
    return (curve if post is None else post(curve)), err


def _shape(ds: xr.Dataset) -> tuple:
    """What the curves of a measurement rest on besides its data: its variables' dims, shapes, dtypes and attrs,
    its coordinates and its :data:`~xtopo.conventions.MEASUREMENT_ATTRS` (not its provenance)."""
    return ({n: (v.dims, v.shape, v.dtype.str, v.attrs, v.data if n in ds.coords else None)
             for n, v in ds.variables.items()},
            {k: v for k, v in ds.attrs.items() if k.startswith(MEASUREMENT_ATTRS) or k == "measurement_kind"})


def _per_measurement(tree, func, area_kw: dict, line_kw: dict, units: str | None, reliable: bool,
                     quantity: str = "psd", post=None, **kw) -> tuple[dict, dict]:
    """Curves and predicted errors of the measurements; lazy ones (dask) as one task each
    (:func:`~xtopo._one_task.one_task`), their coordinates from one lazy graph per shape."""
    ms = _measurements(tree)
    units = _common_units(ms, units)
    curves, errors, settings, templates = {}, {}, {}, {}
    for name, ds in ms.items():
        ds = convert_length(ds, units)
        extra = area_kw if lateral_dims(ds["height"]) == ("y", "x") else line_kw
        measure = partial(_curve, name=name, func=func, extra=extra, reliable=reliable,
                          quantity=quantity, post=post, kw=kw)
        if ds["height"].chunks is None:  # each average, figure and report of the twin asks again
            curves[name], errors[name] = remember(measure, ds, _shape(ds))
        else:
            from dask.base import tokenize  # deferred: lazy measurements only (the core install has no dask)

            key = tokenize(_shape(ds))
            if key not in templates:
                templates[key] = template(measure(ds))
            curves[name], errors[name] = one_task(measure, ds, templates[key])
        settings[name] = _setting(ds)
    return curves, _pool_errors(errors, settings)


def _with_provenance(out: xr.Dataset, tree, analysis: str, **params) -> xr.Dataset:
    """The twin average ``out`` with its provenance; the one place where twin averages get it.

    As an analysis result of one measurement (:func:`xtopo.analysis._scale.provenance`): the
    twin root's ``source_file``/``source_sha256`` where it has them, and its ``history`` plus one
    line naming the average, its parameters (``units``: the length unit used, also where it
    was the first measurement's) and how many measurements entered. Each
    measurement's ``source_file``, ``source_sha256`` and ``history`` (its preprocessing) become
    coordinates along ``measurement``
    ('' for one without). Only attrs and coordinates built from attrs: a lazy average stays lazy.
    """
    names = [str(n) for n in out["measurement"].values]
    if "units" in params and params["units"] is None:
        params["units"] = _common_units(_measurements(tree))
    coords = {}
    for key, long_name in (("source_file", "file the measurement was read from ('' where unknown)"),
                           ("source_sha256", "SHA-256 checksum of that file ('' where unknown)"),
                           ("history", "processing of the measurement before the average, one step a line")):
        values = [str(tree.children[n].attrs.get(key) or "") for n in names]
        if any(values):
            coords[key] = ("measurement", values, {"long_name": long_name})
    out = provenance(out.assign_coords(coords), tree, f"stitching.{analysis}", **params)
    out.attrs["history"] += f" over {len(names)} measurement{'s' if len(names) != 1 else ''}"
    return out


_CRITERION = """With ``reliable``, a measurement is used only above its short cutoff (tip radius or
    resolution, paper §4.9; spectra also 4 pixels above the pixel size,
    :func:`~xtopo.analysis.statistical_reliability.sampling_cutoff`), and there at every collocation point of
    its range, with equal weight (see :func:`average_curves`). The statistical uncertainty of each
    point is returned (``uncertainty``, ``relative_error``), not used to delete data unless
    ``max_error`` is given."""

_TWIN_PARAMETERS = """tree : xarray.DataTree
        A twin (:func:`xtopo.twin`): one child node per measurement.{extra}
    per_decade : int
        Collocation points per decade of the length scale (default 10).
    units : str, optional
        Length unit of the average (default: the unit of the first measurement).
    reliable : bool
        Use each measurement only where it is reliable (default True; see above).
    max_error : float, optional
        Opt-in statistical criterion: largest predicted relative standard error of an average
        point (e.g. :data:`xtopo.analysis.statistical_reliability.MAX_RELATIVE_ERROR`); the values it
        drops are marked in ``left_out``. Default None: every reliable point is averaged."""

#: Parameters of one average beyond those all share (after ``tree``).
_EXTRA = {
    "twin_average": """
    measure : callable
        The analysis of one measurement, ``measure(ds, **kwargs, reliable=...)`` returning a curve.
    error : callable, optional
        Its error model: ``error(ds, curve)``, the predicted relative standard error of the curve's points
        (a DataArray on its coordinate); replicates share the median (see :func:`_pool_errors`).""",
    "twin_psd": """
    areal : bool
        Average ``Ciso`` of area scans instead of ``C1D`` along x (default False).
    window : {"auto", "hann", None}
        Window of each spectrum, as in :func:`xtopo.analysis.psd.psd` (default ``"auto"``).""",
    "twin_vbm": """
    kind : {"area", "1d"}
        Square blocks of area scans (paper §4.8, default) or segments of their profiles along x
        (SurfaceTopography's container average), as :func:`xtopo.analysis.vbm.vbm`.
    average : {"mean", "rms"}
        Arithmetic mean of the blocks' RMS heights (paper, default) or the RMS over all
        blocks (SurfaceTopography).""",
    "twin_sdrp": """
    order : {1, 2}
        Slope (1, default) or curvature (2).""",
}

_TWIN_RETURNS = """Returns
    -------
    xarray.Dataset
        ``average``, ``uncertainty``, ``relative_error`` and ``count`` on the collocation
        coordinate, the per-measurement ``curves`` and the reliability cutoff and its criterion
        per measurement (see :func:`average_curves`)."""


@checked
def twin_psd(tree, *, areal: Annotated[bool, Flag()] = False, window: Annotated[str | None, WINDOWS] = "auto",
             per_decade: Annotated[int, _PER_DECADE] = PER_DECADE, units: Annotated[str | None, LengthUnit()] = None,
             reliable: Annotated[bool, Flag()] = True, max_error: Annotated[float | None, _MAX_ERROR] = None
             ) -> xr.Dataset:
    """Average PSD of a twin: 1D PSDs (``C1D`` along x) or, with ``areal=True``, ``Ciso``.

    ``areal=True`` needs every measurement to be an area scan. 1D spectra of nonperiodic
    measurements are prewhitened (``psd(prewhiten=True)``: the windowed slopes' spectrum
    divided by ``|D̃_x(q)|²``, which removes the Hann window's bias at a scan's longest
    wavelengths, 1.7-2.7× at ``k = 2`` for ``C1D ∝ q^-2.6``), and their lowest wavevector
    ``2π/L``, inside the window's main lobe around ``q = 0``, is not averaged: ``left_out``
    flags where it would have contributed. {criterion} A spectrum's
    predicted error in a collocation bin is ``1/√N`` with ``N`` the independent Fourier modes of
    its reliable wavevectors there (:func:`~xtopo.analysis.statistical_reliability.independent_samples`).

    Parameters
    ----------
    {parameters}

    {returns}
    """
    params = dict(locals())
    if areal:
        lines = [n for n, ds in _measurements(tree).items() if ds["height"].ndim != 2]
        if lines:
            raise XtopoError(f"areal averages need area scans only; line scans: {lines}")
        return _binned(tree, "twin_psd", params, psd, {"kind": "iso"}, {}, "psd", window=window)
    return _binned(tree, "twin_psd", params, psd, {"kind": "1d", "dim": "x"}, {"kind": "1d"}, "psd", _main_lobe,
                   window=window, prewhiten=True)


def _binned(tree, analysis: str, params: dict, func, area_kw: dict, line_kw: dict, quantity, post=None,
            **kw) -> xr.Dataset:
    """The twin average ``analysis`` in log bins of each measurement's ``func`` (``post`` applied to each curve);
    ``params``: the public function's arguments, in its order, for the provenance (``tree`` left out)."""
    params = {k: v for k, v in params.items() if k != "tree"}
    curves, errors = _per_measurement(tree, func, area_kw, line_kw, params["units"], params["reliable"],
                                      quantity, post, **kw)
    out = average_curves(curves, per_decade=params["per_decade"], method="bin", errors=errors,
                         max_error=params["max_error"])
    return _with_provenance(out, tree, analysis, **params)


def _main_lobe(curve: xr.DataArray) -> xr.DataArray:
    """A 1D spectrum with its lowest wavevector ``2π/L`` marked :data:`UNRELIABLE` where it was windowed.

    The Hann window's main lobe spans ±2 bins: the bin ``k = 1`` lies inside the lobe around
    ``q = 0``, so its expectation is set by the mean removed from each profile and by the
    wavelengths longer than the scan, which the measurement does not resolve (a long-scale
    limit of the windowed estimator, as the tip radius and the resolution are short-scale
    limits, paper §4.3 and §4.9). From ``k = 2`` on, the prewhitened spectrum
    (:func:`~xtopo._kernels.spectra.prewhitening`) is within a few per cent of the truth on average.
    """
    if curve.attrs.get("window") != "hann":
        return curve
    q = np.asarray(curve["q"].values, dtype=float)
    first = q[q > 0].min(initial=np.inf)
    return curve.assign_coords({UNRELIABLE: ("q", (q > 0) & (q < 1.5 * first), {
        "long_name": "points left out of the average",
        "criterion": "lowest wavevector 2π/L of each Hann-windowed spectrum (inside the window's main lobe "
                     "around q = 0: set by the removed mean and by wavelengths longer than the scan)"})})


@checked
def twin_acf(tree, *, per_decade: Annotated[int, _PER_DECADE] = PER_DECADE,
             units: Annotated[str | None, LengthUnit()] = None,
             reliable: Annotated[bool, Flag()] = True, max_error: Annotated[float | None, _MAX_ERROR] = None
             ) -> xr.Dataset:
    """Average height-difference ACF of a twin (profiles along x).

    {criterion} A measurement's predicted error is that of
    :func:`~xtopo.analysis.statistical_reliability.stencil_error`.

    Parameters
    ----------
    {parameters}

    {returns}
    """
    return _binned(tree, "twin_acf", locals(), acf, {"kind": "1d", "dim": "x"}, {"kind": "1d"}, "acf")


@checked
def twin_average(tree, measure: Callable, *, error: Callable | None = None,
                 per_decade: Annotated[int, _PER_DECADE] = PER_DECADE,
                 units: Annotated[str | None, LengthUnit()] = None, reliable: Annotated[bool, Flag()] = True,
                 max_error: Annotated[float | None, _MAX_ERROR] = None, **kwargs) -> xr.Dataset:
    """Average over a twin of any scale-dependent analysis of one measurement, binned.

    The generic twin average of a :class:`TwinAnalysis` declared with ``measure=``: each
    measurement's curve ``measure(ds, **kwargs, reliable=False)`` (on a length or wavevector
    coordinate) is masked below its short cutoff and averaged in log bins as :func:`twin_acf`
    does. {criterion} Without an error model, ``uncertainty`` is NaN.

    Parameters
    ----------
    {parameters}
    **kwargs
        Further arguments of ``measure``.

    {returns}
    """
    params = dict(measure=measure.__name__, error=None if error is None else error.__name__, per_decade=per_decade,
                  units=units, reliable=reliable, max_error=max_error, **kwargs)
    return _binned(tree, "twin_average", params, measure, kwargs, kwargs, error)


def _vbm(ds: xr.Dataset, **kw) -> xr.DataArray:
    """VBM of a measurement; a set of parallel profiles (``measurement_kind="profiles"``: rows far
    apart, as the stylus scans of :func:`xtopo.datasets.example_twin`) is the mean of its profiles'
    line-scan VBMs, not one VBM of a map with rows as far apart as the scan is long."""
    if ds.attrs.get("measurement_kind") == "profiles" and ds["height"].ndim == 2:
        kw["kind"] = "1d"
    return vbm(ds, **kw)


@checked
def twin_vbm(tree, *, kind: Annotated[str, Choice("area", "1d")] = "area",
             average: Annotated[str, Choice("mean", "rms")] = "mean",
             per_decade: Annotated[int, _PER_DECADE] = PER_DECADE,
             units: Annotated[str | None, LengthUnit()] = None,
             reliable: Annotated[bool, Flag()] = True, max_error: Annotated[float | None, _MAX_ERROR] = None
             ) -> xr.Dataset:
    """Average variable-bandwidth RMS height of a twin.

    {criterion} A measurement's predicted error is ``1/(2√N)`` with ``N`` independent windows.

    Parameters
    ----------
    {parameters}

    {returns}
    """
    return _binned(tree, "twin_vbm", locals(), _vbm, {"kind": kind}, {}, "vbm", average=average)


@checked
def twin_sdrp(tree, order: Annotated[int, Choice(1, 2)] = 1, *, per_decade: Annotated[int, _PER_DECADE] = PER_DECADE,
              units: Annotated[str | None, LengthUnit()] = None, reliable: Annotated[bool, Flag()] = True,
              max_error: Annotated[float | None, _MAX_ERROR] = None) -> xr.Dataset:
    """Average scale-dependent slope (``order=1``) or curvature (``order=2``) of a twin.

    Every measurement is evaluated at exactly the common collocation distances
    (fractional scale factors by linear interpolation, §4.10). {criterion} A measurement's
    predicted error is that of :func:`~xtopo.analysis.statistical_reliability.stencil_error` of the
    slope or curvature.

    Parameters
    ----------
    {parameters}

    {returns}
    """
    ms = _measurements(tree)
    units = _common_units(ms, units)
    lo, hi = np.inf, 0.0
    for ds in ms.values():
        x = np.asarray(ds["x"].values, dtype=float) * length_factor(ds["x"].attrs.get("units", units), units)
        if x.size > 1:  # a single point has no slope: its curve stays empty
            lo = min(lo, float(np.min(np.diff(x))))
            hi = max(hi, float(x[-1] - x[0]) / 2)
    if not hi > 0:
        raise GridError("twin_sdrp needs a measurement with at least two points along 'x'")
    grid = collocation_points(lo, hi, per_decade)

    def on_grid(ds, reliable):  # the common collocation distances inside the measurement's range
        x = np.asarray(ds["x"].values, dtype=float)
        mine = grid[:0] if x.size < 2 else grid[(grid >= np.min(np.diff(x)) * (1 - 1e-9))
                                                & (grid <= (x[-1] - x[0]) / 2)]
        return sdrp(ds, order, dim="x", distances=mine, reliable=reliable)

    curves, errors = _per_measurement(tree, on_grid, {}, {}, units, reliable, ("slope", "curvature")[order - 1])
    out = average_curves(curves, points=grid, errors=errors, max_error=max_error)
    return _with_provenance(out, tree, "twin_sdrp", order=order, per_decade=per_decade, units=units,
                            reliable=reliable, max_error=max_error)


for _f in (twin_psd, twin_acf, twin_vbm, twin_sdrp, twin_average):
    _f.__doc__ = _f.__doc__.format(criterion=_CRITERION, returns=_TWIN_RETURNS,
                                   parameters=_TWIN_PARAMETERS.format(extra=_EXTRA.get(_f.__name__, "")))


@dataclass(frozen=True)
class TwinAnalysis:
    """One scale-dependent analysis of a twin, declared once (the report, the CLI, the figure and
    :func:`analyze_twin` loop over :data:`ANALYSES`).

    Attributes
    ----------
    name : str
        Key (group name in the NetCDF output, ``--analyses`` of the CLI).
    function : callable or None
        The twin average, ``function(tree, **kwargs, per_decade=..., ...)`` returning the
        Dataset of :func:`average_curves`; None: :func:`twin_average` of :attr:`measure`.
    coord : str
        Its coordinate (``q``: wavevector, 1/length; others: lengths).
    averaging : str
        How measurements meet at the collocation points (``"bin"``: log bins, interpolated
        between sparse points; ``"points"``: evaluated at the points).
    error_model : str
        How the predicted statistical error of each measurement's curve is obtained.
    title : str
        Plot title.
    kwargs : dict
        Fixed arguments of ``function`` (SDRP: ``order=2``, the curvature of Figure 5), or of
        :attr:`measure`.
    measure : callable, optional
        The analysis of one measurement that :func:`twin_average` averages (with ``function=None``):
        a new scale-dependent analysis needs this record and its module, nothing else.
    error : callable, optional
        The error model :func:`twin_average` uses, ``error(ds, curve)`` (None: uncertainty unknown).
    """

    name: str
    function: Callable | None
    coord: str
    averaging: str
    error_model: str
    title: str
    kwargs: Mapping = field(default_factory=dict)
    measure: Callable | None = None
    error: Callable | None = None

    def __call__(self, tree, **kwargs) -> xr.Dataset:
        """The twin average of this analysis (``kwargs`` as of :attr:`function`, or of :func:`twin_average`)."""
        if self.function is None:
            return twin_average(tree, self.measure, error=self.error, **{**self.kwargs, **kwargs})
        return self.function(tree, **{**self.kwargs, **kwargs})


#: The twin analyses of the paper's Figure 5, in its order.
ANALYSES: dict[str, TwinAnalysis] = {a.name: a for a in (
    TwinAnalysis("psd", twin_psd, "q", "bin", "1/√N, N independent Fourier modes in the bin",
                 "power spectral density (1D)"),
    TwinAnalysis("acf", twin_acf, "distance", "bin", "variance of the mean square difference (stencil_error)",
                 "height-difference autocorrelation"),
    TwinAnalysis("vbm", twin_vbm, "bandwidth", "bin", "1/(2√N), N independent windows",
                 "variable-bandwidth RMS height"),
    TwinAnalysis("sdrp", twin_sdrp, "distance", "points", "variance of the mean square curvature (stencil_error)",
                 "scale-dependent RMS curvature", {"order": 2}),
    TwinAnalysis("curvature_kurtosis", None, "distance", "bin", "√(24/N)/3 of a Gaussian surface, N independent "
                 "stretches", "kurtosis of the scale-dependent curvature", measure=curvature_kurtosis,
                 error=curvature_kurtosis_error),
)}


@checked
def analyze_twin(tree, *, per_decade: Annotated[int, _PER_DECADE] = PER_DECADE,
                 progress: Annotated[bool | None, Flag(optional=True)] = False) -> xr.DataTree:
    """The main job: per-measurement summary and the averaged curves of a twin (:data:`ANALYSES`).

    Parameters
    ----------
    tree : xarray.DataTree
        The twin.
    per_decade : int
        Collocation points per decade of the averages.
    progress : bool, optional
        A progress bar over the analyses (None: on a terminal or in a notebook).

    Returns
    -------
    xarray.DataTree
        Root: the summary table (scalars per measurement); one group per analysis of
        :data:`ANALYSES` (``psd``, ``acf``, ``vbm``, ``sdrp``: the curvature) with the
        averages, uncertainties, counts and per-measurement curves (computed).
    """
    ms = _measurements(tree)
    results = {"/": summary_table(ms).assign_attrs({**tree.attrs, "title": tree.attrs.get("title", "twin analysis")})}

    for name, analysis in progress_bar(ANALYSES.items(), desc="twin averages", unit="analysis", enabled=progress):
        results[f"/{name}"] = analysis(tree, per_decade=per_decade).compute()
    return xr.DataTree.from_dict(results)
