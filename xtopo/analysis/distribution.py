"""Distributions of heights, slopes and curvatures (paper §4.4)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._apply import apply_lateral
from .._checks import bin_count
from .._kernels.derivatives import forward_difference, second_difference
from ..conventions import X, height_of, is_periodic, lateral_dims, shared_length_unit, spacing
from ..errors import XtopoError
from ..params import Choice, Count, checked
from ._scale import provenance, unit_of

__all__ = ["distribution"]

#: quantity → the unit kinds (:func:`._scale.unit_of`) of its values and of its probability density
_KINDS = {"height": ("L", "L-1"), "slope": ("1", "1"), "curvature": ("L-1", "L")}
_DIFFERENCES = {"slope": forward_difference, "curvature": second_difference}


def _histogram(h, *, kind, bins, dx, axis, periodic, ndim):
    v = h if kind == "height" else _DIFFERENCES[kind](h, dx, periodic=periodic, axis=axis)
    flat = v.reshape(v.shape[: v.ndim - ndim] + (-1,))
    out_d = np.empty(flat.shape[:-1] + (bins,))
    out_c = np.empty(flat.shape[:-1] + (bins,))
    for idx in np.ndindex(flat.shape[:-1]):
        vals = flat[idx]
        vals = vals[np.isfinite(vals)]
        if vals.size == 0:
            out_d[idx] = out_c[idx] = np.nan
            continue
        lo, hi = vals.min(), vals.max()
        if hi <= lo:
            pad = abs(lo) * 1e-9 or 1e-300
            lo, hi = lo - pad, hi + pad
        dens, edges = np.histogram(vals, bins=bins, range=(lo, hi), density=True)
        out_d[idx] = dens
        out_c[idx] = (edges[1:] + edges[:-1]) / 2
    return out_d, out_c


@checked
def distribution(obj, kind: Annotated[str, Choice(*_KINDS)] = "height", *, dim: str = X,
                 bins: Annotated[int, Count()] = 100) -> xr.Dataset:
    """Probability density of heights, slopes or curvatures.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement or its height.
    kind : {"height", "slope", "curvature"}
        Slopes use the forward difference, curvatures the central second
        difference of paper Table 1, along ``dim``.
    dim : {"x", "y"}
        Direction of the derivative (ignored for heights).
    bins : int
        Number of equal-width bins spanning each measurement's range.

    Returns
    -------
    xarray.Dataset
        ``probability_density`` on dim ``bin`` with the coordinate ``bin_center``
        (which may vary along batch dims); units are the inverse of the quantity's.
    """
    h = height_of(obj)
    lat = lateral_dims(h)
    bins = bin_count(bins, "bins", int(np.prod([h.sizes[d] for d in lat])))
    if not isinstance(dim, str) or dim not in lat:
        raise XtopoError(f"dim {dim!r} is not a lateral dim of this measurement ({lat})")
    units = shared_length_unit(h, "distribution")
    qunits, dunits = (unit_of(k, units) for k in _KINDS[kind])
    axis = -1 if dim == lat[-1] else -2
    dx = spacing(h, dim) if kind != "height" else 1.0
    dens, centers = apply_lateral(
        _histogram, h, output_core_dims=[["bin"], ["bin"]], output_sizes={"bin": bins},
        kwargs=dict(kind=kind, bins=bins, dx=dx, axis=axis, periodic=is_periodic(h), ndim=len(lat)),
        height_power=(-1, 1), what="distribution")
    dens.attrs = {"units": dunits, "long_name": f"probability density of {kind}"}
    centers.attrs = {"units": qunits, "long_name": f"{kind} (bin centre)"}
    ds = xr.Dataset({"probability_density": dens}, coords={"bin_center": centers})
    ds.attrs = {"title": f"{kind} distribution", "kind": kind, "direction": dim if kind != "height" else ""}
    return provenance(ds, obj, "distribution", kind=kind, dim=dim, bins=bins)
