"""Averages of scale-dependent curves over a digital surface twin (paper §4.10).

Each measurement's curve (PSD, ACF, VBM, SDRP) is computed in its 1D (profile)
representation with its unreliable scales removed (§4.9), interpolated in
log-log space onto common log-spaced collocation points, and averaged with
equal weight per measurement wherever at least one measurement is reliable.
Everything stays lazy on dask-backed twins: the graph is built from coordinates
alone, data are read and computed only by ``.compute()`` (threaded scheduler,
or the active ``distributed.Client``).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ._kernels.collocation import bin_mean, collocation_points, interp_loglog
from .conventions import MASK, convert_length, lateral_dims, length_factor
from .errors import XtopoError
from .twins import measurements as _measurements

__all__ = ["average_curves", "twin_psd", "twin_acf", "twin_vbm", "twin_sdrp"]

#: default density of collocation points
PER_DECADE = 10
#: coordinate holding the independent modes of each wavevector of a spectrum
_MODES = "independent_modes"


def _common_units(ms: dict) -> str:
    for ds in ms.values():
        return ds["x"].attrs.get("units", "m")
    raise XtopoError("the twin has no measurements")


def _curve_coord(curve: xr.DataArray) -> str:
    dims = [d for d in curve.dims if d in curve.coords and d not in ("x", "y")]
    if len(dims) != 1:
        raise XtopoError(f"expected a curve with one coordinate dimension, got dims {curve.dims}")
    return dims[0]


def _onto(curve: xr.DataArray, coord: str, grid: np.ndarray, method: str) -> xr.DataArray:
    x = np.asarray(curve[coord].values, dtype=float)
    clean = curve.drop_vars([c for c in curve.coords if c != coord])
    kwargs = dict(x=x, xnew=grid)
    if method == "bin" and _MODES in curve.coords:  # spectra: independent modes add up within a bin
        kwargs.update(weights=np.asarray(curve[_MODES].values), min_weight=curve.attrs["min_independent"])
    kernel = {"interp": interp_loglog, "bin": bin_mean}[method]
    out = xr.apply_ufunc(kernel, clean, input_core_dims=[[coord]], output_core_dims=[["_grid"]],
                         exclude_dims={coord}, kwargs=kwargs, dask="parallelized",
                         output_dtypes=[float], dask_gufunc_kwargs={"output_sizes": {"_grid": grid.size}})
    return out


def average_curves(curves: dict, *, per_decade: int = PER_DECADE, points=None, method: str = "interp") -> xr.Dataset:
    """Average 1D curves of several measurements at common log-spaced points.

    Parameters
    ----------
    curves : dict of str to xarray.DataArray
        One curve per measurement, each with a single coordinate dim (``q``,
        ``distance`` or ``bandwidth``) in the same units; NaN marks unreliable points.
    per_decade : int
        Density of collocation points when ``points`` is not given.
    points : array_like, optional
        Explicit collocation points.
    method : {"interp", "bin"}
        ``"interp"``: log-log interpolation of each curve (smooth or sparse curves:
        SDRP, VBM); ``"bin"``: mean of each curve's points in log bins around the
        collocation points (dense, noisy curves: PSD, ACF; paper §4.10).

    Returns
    -------
    xarray.Dataset
        ``average`` and ``count`` on the collocation coordinate, ``curves`` on
        (``measurement``, coordinate) and ``reliability_cutoff`` per measurement
        where the curves carry one.
    """
    if not curves:
        raise XtopoError("no curves to average")
    first = next(iter(curves.values()))
    coord = _curve_coord(first)
    if points is None:
        lo = min(float(np.min(c[coord].values[c[coord].values > 0])) for c in curves.values() if c.sizes[coord])
        hi = max(float(np.max(c[coord].values)) for c in curves.values() if c.sizes[coord])
        grid = collocation_points(lo, hi, per_decade)
    else:
        grid = np.asarray(points, dtype=float)
    names = list(curves)
    per = [_onto(curves[n], coord, grid, method) for n in names]
    stacked = xr.concat(per, dim=xr.DataArray(names, dims="measurement", name="measurement"))
    stacked = stacked.rename({"_grid": coord}).assign_coords({coord: (coord, grid, dict(first[coord].attrs))})
    stacked.attrs = {k: v for k, v in first.attrs.items() if k in ("units", "long_name")}
    count = stacked.notnull().sum("measurement")
    total = stacked.fillna(0.0).sum("measurement")
    average = (total / count.where(count > 0)).assign_attrs(
        units=first.attrs.get("units", "1"), long_name=f"average {first.attrs.get('long_name', first.name or '')}".strip())
    count.attrs = {"units": "1", "long_name": "number of measurements contributing"}
    out = xr.Dataset({"average": average, "count": count, "curves": stacked})
    cuts = [c.coords["reliability_cutoff"].variable if "reliability_cutoff" in c.coords else xr.Variable((), np.nan)
            for c in curves.values()]
    if all(v.ndim == 0 for v in cuts):
        units = next((c.coords["reliability_cutoff"].attrs.get("units") for c in curves.values()
                      if "reliability_cutoff" in c.coords), "")
        out["reliability_cutoff"] = xr.concat([xr.DataArray(v) for v in cuts], dim="measurement").assign_attrs(
            units=units, long_name="short reliability cutoff")
    out.attrs = {"title": f"twin average of {first.name or 'curves'}", "collocation_points_per_decade": per_decade,
                 "collocation_method": method,
                 "weighting": "equal weight per measurement over its reliable scales"}
    return out


def _complete(ds: xr.Dataset) -> xr.Dataset:
    """Measurements with missing data are filled harmonically first (paper §3.2); lazy on dask."""
    if MASK in ds.data_vars:
        from .preprocess import fill_missing

        return fill_missing(ds)
    return ds


def _statistically_reliable(curve: xr.DataArray, ds: xr.Dataset, coord: str, max_error, quantity: str) -> xr.DataArray:
    """Attach (spectra) or apply (real-space curves) the long-scale statistical criterion.

    Spectra: each wavevector carries its independent Fourier modes; a collocation bin
    counts when its modes reach ``1/max_error²`` (relative error ``1/√N``). ACF and SDRP:
    the predicted relative error of :func:`~xtopo.analysis.reliability.stencil_error`.
    VBM: ``1/(2√N)`` with ``N`` independent windows.
    """
    from .analysis.reliability import MAX_RELATIVE_ERROR, independent_samples, stencil_error

    tol = MAX_RELATIVE_ERROR if max_error is None else float(max_error)
    direction = curve.attrs.get("direction", "x")
    x = np.asarray(curve[coord].values, dtype=float)
    if coord == "q":
        n = independent_samples(ds, coord, x, dim=direction)
        out = curve.assign_coords({_MODES: (coord, n, {"units": "1", "long_name": "independent Fourier modes"})})
        out.attrs = dict(curve.attrs, min_independent=tol**-2 if tol > 0 else np.inf, max_error=tol)
        return out
    if quantity == "vbm":
        n = independent_samples(ds, coord, x, dim=direction)
        with np.errstate(divide="ignore"):
            err = xr.DataArray(np.where(n > 0, 0.5 / np.sqrt(np.where(n > 0, n, 1.0)), np.inf), dims=coord)
    else:
        err = stencil_error(ds, x, quantity=quantity, dim=direction).rename(distance=coord).drop_vars(coord)
    out = curve.where(err <= tol)
    out.attrs = dict(curve.attrs, max_error=tol)
    return out


def _reliable_part(curve: xr.DataArray, ds: xr.Dataset, coord: str, reliable: bool) -> xr.DataArray:
    """Mask (never drop) the unreliable scales so every backend yields the same coordinates.

    Short-scale criteria: tip radius or resolution (paper §4.9) and, for spectra, the
    sampling criterion :func:`~xtopo.analysis.reliability.sampling_cutoff`.
    """
    if not reliable:
        return curve
    from .analysis.reliability import reliability_cutoff, sampling_cutoff

    cut = reliability_cutoff(ds)
    if coord == "q":  # spectra also end where aliasing sets in
        cut = np.fmax(cut, sampling_cutoff(ds, curve.attrs.get("direction", "x")))
    x = curve[coord]
    keep = (x <= 2 * np.pi / cut) if coord == "q" else (x >= cut)
    out = curve.where(keep | ~(cut > 0))
    out.attrs = dict(curve.attrs, reliable=1)
    return out.assign_coords(reliability_cutoff=cut.variable)


def _per_measurement(tree, func, area_kw: dict, line_kw: dict, units: str | None, reliable: bool,
                     max_error=None, quantity: str = "psd", **kw) -> dict:
    ms = _measurements(tree)
    units = units or _common_units(ms)
    out = {}
    for name, ds in ms.items():
        ds = _complete(convert_length(ds, units))
        extra = area_kw if lateral_dims(ds["height"]) == ("y", "x") else line_kw
        curve = func(ds, **extra, **kw, reliable=False)
        coord = _curve_coord(curve)
        curve = _reliable_part(curve, ds, coord, reliable)
        out[name] = _statistically_reliable(curve, ds, coord, max_error, quantity) if reliable else curve
    return out


def twin_psd(tree, *, areal: bool = False, window="auto", per_decade: int = PER_DECADE, units: str | None = None,
             reliable: bool = True, max_error: float | None = None) -> xr.Dataset:
    """Average PSD of a twin: 1D PSDs (``C1D`` along x) or, with ``areal=True``, ``Ciso``.

    ``areal=True`` needs every measurement to be an area scan. With ``reliable``, each
    measurement contributes only where its scales are reliable: above its short cutoff
    (paper §4.9) and where its predicted relative standard error is at most ``max_error``
    (default :data:`xtopo.analysis.reliability.MAX_RELATIVE_ERROR`): spectra in collocation
    bins holding at least ``1/max_error²`` independent Fourier modes (see
    :func:`~xtopo.analysis.reliability.independent_samples`).
    """
    from .analysis.psd import psd

    if areal:
        ms = _measurements(tree)
        lines = [n for n, ds in ms.items() if ds["height"].ndim != 2]
        if lines:
            raise XtopoError(f"areal averages need area scans only; line scans: {lines}")
        curves = _per_measurement(tree, psd, {"kind": "iso"}, {}, units, window=window, reliable=reliable,
                                  max_error=max_error)
    else:
        curves = _per_measurement(tree, psd, {"kind": "1d", "dim": "x"}, {"kind": "1d"}, units, window=window,
                                  reliable=reliable, max_error=max_error)
    return average_curves(curves, per_decade=per_decade, method="bin")


def twin_acf(tree, *, per_decade: int = PER_DECADE, units: str | None = None, reliable: bool = True,
             max_error: float | None = None) -> xr.Dataset:
    """Average height-difference ACF of a twin (profiles along x).

    Reliability as in :func:`twin_psd`; the long-scale criterion is the predicted relative
    error of :func:`~xtopo.analysis.reliability.stencil_error` (at most ``max_error``).
    """
    from .analysis.acf import acf

    curves = _per_measurement(tree, acf, {"kind": "1d", "dim": "x"}, {"kind": "1d"}, units, reliable=reliable,
                              max_error=max_error, quantity="acf")
    return average_curves(curves, per_decade=per_decade, method="bin")


def twin_vbm(tree, *, per_decade: int = PER_DECADE, units: str | None = None, reliable: bool = True,
             max_error: float | None = None) -> xr.Dataset:
    """Average variable-bandwidth RMS height of a twin.

    Reliability as in :func:`twin_psd`; long-scale error ``1/(2√N)`` with ``N`` independent windows.
    """
    from .analysis.vbm import vbm

    curves = _per_measurement(tree, vbm, {}, {}, units, reliable=reliable, max_error=max_error, quantity="vbm")
    return average_curves(curves, per_decade=per_decade)


def twin_sdrp(tree, order: int = 1, *, per_decade: int = PER_DECADE, units: str | None = None,
              reliable: bool = True, max_error: float | None = None) -> xr.Dataset:
    """Average scale-dependent slope (``order=1``) or curvature (``order=2``) of a twin.

    Every measurement is evaluated at exactly the common collocation distances
    (fractional scale factors by linear interpolation, §4.10); reliability as in :func:`twin_acf`
    (:func:`~xtopo.analysis.reliability.stencil_error` of the slope or curvature).
    """
    from .analysis.sdrp import sdrp

    ms = _measurements(tree)
    units = units or _common_units(ms)
    lo, hi = np.inf, 0.0
    for ds in ms.values():
        x = np.asarray(ds["x"].values, dtype=float) * length_factor(ds["x"].attrs.get("units", units), units)
        lo = min(lo, float(np.min(np.diff(x))))
        hi = max(hi, float(x[-1] - x[0]) / 2)
    grid = collocation_points(lo, hi, per_decade)
    curves = {}
    for name, ds in ms.items():
        ds = _complete(convert_length(ds, units))
        x = np.asarray(ds["x"].values, dtype=float)
        mine = grid[(grid >= np.min(np.diff(x)) * (1 - 1e-9)) & (grid <= (x[-1] - x[0]) / 2)]
        curve = _reliable_part(sdrp(ds, order, dim="x", distances=mine, reliable=False), ds, "distance", reliable)
        curves[name] = (_statistically_reliable(curve, ds, "distance", max_error, ("slope", "curvature")[order - 1])
                        if reliable else curve)
    return average_curves(curves, points=grid)


def analyze_twin(tree, *, per_decade: int = PER_DECADE) -> xr.DataTree:
    """The main job: per-measurement summary and the four averaged curves of a twin.

    Returns
    -------
    xarray.DataTree
        Root: the summary table (scalars per measurement); groups ``psd``, ``acf``,
        ``vbm``, ``sdrp`` with the averages, counts and per-measurement curves (computed).
    """
    from .summary import summary_table

    ms = _measurements(tree)
    results = {"/": summary_table(ms).assign_attrs({**tree.attrs, "title": tree.attrs.get("title", "twin analysis")})}
    for name, func in (("psd", twin_psd), ("acf", twin_acf), ("vbm", twin_vbm), ("sdrp", twin_sdrp)):
        results[f"/{name}"] = func(tree, per_decade=per_decade).compute()
    return xr.DataTree.from_dict(results)
