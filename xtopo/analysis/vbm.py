"""Variable bandwidth method (paper §4.8)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._apply import apply_lateral
from .._kernels import bandwidth as _k
from ..conventions import X
from ..errors import XtopoError
from ..params import Count, Flag, checked
from ._scale import finish, length_coord, prepare, provenance
from .reliability import apply_reliability

__all__ = ["vbm"]


@checked
def vbm(obj, *, min_pixels: Annotated[int, Count(min=2)] = 4, reliable: Annotated[bool, Flag()] = True) -> xr.DataArray:
    """Mean tilt-corrected RMS height as a function of the bandwidth ``ℓ = L/ζ``.

    The map is cut into ``ζ × ζ`` rectangles (``ζ`` segments for line scans),
    ``ζ = 1, 2, 4, …`` while a block keeps at least ``min_pixels`` pixels per side;
    a plane (line) is fitted and removed in every block, the RMS height computed,
    and the mean over blocks reported.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement; extra dims broadcast, dask stays lazy.
    min_pixels : int
        Smallest block side in pixels: at least 3 for line scans, 2 for area scans (a
        smaller block holds no more pixels than the fitted line/plane has parameters).
    reliable : bool
        Drop bandwidths below the reliability cutoff.

    Returns
    -------
    xarray.DataArray
        ``vbm`` (length) on coord ``bandwidth`` (length; ``sqrt(Lx Ly)/ζ`` for area
        scans, ``L/ζ`` for line scans), ascending, with coord ``magnification`` (ζ).
    """
    prep = prepare(obj)
    h, u = prep.h, prep.units
    if min_pixels < 2 + (not prep.is_area):
        raise XtopoError(f"min_pixels must be an integer >= 3 for a line scan, got {min_pixels!r}")
    sizes = [h.sizes[d] for d in prep.lat]
    levels = _k.vbm_levels(sizes, min_pixels)
    kwargs = dict(dx=prep.spacing(X), levels=levels, ndim=len(prep.lat))
    out = apply_lateral(_k.vbm, h, output_core_dims=[["bandwidth"]], output_sizes={"bandwidth": levels.size},
                        kwargs=kwargs, height_power=(1,), what="vbm")
    length = float(np.prod([prep.size(d) for d in prep.lat]) ** (1 / len(prep.lat)))  # sqrt(Lx Ly), or L
    out = out.assign_coords(bandwidth=length_coord("bandwidth", length / levels, u, "bandwidth"),
                            magnification=("bandwidth", levels, {"units": "1", "long_name": "magnification ζ"}))
    out = out.isel(bandwidth=slice(None, None, -1))
    out = finish(out, "vbm", u, "mean tilt-corrected RMS height", prep, "vbm", min_pixels=int(min_pixels))
    out = apply_reliability(out, obj, coord="bandwidth", kind="length", reliable=reliable)
    return provenance(out, obj, "vbm", min_pixels=min_pixels, reliable=reliable)
