"""Scale-dependent curvature distribution: its kurtosis at each scale.

At the stencil length ``ℓ = 2ηΔx`` the curvature ``κ_ℓ = D²^(η) h`` (the second difference of
:func:`~xtopo.analysis.sdrp.sdrp` with ``order=2``) has a distribution over the surface. Its RMS is
the scale-dependent RMS curvature; its kurtosis ``K(ℓ) = ⟨κ_ℓ⁴⟩/⟨κ_ℓ²⟩²`` says how heavy its tails
are: 3 at every scale for a Gaussian surface, 1.5 for a sinusoid, and more where a few sharp
features (asperity tips, scratches, spikes) carry the curvature of that scale.

The twin average of this analysis is declared in :data:`xtopo.stitching.ANALYSES`.
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._kernels.scaled import scaled_difference
from .._kernels.spectra import check_finite
from ..conventions import X
from ..errors import UndefinedValueWarning, warn
from ..params import Flag, Lengths, checked
from ._scale import finish, length_coord, provenance
from .reliability import apply_reliability
from .sdrp import stencils
from .statistical_reliability import independent_samples

__all__ = ["curvature_kurtosis", "curvature_kurtosis_error"]


def _kurtosis(h: np.ndarray, *, etas, periodic: bool, rows: int) -> np.ndarray:
    """``⟨κ⁴⟩/⟨κ²⟩²`` of the scaled second difference at each ``η``, over profiles and ``rows`` leading axes."""
    check_finite(h, "curvature_kurtosis")
    axes = tuple(range(-1 - rows, 0))
    out = np.full(h.shape[:h.ndim - 1 - rows] + (len(etas),), np.nan)
    for i, eta in enumerate(etas):
        d = scaled_difference(h, eta, order=2, periodic=periodic)
        if d.shape[-1] == 0:  # the stencil does not fit
            continue
        d2 = d * d
        m2 = d2.mean(axis=axes)
        with np.errstate(invalid="ignore", divide="ignore"):
            out[..., i] = np.where(m2 > 0, (d2 * d2).mean(axis=axes) / np.where(m2 > 0, m2 * m2, 1.0), np.nan)
    return out


@checked
def curvature_kurtosis(obj, *, dim: str = X, distances: Annotated[np.ndarray | None, Lengths()] = None,
                       reliable: Annotated[bool, Flag()] = True) -> xr.DataArray:
    """Kurtosis of the scale-dependent curvature distribution, ``K(ℓ) = ⟨κ_ℓ⁴⟩/⟨κ_ℓ²⟩²``.

    ``κ_ℓ = (h(x+ηΔx) - 2h(x) + h(x-ηΔx))/(ηΔx)²`` over all points whose stencil fits (all
    points of periodic data) and all profiles along ``dim``; ``ℓ = 2ηΔx``.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement; extra dims broadcast, dask stays lazy.
    dim : {"x", "y"}
        Direction of the curvature.
    distances : array_like, optional
        Stencil lengths ``ℓ`` in the measurement's length unit, at most the scan length.
        Default: those of :func:`~xtopo.analysis.sdrp.sdrp` (10 per decade from ``2Δx`` to
        ``L/2`` at integer ``η``).
    reliable : bool
        Drop distances below the reliability cutoff.

    Returns
    -------
    xarray.DataArray
        ``curvature_kurtosis`` (dimensionless) on coord ``distance``; 3 for a Gaussian surface.
        NaN, with an :class:`~xtopo.errors.UndefinedValueWarning`, where the curvature is zero
        everywhere (a flat or linear profile).
    """
    given = distances
    prep, dx, distances = stencils(obj, dim, distances, 2, "curvature_kurtosis")
    out = prep.along(_kurtosis, dim, length_coord("distance", distances, prep.units, "stencil length"), 0,
                     "curvature_kurtosis", etas=distances / (2 * dx), periodic=prep.periodic)
    out = finish(out, "curvature_kurtosis", "1", "kurtosis of the scale-dependent curvature", prep, direction=dim)
    if out.chunks is None and bool(np.isnan(out.values).all(axis=-1).any()):
        warn("curvature_kurtosis: the curvature is zero at every scale (a flat or linear profile); its "
             "kurtosis is undefined (NaN)", UndefinedValueWarning)
    out = apply_reliability(out, obj, coord="distance", kind="length", reliable=reliable)
    return provenance(out, obj, "curvature_kurtosis", dim=dim, distances=given, reliable=reliable)


def curvature_kurtosis_error(obj, curve: xr.DataArray) -> xr.DataArray:
    """Predicted relative standard error of a measurement's :func:`curvature_kurtosis` (its twin average's error model).

    The sample kurtosis of ``N`` independent Gaussian values has the variance ``24/N``; at the scale
    ``ℓ`` a scan holds ``N`` independent stretches
    (:func:`~xtopo.analysis.statistical_reliability.independent_samples`), so the relative error of
    ``K = 3`` is ``√(24/N)/3`` (infinite where the scan holds none).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        The measurement.
    curve : xarray.DataArray
        Its :func:`curvature_kurtosis` (on ``distance``; ``direction`` attr).

    Returns
    -------
    xarray.DataArray
        ``relative_error`` on ``distance``.
    """
    n = independent_samples(obj, "distance", curve["distance"].values, dim=curve.attrs.get("direction", X))
    with np.errstate(divide="ignore"):
        err = np.where(n > 0, np.sqrt(24 / np.where(n > 0, n, 1.0)) / 3, np.inf)
    return xr.DataArray(err, dims="distance", name="relative_error",
                        attrs={"units": "1", "long_name": "predicted relative standard error of the curvature kurtosis"})
