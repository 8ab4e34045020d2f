"""Scale-dependent roughness parameters (paper §4.5, eq. 9)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._kernels.collocation import collocation_points
from .._kernels.scaled import sdrp_rms
from ..conventions import X
from ..errors import GridError, XtopoError
from ..params import Choice, Flag, Lengths, checked
from ._scale import POINTS_PER_DECADE, finish, length_coord, prepare, provenance
from .reliability import apply_reliability

__all__ = ["sdrp", "stencils"]


def stencils(obj, dim: str, distances, order: int, what: str):
    """What a scale-dependent derivative of ``order`` along ``dim`` needs: the prepared measurement, the
    spacing and the stencil lengths ``ℓ = order·η·Δx`` (at most the scan length).

    Default lengths: 10 per decade from ``order·Δx`` to ``L/2`` at integer ``η`` (no interpolation, which
    biases the slope low at fractional η: benchmarks/tradeoffs.py gives half the error, and faster;
    duplicates dropped, so fewer points at the smallest scales).
    """
    prep = prepare(obj)
    prep.check_dim(dim)
    n, dx = prep.h.sizes[dim], prep.spacing(dim)
    if distances is None:
        lo, hi = order * dx, n * dx / 2
        if hi < lo:
            raise GridError(f"the scan is too short for {what} ({n} points along {dim!r})")
        distances = np.unique(np.round(collocation_points(1.0, hi / lo, POINTS_PER_DECADE))) * lo
    elif np.any(distances > n * dx):
        raise XtopoError(f"distances must be positive finite lengths of at most {n * dx:g} {prep.units} (the size "
                         f"of the measurement), got {distances[distances > n * dx].tolist()}")
    return prep, dx, distances


@checked
def sdrp(obj, order: Annotated[int, Choice(1, 2)] = 1, *, dim: str = X,
         distances: Annotated[np.ndarray | None, Lengths()] = None,
         reliable: Annotated[bool, Flag()] = True) -> xr.DataArray:
    """Scale-dependent RMS slope (``order=1``) or RMS curvature (``order=2``).

    ``D^(η) h = (h(x+ηΔx) - h(x))/(ηΔx)`` (eq. 9) and
    ``D²^(η) h = (h(x+ηΔx) - 2h(x) + h(x-ηΔx))/(ηΔx)²``; the RMS is taken over all
    points whose stencil fits (all points for periodic data) and all profiles along
    ``dim``. Fractional ``η`` interpolate heights linearly.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement; extra dims broadcast, dask stays lazy.
    order : {1, 2}
        Derivative order.
    dim : {"x", "y"}
        Direction of the derivative.
    distances : array_like, optional
        Stencil lengths ``ℓ = order·η·Δx`` in the measurement's length unit, at most the
        scan length ``L`` (longer stencils of nonperiodic data give NaN). Default:
        10 per decade from ``order·Δx`` to ``L/2``, rounded to integer ``η`` (no interpolation;
        duplicates dropped, so fewer points at the smallest scales).
    reliable : bool
        Drop distances below the reliability cutoff.

    Returns
    -------
    xarray.DataArray
        ``sdrp`` (dimensionless slope or curvature in inverse length) on coord
        ``distance``; at ``ℓ = Δx`` (order 1) it equals RΔq, at ``ℓ = 2Δx`` (order 2) RΔ²q.
    """
    given = distances
    prep, dx, distances = stencils(obj, dim, distances, order, f"sdrp(order={order})")
    u = prep.units
    out = prep.along(sdrp_rms, dim, length_coord("distance", distances, u, "stencil length"), 1, "sdrp", dx=dx,
                     etas=distances / (order * dx), order=order, periodic=prep.periodic)
    units, what = ("1", "slope") if order == 1 else (f"{u}-1", "curvature")
    out = finish(out, "sdrp", units, f"scale-dependent RMS {what}", prep, order=order, direction=dim)
    out = apply_reliability(out, obj, coord="distance", kind="length", reliable=reliable)
    return provenance(out, obj, "sdrp", order=order, dim=dim, distances=given, reliable=reliable)
