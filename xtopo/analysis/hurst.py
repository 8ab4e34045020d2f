"""Hurst exponent from the self-affine part of a PSD, ACF, VBM or SDRP (paper §4.6-4.8).

A straight line is fitted to the log-log data in a range of length scales; the
exponent follows from the slope ``s``:

=========================  =========================  ==============
analysis                   power law                  H
=========================  =========================  ==============
C1D, q Ciso/π (length³)    C ∝ q^(-1-2H)              -(s+1)/2
Ciso, C2D (length⁴)        C ∝ q^(-2-2H)              -(s+2)/2
ACF                        A ∝ ℓ^(2H)                 s/2
VBM                        h_rms ∝ ℓ^H                s
SDRP order 1               h'_rms ∝ ℓ^(H-1)           s+1
=========================  =========================  ==============

The uncertainty is the standard error of the least-squares slope (assuming
independent residuals; neighbouring points of these curves are correlated, so
treat it as a lower bound and compare methods).
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from ..errors import XtopoError
from ..params import Choice, Flag, Interval, checked
from ._scale import prepare, provenance
from .acf import acf
from .psd import psd
from .reliability import reliable_scales
from .sdrp import sdrp
from .vbm import vbm

__all__ = ["hurst", "fit_power_law", "fit_power_law_whittle"]

_METHODS = ("psd", "acf", "vbm", "sdrp")


def fit_power_law(x: np.ndarray, y: np.ndarray):
    """Least-squares line through ``(log x, log y)`` along the last axis, ignoring NaN/non-positive y.

    Returns
    -------
    slope, intercept, slope_stderr, npoints : ndarray
        Over the leading dims; NaN where fewer than 3 points are usable.
    """
    x = np.broadcast_to(np.asarray(x, dtype=float), np.shape(y))
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(y) & (y > 0) & (x > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        lx = np.where(ok, np.log(np.where(ok, x, 1.0)), 0.0)
        ly = np.where(ok, np.log(np.where(ok, y, 1.0)), 0.0)
        n = ok.sum(axis=-1)
        nn = np.where(n > 0, n, 1)
        mx = lx.sum(-1) / nn
        my = ly.sum(-1) / nn
        dx = np.where(ok, lx - mx[..., None], 0.0)
        dy = np.where(ok, ly - my[..., None], 0.0)
        sxx = (dx * dx).sum(-1)
        good = (n >= 3) & (sxx > 0)
        slope = np.where(good, (dx * dy).sum(-1) / np.where(sxx > 0, sxx, 1.0), np.nan)
        intercept = my - slope * mx
        res = np.where(ok, dy - slope[..., None] * dx, 0.0)
        ssr = (res * res).sum(-1)
        stderr = np.where(good, np.sqrt(ssr / np.maximum(n - 2, 1) / np.where(sxx > 0, sxx, 1.0)), np.nan)
    return slope, intercept, stderr, n


def fit_power_law_whittle(x: np.ndarray, y: np.ndarray):
    """Whittle-type fit of ``y = P x^s`` to spectral estimates along the last axis.

    Minimises ``Σ [log S_i + y_i/S_i]`` with ``S_i = P x_i^s`` (Newton on the profile
    in ``s``, started from the log-log least-squares slope). Unlike a least-squares
    line through ``log y``, this is unbiased for periodogram-like data whose scatter
    (and hence the bias of ``log y``) differs between points. The error is the
    sandwich (robust) standard error of ``s``.

    Returns
    -------
    slope, intercept, slope_stderr, npoints : ndarray
    """
    slope, _, _, n = fit_power_law(x, y)
    x = np.broadcast_to(np.asarray(x, dtype=float), np.shape(y))
    y = np.asarray(y, dtype=float)
    ok = np.isfinite(y) & (y > 0) & (x > 0)
    lx = np.log(np.where(ok, x, 1.0))
    yy = np.where(ok, y, 0.0)
    nn = np.maximum(ok.sum(-1), 1)
    lbar = np.where(ok, lx, 0.0).sum(-1) / nn
    s = np.where(np.isfinite(slope), slope, 0.0)
    c = lx - lbar[..., None]
    for _ in range(50):
        e = yy * np.exp(-s[..., None] * c)          # y x^-s (up to a constant factor)
        z = e.sum(-1)
        zz = np.where(z > 0, z, 1.0)
        m1 = (e * c).sum(-1) / zz
        m2 = (e * c * c).sum(-1) / zz
        var = m2 - m1 * m1
        step = np.where(var > 0, -m1 / np.where(var > 0, var, 1.0), 0.0)  # F'(s) = -m1, F'' = var
        s = s - step
        if np.all(np.abs(step) < 1e-12):
            break
    e = yy * np.exp(-s[..., None] * c)
    pref_c = e.sum(-1) / nn                             # P at log x = lbar
    intercept = np.log(np.where(pref_c > 0, pref_c, np.nan)) - s * lbar
    r = np.where(ok, e / np.where(pref_c > 0, pref_c, 1.0)[..., None] - 1.0, 0.0)
    sxx = np.where(ok, c * c, 0.0).sum(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        stderr = np.sqrt(np.where(ok, (c * r) ** 2, 0.0).sum(-1)) / np.where(sxx > 0, sxx, np.nan)
    bad = ~np.isfinite(slope)
    return np.where(bad, np.nan, s), np.where(bad, np.nan, intercept), np.where(bad, np.nan, stderr), n


def _exponent_map(da: xr.DataArray):
    """(abscissa dim, is_wavevector, slope→H, prefactor units template) for an analysis result."""
    a = da.attrs
    method = a.get("analysis")
    if method == "psd":
        if a.get("kind") == "2d":
            raise XtopoError("fit the Hurst exponent on psd(kind='iso') or kind='1d', not the 2D map")
        k = 1 if a.get("kind") == "1d" or bool(a.get("equivalent_1d", 0)) else 2  # C ∝ q^(-k-2H)
        return "q", True, (lambda s: -(s + k) / 2), "2-2H"
    if method == "acf":
        return "distance", False, (lambda s: s / 2), "2-2H"
    if method == "vbm":
        return "bandwidth", False, (lambda s: s), "1-H"
    if method == "sdrp":
        if int(a.get("order", 1)) != 1:
            raise XtopoError("the Hurst exponent is fitted on sdrp(order=1) (RMS slope ∝ ℓ^(H-1))")
        return "distance", False, (lambda s: s + 1), "-H"
    raise XtopoError(f"cannot fit a Hurst exponent to {da.name!r}: attrs['analysis'] must be one of {_METHODS}, "
                     f"got {method!r}")


@checked
def hurst(obj, method: Annotated[str, Choice(*_METHODS)] = "psd", *, kind: Annotated[str, Choice("1d", "iso")] = "1d",
          dim: str = "x", scale_range: Annotated[tuple | None, Interval(0.0, what="lengths")] = None,
          reliable: Annotated[bool, Flag()] = True) -> xr.Dataset:
    """Fit the Hurst exponent H (and the power-law prefactor) of a measurement.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement, or a result of :func:`psd`, :func:`acf`, :func:`vbm` or
        :func:`sdrp` (``order=1``), recognised by its ``analysis`` attribute.
    method : {"psd", "acf", "vbm", "sdrp"}
        Which analysis to compute when ``obj`` is a measurement.
    kind : str
        ``kind`` of the PSD/ACF (``"1d"`` or ``"iso"``).
    dim : {"x", "y"}
        Profile direction for 1D PSD/ACF/SDRP.
    scale_range : (float, float), optional
        Range of length scales (in the measurement's unit) to fit; for a PSD the
        scale of ``q`` is the wavelength ``2π/q``. Default: 4 pixels to ``L/8``
        (PSD, SDRP), 4 pixels to ``max(L/64, 32 pixels)`` (ACF, which bends away
        from the power law at large ℓ), 16 pixels to ``L/4`` (VBM, biased in small
        blocks), within the reliable range. For a result, the range follows from its
        reliable points; a lazy result with a tip-radius cutoff keeps its unreliable
        points (masked), and its cutoff is computed here to find them.
    reliable : bool
        Only fit reliable scales.

    Returns
    -------
    xarray.Dataset
        ``hurst`` (1), ``hurst_stderr`` (1), ``prefactor`` (length^(…); attrs give the
        power law), ``npoints``; extra dims of ``obj`` broadcast.
    """
    if isinstance(obj, xr.DataArray) and obj.attrs.get("analysis") in _METHODS:
        da = obj
        length_units = _length_units(da)
        size = None
    else:
        prep = prepare(obj)
        length_units = prep.units
        size, pixel = min(prep.size(d) for d in prep.lat), max(prep.spacing(d) for d in prep.lat)
        if method == "psd":
            da = psd(obj, kind, dim=dim, nb_points=None if kind == "1d" else _bins(prep, dim), reliable=reliable)
        elif method == "acf":
            da = acf(obj, kind, dim=dim, nb_points=_bins(prep, dim) if kind == "1d" else None, reliable=reliable)
        elif method == "vbm":
            da = vbm(obj, reliable=reliable)
        else:
            da = sdrp(obj, 1, dim=dim, reliable=reliable)
    units = da.attrs.get("units", "1")
    analysis = da.attrs["analysis"]
    xdim, is_q, to_h, pref_power = _exponent_map(da)
    x = np.asarray(da[xdim].values, dtype=float)
    with np.errstate(divide="ignore"):
        scale = np.where(x > 0, 2 * np.pi / np.where(x > 0, x, 1.0), np.inf) if is_q else x
    if scale_range is None:
        if size is None:
            sc = scale[(x > 0) & _reliable(da, x, is_q)]
            if not sc.size:
                raise XtopoError(f"the {analysis} result has no reliable point at a positive {xdim}: "
                                 "nothing to fit")
            lo, hi = sc.min() * (2 if is_q else 4), sc.max() / (2 if is_q else 8)
        else:
            # the ends of each curve carry known biases: VBM blocks of a few pixels
            # (tilt removal), ACF at ℓ ≳ L/50 (finite size), PSD near 2π/L (few modes)
            lo = (16 if analysis == "vbm" else 4) * pixel
            hi = {"acf": max(size / 64, 32 * pixel), "vbm": size / 4}.get(analysis, size / 8)
    else:
        lo, hi = scale_range
    sel = (scale >= lo) & (scale <= hi)
    if sel.sum() < 3:
        if scale_range is None:
            what = "is empty" if lo >= hi else f"({lo:g} to {hi:g} {length_units}) holds fewer than 3 points"
            raise XtopoError(f"the scan is too short for a default fit: the range of scales method={analysis!r} "
                             f"trusts {what}; give scale_range=(lo, hi) explicitly, or use a longer scan")
        raise XtopoError(f"fewer than 3 points between the scales {lo:g} and {hi:g} {length_units}; widen scale_range")
    sub = da.isel({xdim: np.flatnonzero(sel)})
    fit = fit_power_law_whittle if analysis == "psd" else fit_power_law
    slope, intercept, stderr, npts = xr.apply_ufunc(
        fit, sub[xdim], sub, input_core_dims=[[xdim], [xdim]], output_core_dims=[[], [], [], []],
        dask="parallelized", output_dtypes=[float, float, float, int])
    factor = abs(to_h(1.0) - to_h(0.0))
    ds = xr.Dataset({
        "hurst": to_h(slope).assign_attrs(units="1", long_name="Hurst exponent"),
        "hurst_stderr": (stderr * factor).assign_attrs(units="1", long_name="standard error of the Hurst exponent"),
        "prefactor": np.exp(intercept).assign_attrs(
            units=f"{length_units}^({pref_power})",
            long_name=f"power-law prefactor of {analysis} ({units} at unit abscissa)"),
        "npoints": npts.assign_attrs(units="1", long_name="number of points in the fit"),
    }, attrs={"analysis": analysis, "fit_scale_min": float(lo), "fit_scale_max": float(hi),
              "fit_scale_units": length_units, "abscissa": xdim})
    if size is None:  # fitted to a given result: its own history says how it was computed
        return provenance(ds, obj, "hurst", scale_range=scale_range)
    return provenance(ds, obj, "hurst", method=method, kind=kind, dim=dim, scale_range=scale_range, reliable=reliable)


def _reliable(da, x, is_q):
    """Which abscissae of a result are reliable: a lazy result (tip-radius cutoff on dask) masks its
    unreliable scales instead of dropping them, so its cutoff coordinate says which they are."""
    if "reliability_cutoff" not in da.coords:
        return np.ones(x.shape, bool)
    cut = np.asarray(da.coords["reliability_cutoff"].values, dtype=float).reshape(1, -1)  # computes a lazy cutoff
    return np.asarray(reliable_scales(x[:, None], cut, "q" if is_q else "length")).any(axis=1)


def _bins(prep, dim):
    """Log bins for fitting: 25 per decade of the scan's range of scales."""
    return max(3, int(np.ceil(25 * np.log10(max(prep.h.sizes[dim], 10)))))


def _length_units(da):
    for name in ("q", "distance", "bandwidth"):
        if name in da.coords:
            u = da.coords[name].attrs.get("units", "1")
            return u[:-2] if u.endswith("-1") else u
    return "1"
