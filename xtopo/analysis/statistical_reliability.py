"""Statistical reliability (long scales): how much a measurement's curve at each scale can be trusted.

Short scales are limited by the instrument (:mod:`xtopo.analysis.reliability`, paper §4.9); long
scales by statistics: a scan of length ``L`` holds few independent samples of wavelengths near ``L``.
The twin averages (:mod:`xtopo.stitching`, paper §4.10) report the uncertainty of each point from the
predicted relative standard errors of this module (and, with ``max_error``, leave out what is too uncertain).
"""

from __future__ import annotations

import functools
from typing import Annotated

import numpy as np
import xarray as xr

from .._kernels.collocation import collocation_points
from .._kernels.estimator_error import mean_square_relative_error, variogram_from_samples
from ..conventions import X
from ..errors import XtopoError
from ..params import Choice, Lengths, Positive, checked
from ._scale import prepare
from .acf import acf

__all__ = ["independent_samples", "sampling_cutoff", "stencil_error", "MAX_RELATIVE_ERROR", "SAMPLING_FACTOR",
           "VARIOGRAM_FRACTION"]


#: Largest predicted relative standard error of a curve value that counts as statistically reliable
#: (long-scale criterion of the twin averages): 7.5% keeps two standard errors within 15%.
MAX_RELATIVE_ERROR = 0.075
#: Share of a scan's length over which its own ACF serves as the variogram of :func:`stencil_error`
#: (longer lags rest on few pairs and carry the scan's own tilt; beyond, a power law continues it).
VARIOGRAM_FRACTION = 0.25
#: Stencils ``(offsets in units of ℓ, weights)`` of the mean-square estimators of :func:`stencil_error`.
_STENCILS = {"acf": ((0.0, 1.0), (-1.0, 1.0)), "slope": ((0.0, 1.0), (-1.0, 1.0)),
             "curvature": ((-0.5, 0.0, 0.5), (1.0, -2.0, 1.0))}


def independent_samples(obj, coord: str, values, *, dim: str = X) -> np.ndarray:
    """How many statistically independent samples a measurement holds at each scale (long-scale reliability).

    A 1D power spectrum at ``q = 2πk/L`` holds one squared Fourier amplitude per
    profile; profiles of an isotropic area scan a distance ``d`` apart are
    independent at that wavelength only when ``d ≳ λ/2``, so an area scan of width
    ``W`` contributes ``min(rows, 2kW/L + 1)`` of them. A Hann window (nonperiodic
    data) correlates neighbouring wavevectors and halves the count. Real-space curves
    (ACF, SDRP, VBM) at length ``ℓ`` hold ``L/ℓ`` independent stretches per profile and
    ``min(rows, W/ℓ)`` independent rows. The relative standard error of a power estimate
    from ``N`` independent modes is ``1/√N``: the twin averages (paper §4.10) use a
    spectrum's bin only where it reaches :data:`MAX_RELATIVE_ERROR`, and the VBM (an
    RMS: half that error) likewise. ACF and SDRP use :func:`stencil_error` instead
    (a count of stretches overstates their information when ``H > 3/4``).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        The measurement.
    coord : {"q", "distance", "bandwidth"}
        What ``values`` are: angular wavevectors or lengths, in the measurement's unit.
    values : array_like
    dim : {"x", "y"}
        Profile direction of the curve.

    Returns
    -------
    numpy.ndarray
        Independent samples per value (0 for ``q = 0`` or lengths beyond the measurement).
    """
    prep = prepare(obj)
    other = [d for d in prep.lat if d != dim]  # the profiles of an area scan lie side by side along it
    rows, width = (prep.h.sizes[other[0]], prep.size(other[0])) if other else (1, 0.0)
    length = prep.size(dim)
    v = np.abs(np.asarray(values, dtype=float))
    if coord == "q":
        k = v * length / (2 * np.pi)
        across = np.minimum(rows, 2 * k * width / length + 1) if rows > 1 else np.ones_like(k)
        out = np.where(k >= 0.5, across, 0.0)
        return out if prep.periodic else out / 2
    with np.errstate(divide="ignore"):
        along = np.where(v > 0, length / v, np.inf)
        across = np.minimum(rows, width / v) if rows > 1 else 1.0
    return np.where(along >= 1, along * np.maximum(across, 1.0), 0.0)


