"""Reliability analysis (paper §4.9): which scales of a measurement can be trusted.

Two sources, checked in this order:

* ``resolution`` attribute (optical instruments): everything below the lateral
  resolution is unreliable;
* ``tip_radius`` attribute (scanning probes): the scale ``ℓ`` below which the
  largest negative curvature at that scale exceeds the tip curvature, eq. (13),
  ``max_x[-D²_(ℓ) h] > c / R_tip`` with ``c = 1/2``.

The curvature criterion expects peaks to point up (positive heights).
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._apply import apply_lateral, check_core_chunks
from .._kernels.collocation import collocation_points
from .._kernels.scaled import max_negative_curvature
from ..conventions import length_attr, length_factor
from ..errors import GridError
from ..params import Positive, checked
from ._scale import POINTS_PER_DECADE, prepare

__all__ = ["reliability_cutoff", "apply_reliability", "reliable_scales", "TIP_FACTOR"]

#: the constant ``c`` of eq. (13)
TIP_FACTOR = 0.5


def _attr_length(obj, key, units):
    val = length_attr(obj, key)
    if val is None:
        return None
    src = obj.attrs.get(f"{key}_units")
    return val * length_factor(src, units) if src else val


def _crossing(curv: np.ndarray, dist: np.ndarray, threshold: float) -> np.ndarray:
    """Largest distance at which ``curv > threshold``, refined by log-log interpolation to the next point."""
    rows = curv.reshape(-1, curv.shape[-1])
    bad = rows > threshold
    res = np.zeros(rows.shape[0])
    for i, c in enumerate(rows):  # loop over the batch only
        idx = np.flatnonzero(bad[i])
        if idx.size == 0:  # 0: the tip limits no scale
            continue
        j = idx[-1]
        if j + 1 >= dist.size or not np.isfinite(c[j + 1]) or c[j + 1] <= 0:
            res[i] = dist[j]
            continue
        c0, c1 = np.log(c[j]), np.log(c[j + 1])
        t = (c0 - np.log(threshold)) / (c0 - c1) if c0 != c1 else 0.0
        res[i] = float(np.exp(np.log(dist[j]) + t * (np.log(dist[j + 1]) - np.log(dist[j]))))
    return res.reshape(curv.shape[:-1])


def _tip_cutoff(h: xr.DataArray, *, lat, dims, spacings, periodic, threshold) -> xr.DataArray:
    """Tip-radius cutoff of eq. (13) along each of ``dims`` (combined by max), on the heights ``h``."""
    cut = None
    for dim in dims:
        other = [d for d in lat if d != dim]
        dx = spacings[dim]
        etas = np.unique(collocation_points(1.0, (h.sizes[dim] - 1) / 2, POINTS_PER_DECADE))
        curv = apply_lateral(max_negative_curvature, h, core_dims=tuple(other) + (dim,),
                             output_core_dims=[["_eta"]], output_sizes={"_eta": etas.size},
                             kwargs=dict(dx=dx, etas=etas, periodic=periodic, rows=len(other)),
                             height_power=(1,), what="reliability_cutoff")
        one = xr.apply_ufunc(_crossing, curv, input_core_dims=[["_eta"]],
                             kwargs=dict(dist=2 * etas * dx, threshold=threshold))
        cut = one if cut is None else np.maximum(cut, one)
    return cut


def _tip_cutoff_block(values: np.ndarray, *, batch, lat, **kw) -> np.ndarray:
    """:func:`_tip_cutoff` of one block of heights (lateral dims last), as numpy."""
    return _tip_cutoff(xr.DataArray(values, dims=batch + tuple(lat)), lat=lat, **kw).transpose(*batch).values


@checked
def reliability_cutoff(obj, *, c: Annotated[float, Positive()] = TIP_FACTOR) -> xr.DataArray:
    """Shortest reliable length scale of a measurement (paper §4.9).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement (attrs ``resolution`` or ``tip_radius`` with ``*_units``).
    c : float
        Factor of the tip criterion eq. (13); the paper uses 1/2.

    Returns
    -------
    xarray.DataArray
        The cutoff length in the measurement's length unit (0-d, or over batch
        dims for a tip-radius criterion on a batch); NaN when the measurement
        has neither attribute; 0 when the tip criterion holds at every scale the data
        resolve (the tip does not limit the measurement). Attr ``method`` says which
        criterion was used.
        Lazy on dask inputs.

    Raises
    ------
    ValidationError
        If ``tip_radius`` or ``resolution`` is not a positive number.
    GridError
        If the tip-radius criterion is asked for on data with fewer than 3 points
        along every lateral dim (no curvature can be formed).
    """
    prep = prepare(obj)
    h, units = prep.h, prep.units
    attrs = {"units": units, "long_name": "short reliability cutoff"}
    res = _attr_length(obj, "resolution", units)
    if res is not None:
        return xr.DataArray(res, name="reliability_cutoff", attrs=dict(attrs, method="resolution"))
    tip = _attr_length(obj, "tip_radius", units)
    if tip is None:
        return xr.DataArray(np.nan, name="reliability_cutoff", attrs=dict(attrs, method="none"))
    dims = [dim for dim in prep.lat if (h.sizes[dim] - 1) / 2 >= 1]
    if not dims:
        raise GridError(f"reliability_cutoff: the tip-radius criterion (eq. 13) needs at least 3 points along "
                        f"{' or '.join(repr(d) for d in prep.lat)}, these data have {dict(h.sizes)}; remove the "
                        "'tip_radius' attribute or pass reliable=False")
    kw = dict(lat=tuple(prep.lat), dims=tuple(dims), spacings={d: prep.spacing(d) for d in dims},
              periodic=prep.periodic, threshold=c / tip)
    if h.chunks is None:
        cut = _tip_cutoff(h, **kw)
    else:  # one task per chunk, not a chain of dask arrays: building those dominated twins of many files
        check_core_chunks(h, tuple(prep.lat), "reliability_cutoff")
        batch = tuple(d for d in h.dims if d not in prep.lat)
        cut = xr.apply_ufunc(_tip_cutoff_block, h, input_core_dims=[list(prep.lat)], kwargs=dict(kw, batch=batch),
                             dask="parallelized", output_dtypes=[float])
    cut = cut.drop_vars([v for v in cut.coords if v == "_eta"], errors="ignore")
    cut.name = "reliability_cutoff"
    cut.attrs = dict(attrs, method="tip_radius", tip_radius=tip, tip_factor=c)
    return cut


def reliable_scales(x, cut, kind: str):
    """Where the abscissae ``x`` of a curve are reliable for the short cutoff ``cut`` (numpy or xarray, lazy or not).

    ``kind="q"``: ``x <= 2π/cut``; ``kind="length"``: ``x >= cut``. A cutoff ``<= 0`` keeps every scale.
    """
    if kind != "q":
        return x >= cut
    return (x <= 2 * np.pi / xr.where(cut > 0, cut, np.nan)) | (cut <= 0)  # no division by a zero cutoff


def apply_reliability(result: xr.DataArray, obj, *, coord: str, kind: str, reliable: bool) -> xr.DataArray:
    """Drop (or, for lazy data-dependent cutoffs, mask) the unreliable scales of ``result``.

    ``kind="q"``: keep ``q <= 2π/cutoff``; ``kind="length"``: keep ``coord >= cutoff``.
    The cutoff and its method are stored in ``result.attrs``.
    """
    if not reliable:
        result.attrs.update(reliable=0)
        return result
    cut = reliability_cutoff(obj)
    attrs = dict(result.attrs, reliable=1, reliability_method=cut.attrs["method"],
                 reliability_cutoff_units=cut.attrs["units"])
    if cut.attrs["method"] == "none":
        attrs["reliability_cutoff"] = np.nan
        result.attrs = attrs
        return result
    x = result[coord]
    if cut.ndim == 0 and cut.chunks is None:
        attrs["reliability_cutoff"] = value = float(cut)
        out = result.sel({coord: reliable_scales(x, value, kind).values})
        out.attrs = attrs
        return out
    out = result.where(reliable_scales(x, cut, kind))
    if out.chunks is None:
        valid = out.notnull()
        other = [d for d in out.dims if d != coord]
        out = out.sel({coord: valid.any(other).values if other else valid.values})
        attrs["reliability_cutoff"] = float(cut.max())
    out = out.assign_coords(reliability_cutoff=cut.variable.copy(deep=False))
    out.attrs = attrs
    return out
