"""Height-difference autocorrelation function (paper §4.7, eq. 11-12)."""

from __future__ import annotations

import functools
from typing import Annotated

import numpy as np
import xarray as xr

from .._apply import apply_lateral
from .._kernels import correlation as _k
from ..conventions import X, Y
from ..params import Choice, Count, Flag, checked
from ._scale import finish, length_coord, log_bin, log_plan, prepare, provenance
from .reliability import apply_reliability

__all__ = ["acf"]


@functools.lru_cache(maxsize=4)
def _iso_plan(ny, nx, dy, dx, periodic, nb_points):
    r = _k.acf_offsets(ny, nx, dy, dx, periodic=periodic)
    return log_plan(r, min(dx, dy), float(r.max()), nb_points, _k.acf_weights(ny, nx, periodic=periodic))


def _acf_iso_kernel(h, *, periodic, plan):
    return plan.mean(_k.acf_map(h, periodic=periodic))


@checked
def acf(obj, kind: Annotated[str, Choice("1d", "iso")] = "1d", *, dim: str = X,
        nb_points: Annotated[int | None, Count()] = None, reliable: Annotated[bool, Flag()] = True) -> xr.DataArray:
    """Height-difference autocorrelation function ``A(ℓ) = ½⟨(h(r) - h(r+ℓ))²⟩``.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement (line or area scan); extra dims broadcast, dask stays lazy.
    kind : {"1d", "iso"}
        ``"1d"``: along the profiles in ``dim``, averaged over the other lateral dim,
        at ``ℓ = kΔ`` (``k ≤ N/2`` periodic, ``k < N`` nonperiodic). ``"iso"``: eq. (12),
        averaged over all directions and log-spaced bins of ``|ℓ|``.
    dim : {"x", "y"}
        Profile direction for ``kind="1d"``.
    nb_points : int, optional
        Number of log bins (``"iso"``: default 10 per decade; ``"1d"``: no binning unless given);
        empty bins are dropped. At most the number of values binned, or 10 000.
    reliable : bool
        Drop distances below the reliability cutoff.

    Returns
    -------
    xarray.DataArray
        ``acf`` in length² on coord ``distance`` (length). Computed by FFT; periodic data
        wrap, nonperiodic data are zero padded and each lag is divided by its own
        number of pairs (so the result equals the direct sum, eq. 11).
    """
    prep = prepare(obj)
    h, u = prep.h, prep.units
    if kind == "1d":
        prep.check_dim(dim)
        n, dx = h.sizes[dim], prep.spacing(dim)
        k = n // 2 + 1 if prep.periodic else n
        out = prep.along(_k.acf_profiles, dim, length_coord("distance", np.arange(k) * dx, u, "distance"), 2, "acf",
                         dx=dx, periodic=prep.periodic)
        if nb_points is not None:
            out = log_bin(out, "distance", nb_points)
        out = finish(out, "acf", f"{u}2", "height-difference autocorrelation function", prep, kind="1d", direction=dim)
    else:
        prep.check_iso("acf")
        ny, nx = h.sizes[Y], h.sizes[X]
        dy, dx = prep.spacing(Y), prep.spacing(X)
        plan = _iso_plan(ny, nx, dy, dx, prep.periodic, nb_points)
        out = apply_lateral(_acf_iso_kernel, h, output_core_dims=[["distance"]],
                            output_sizes={"distance": len(plan)}, kwargs=dict(periodic=prep.periodic, plan=plan),
                            height_power=(2,), what="acf")
        out = out.assign_coords(distance=length_coord("distance", plan.centers, u, "distance"))
        out = finish(out, "acf", f"{u}2", "radially averaged height-difference autocorrelation function", prep,
                     kind="iso")
    out = apply_reliability(out, obj, coord="distance", kind="length", reliable=reliable)
    return provenance(out, obj, "acf", kind=kind, dim=dim, nb_points=nb_points, reliable=reliable)