#: Shortest reliable wavelength of a sampled spectrum, in pixels (aliasing criterion of :func:`sampling_cutoff`).
SAMPLING_FACTOR = 4


@checked
def sampling_cutoff(obj, dim: str = X, *, factor: Annotated[float, Positive()] = SAMPLING_FACTOR) -> float:
    """Shortest wavelength at which a sampled measurement's spectrum is free of aliasing (spectra only).

    A real surface keeps its roughness below the pixel size, and sampling it folds
    the power of the wavevectors ``2k q_N ± q`` (``q_N = π/Δx``) onto ``q``. For a
    self-affine 1D spectrum ``C1D ∝ q^(-1-2H)`` the folded share at ``q = 2q_N/f``
    (wavelength ``f Δx``) is ``Σ_k (kf - 1)^(-1-2H) + (kf + 1)^(-1-2H)``: 8.5% at
    ``f = 4`` for H = 0.8, but 2× at the Nyquist wavevector. Instrument noise (white,
    ``C1D = σ² Δx``) also weighs most there. Spectra are therefore cut at
    ``factor · Δx`` in addition to the tip/resolution criteria of §4.9 (which the paper
    gives; this one it does not: it is the sampling theorem applied to rough data).
    Real-space curves (ACF, SDRP, VBM) sample heights exactly and are not affected.
    Nonuniform line scans use their mean spacing (their spectra are taken after
    linear interpolation onto as many uniform points).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        The measurement.
    dim : {"x", "y"}
        Direction of the profiles whose spectrum is cut.
    factor : float
        Shortest reliable wavelength in pixels (2 is the Nyquist wavelength).

    Returns
    -------
    float
        The cutoff wavelength in the measurement's length unit.
    """
    prep = prepare(obj)
    n = prep.h.sizes[prep.check_dim(dim)]
    return factor * prep.size(dim) / n


def _stencil_error_rows(values, *, lags, lengths, nodes, n, dx, rows, dy, offsets, weights):
    """:func:`stencil_error` of each row of ACF values (last axis: ``lags``) at ``lengths``, computed at ``nodes``
    and interpolated log-log (a module-level function: dask tokenizes its partial by value, not by pickling)."""
    flat = values.reshape(-1, values.shape[-1])
    out = np.full((flat.shape[0], lengths.size), np.nan)
    for i, row in enumerate(flat):
        gamma = variogram_from_samples(row, lags)
        if gamma is None:
            continue
        err = mean_square_relative_error(gamma, nodes, offsets=offsets, weights=weights, n=n, dx=dx,
                                         rows=rows, row_spacing=dy)
        if nodes is not lengths:
            ok = np.isfinite(err) & (err > 0)
            if ok.sum() >= 2:
                inside = (lengths >= nodes[ok].min()) & (lengths <= nodes[ok].max())
                err = np.where(inside, np.exp(np.interp(np.log(np.where(lengths > 0, lengths, 1.0)),
                                                        np.log(nodes[ok]), np.log(err[ok]))), np.nan)
            else:
                err = np.full(lengths.size, np.nan)
        out[i] = err
    return out.reshape(values.shape[:-1] + (lengths.size,))


