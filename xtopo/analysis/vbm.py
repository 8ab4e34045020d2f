"""Variable bandwidth method (paper §4.8)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._apply import apply_lateral
from .._kernels import bandwidth as _k
from ..conventions import X
from ..errors import XtopoError
from ..params import Choice, Count, Flag, checked
from ._scale import finish, length_coord, prepare, provenance
from .reliability import apply_reliability

__all__ = ["vbm"]


@checked
def vbm(obj, *, min_pixels: Annotated[int, Count(min=2)] = 4, reliable: Annotated[bool, Flag()] = True,
        kind: Annotated[str, Choice("area", "1d")] = "area", dim: str = X,
        average: Annotated[str, Choice("mean", "rms")] = "mean") -> xr.DataArray:
    """Mean tilt-corrected RMS height as a function of the bandwidth ``ℓ = L/ζ``.

    The map is cut into ``ζ × ζ`` rectangles (``ζ`` segments for line scans),
    ``ζ = 1, 2, 4, …`` while a block keeps at least ``min_pixels`` pixels per side;
    a plane (line) is fitted and removed in every block, the RMS height computed,
    and the mean over blocks reported (paper §4.8). ``kind="1d"`` and ``average="rms"``
    give SurfaceTopography's ``variable_bandwidth_from_profile`` (which contact.engineering's
    container averages use): every profile of a map cut into segments, a line removed in
    each, the RMS over all segments' heights. Profiles lose their own offset and tilt, so a
    profile VBM of a map lies below the areal one (by up to 30 % at short bandwidths on an
    AFM map), and the quadratic mean lies above the arithmetic one (Jensen; most at
    blocks of few pixels). Blocks start at pixel ``⌊jN/ζ⌋``, SurfaceTopography's at ``⌈jN/ζ⌉``:
    the same blocks where ``ζ`` divides ``N``.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement; extra dims broadcast, dask stays lazy.
    min_pixels : int
        Smallest block side in pixels: at least 3 for line scans, 2 for area scans (a
        smaller block holds no more pixels than the fitted line/plane has parameters).
    reliable : bool
        Drop bandwidths below the reliability cutoff.
    kind : {"area", "1d"}
        ``"area"``: square blocks of a map (paper §4.8, default); ``"1d"``: segments of the
        profiles along ``dim``, averaged over the profiles. Line scans are always profiles.
    dim : {"x", "y"}
        Profile direction for ``kind="1d"``.
    average : {"mean", "rms"}
        ``"mean"``: arithmetic mean of the blocks' RMS heights ⟨h_rms⟩ (paper, default);
        ``"rms"``: square root of the mean square height over all blocks (SurfaceTopography).

    Returns
    -------
    xarray.DataArray
        ``vbm`` (length) on coord ``bandwidth`` (length; ``sqrt(Lx Ly)/ζ`` for area
        scans, ``L/ζ`` for line scans), ascending, with coord ``magnification`` (ζ).
    """
    prep = prepare(obj)
    if kind == "1d" and prep.is_area:  # each profile a line scan, then the mean (or RMS) over the profiles
        profiles = obj.rename({[d for d in prep.lat if d != prep.check_dim(dim)][0]: "_profile"})
        if dim != X:
            profiles = profiles.rename({dim: X})
        per = vbm(profiles, min_pixels=min_pixels, reliable=False, average=average)
        out = per.mean("_profile") if average == "mean" else np.sqrt((per**2).mean("_profile"))
        out.attrs = dict(per.attrs, kind="1d", direction=dim)
        if dim != X:
            out = out.assign_coords(bandwidth=out.bandwidth.assign_attrs(long_name=f"bandwidth along {dim}"))
        out = apply_reliability(out, obj, coord="bandwidth", kind="length", reliable=reliable)
        return provenance(out, obj, "vbm", min_pixels=min_pixels, reliable=reliable, kind=kind, dim=dim,
                          average=average)
    h, u = prep.h, prep.units
    if min_pixels < 2 + (not prep.is_area):
        raise XtopoError(f"min_pixels must be an integer >= 3 for a line scan, got {min_pixels!r}")
    levels = _k.vbm_levels([h.sizes[d] for d in prep.lat], min_pixels)
    out = apply_lateral(_k.vbm, h, output_core_dims=[["bandwidth"]], output_sizes={"bandwidth": levels.size},
                        kwargs=dict(levels=levels, ndim=len(prep.lat), quadratic=average == "rms"), height_power=(1,),
                        what="vbm")
    length = float(np.prod([prep.size(d) for d in prep.lat]) ** (1 / len(prep.lat)))  # sqrt(Lx Ly), or L
    out = out.assign_coords(bandwidth=length_coord("bandwidth", length / levels, u, "bandwidth"),
                            magnification=("bandwidth", levels, {"units": "1", "long_name": "magnification ζ"}))
    out = out.isel(bandwidth=slice(None, None, -1))
    out = finish(out, "vbm", u, "mean tilt-corrected RMS height" if average == "mean" else
                 "tilt-corrected RMS height over all blocks", prep, min_pixels=int(min_pixels),
                 **({} if average == "mean" else {"average": "rms"}))
    out = apply_reliability(out, obj, coord="bandwidth", kind="length", reliable=reliable)
    extra = {} if (kind, average) == ("area", "mean") else {"kind": kind, "dim": dim, "average": average}
    return provenance(out, obj, "vbm", min_pixels=min_pixels, reliable=reliable, **extra)