@checked
def stencil_error(obj, lengths: Annotated[np.ndarray, Lengths()], *,
                  quantity: Annotated[str, Choice("acf", "curvature", "slope")] = "acf", dim: str = X,
                  fraction: Annotated[float, Positive()] = VARIOGRAM_FRACTION) -> xr.DataArray:
    """Predicted relative standard error of a measurement's ACF, scale-dependent slope or curvature (long-scale reliability).

    These curves are means of a squared stencil ``D = Σ w_i h(x + a_i ℓ)`` (a height
    difference for ``A(ℓ)`` and the slope, a second difference for the curvature) over
    the scan. For a Gaussian surface with variogram ``γ`` the covariance of two stencils
    a distance ``(s, d)`` apart is ``-Σ_ij w_i w_j γ(|(s + (a_i - a_j)ℓ, d)|)`` and the
    variance of their mean over ``M`` points of ``R`` rows is ``2/(MR)² Σ (M-|s|)(R-|j|) Cov²``
    (:func:`xtopo._kernels.estimator_error.mean_square_relative_error`). The variogram
    holds every wavelength, also those longer than the scan, which for a self-affine
    surface with ``H > 3/4`` dominate: the relative error then falls only like
    ``(ℓ/L)^(2-2H)``, and parallel rows hardly help (they share the long wavelengths).
    The variogram is the measurement's own 1D ACF (plug-in estimate) over the first
    ``fraction`` of its length, continued by the power law of its outer half decade
    (isotropy is assumed across rows). RMS quantities (slope, curvature) carry half the
    relative error of their mean square.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        The measurement (missing data filled first); nonuniform line scans are resampled.
    lengths : array_like
        Positive distances ``ℓ`` in the measurement's length unit (stencil length: ``ℓ`` of
        ``A(ℓ)``, of the slope ``D^(η)``, or the full span ``2ηΔx`` of the curvature).
    quantity : {"acf", "slope", "curvature"}
        The estimator.
    dim : {"x", "y"}
        Profile direction.
    fraction : float
        Share of the scan's length (in (0, 1]) whose ACF lags define the variogram.

    Returns
    -------
    xarray.DataArray
        ``relative_error`` on coord ``distance`` (NaN where the stencil does not fit);
        lazy on dask inputs.
    """
    offsets, weights = _STENCILS[quantity]
    if fraction > 1:
        raise XtopoError(f"fraction must be a share of the scan's length, in (0, 1], got {fraction!r}")
    prep = prepare(obj)
    prep.check_dim(dim)
    n, dx = prep.h.sizes[dim], prep.spacing(dim)
    other = [d for d in prep.lat if d != dim]
    rows, dy = (prep.h.sizes[other[0]], prep.spacing(other[0])) if other else (1, 0.0)
    # lengths beyond the scan: NaN (the stencil does not fit)
    curve = acf(obj, kind="1d", dim=dim, reliable=False)
    keep = max(3, int(np.ceil(fraction * n)))
    curve = curve.isel(distance=slice(0, keep))
    lags = np.asarray(curve["distance"].values, dtype=float)
    # evaluate on at most 10 points per decade and interpolate log-log (the error varies slowly with ℓ)
    pos = lengths[lengths > 0]
    nodes = collocation_points(pos.min(), pos.max(), 10) if pos.size > 32 and pos.max() > pos.min() else lengths

    kernel = functools.partial(_stencil_error_rows, lags=lags, lengths=lengths, nodes=nodes, n=n, dx=dx, rows=rows,
                               dy=dy, offsets=offsets, weights=weights)
    err = xr.apply_ufunc(kernel, curve.drop_vars([c for c in curve.coords if c != "distance"]),
                         input_core_dims=[["distance"]], output_core_dims=[["_out"]], exclude_dims={"distance"},
                         dask="parallelized", output_dtypes=[float],
                         dask_gufunc_kwargs={"output_sizes": {"_out": lengths.size}})
    if quantity != "acf":
        err = err / 2  # relative error of an RMS is half that of its mean square
    err = err.rename({"_out": "distance"}).assign_coords(
        distance=("distance", lengths, {"units": prep.units, "long_name": "distance"}))
    err.name = "relative_error"
    err.attrs = {"units": "1", "long_name": f"predicted relative standard error of the {quantity}",
                 "variogram_fraction": float(fraction)}
    return err
