"""Power spectral density (paper §4.6) of line and area scans.

Conventions: eq. (1) ``h̃ = Δx Δy Σ h e^{-iq·r}``, ``C1D = |h̃|²/L`` averaged over
profiles, ``C2D = |h̃|²/(Lx Ly)``; ``Ciso`` averages C2D over log-spaced bins of |q|.
Wavevectors are angular (2π/λ) in inverse length units.
"""

from __future__ import annotations

import functools
from typing import Annotated

import numpy as np
import xarray as xr

from .._apply import apply_lateral
from .._kernels import spectra as _k
from ..conventions import X, Y
from ..errors import XtopoError
from ..params import Choice, Count, Flag, checked
from ._scale import finish, length_coord, log_bin, log_plan, prepare, provenance
from .reliability import apply_reliability

__all__ = ["psd"]

_KINDS = ("1d", "2d", "iso")
#: the windows psd() and twin_psd() take (None, False and "none": no window)
WINDOWS = Choice("auto", "hann", "none", None, False)


@functools.lru_cache(maxsize=4)
def _iso_plan(ny, nx, dy, dx, nb_points):
    q = _k.rfft_abs_q(ny, nx, dy, dx)
    lo = min(2 * np.pi / (ny * dy) if ny > 1 else np.inf, 2 * np.pi / (nx * dx))
    return log_plan(q, lo, float(q.max()), nb_points, _k.rfft_multiplicity(nx))


@checked
def psd(obj, kind: Annotated[str, Choice(*_KINDS)] = "1d", *, dim: str = X,
        window: Annotated[str | None, WINDOWS] = "auto",
        nb_points: Annotated[int | None, Count()] = None,
        convention: Annotated[str, Choice("standard", "persson")] = "standard",
        equivalent_1d: Annotated[bool, Flag()] = False, reliable: Annotated[bool, Flag()] = True,
        prewhiten: Annotated[bool, Flag()] = False) -> xr.DataArray:
    """Power spectral density of a measurement.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement (line or area scan); extra dims broadcast, dask stays lazy.
    kind : {"1d", "2d", "iso"}
        ``"1d"``: C1D of the profiles along ``dim``, averaged over the other lateral
        dim, at ``q = 2πk/L`` (``k ≥ 0``; the ``-q`` half is identical). ``"2d"``: C2D
        on the full ``(q_y, q_x)`` grid, ascending. ``"iso"``: C2D averaged over
        log-spaced bins of |q| (empty bins dropped, coordinate = mean |q| of each bin).
    dim : {"x", "y"}
        Profile direction for ``kind="1d"``.
    window : {"auto", "hann", None}
        ``"auto"``: Hann window for nonperiodic data, none for periodic data. The
        2D window is radial; all windows have ``mean(w²) = 1`` (§4.3).
    nb_points : int, optional
        Number of log bins (``"iso"``: default 10 per decade; ``"1d"``: no binning unless given);
        empty bins are dropped. At most the number of values binned, or 10 000.
    convention : {"standard", "persson"}
        ``"persson"`` divides C2D/Ciso by 4π² (Persson's normalisation).
    equivalent_1d : bool
        For ``"iso"``: return the 1D-equivalent ``q Ciso / π`` (eq. 10, units length³).
    reliable : bool
        Drop wavevectors above ``2π/cutoff`` (see :func:`~xtopo.analysis.reliability.reliability_cutoff`).
    prewhiten : bool
        ``kind="1d"`` with a window: window and transform the slopes ``D_x h`` and divide by
        ``|D̃_x(q)|²`` (:func:`~xtopo._kernels.spectra.prewhitening`), which removes the window's
        bias at the longest wavelengths of a steep spectrum (default False: the paper's estimator).

    Returns
    -------
    xarray.DataArray
        ``psd`` in length³ (1D, 1D-equivalent) or length⁴ (2D, iso), with coords
        ``q`` or ``(q_y, q_x)`` in inverse length. Heights are taken about their mean
        (per profile for 1D), so Parseval holds exactly without a window.
    """
    prep = prepare(obj)
    h, u = prep.h, prep.units
    win = window == "hann" or (window == "auto" and not prep.periodic)
    qunits = f"{u}-1"
    params = dict(kind=kind, window="hann" if win else "none", convention=convention)
    if prewhiten and kind != "1d":
        raise XtopoError("prewhiten applies to kind='1d' only")
    prewhiten = prewhiten and win  # without a window the heights' spectrum has no main-lobe bias to remove
    if prewhiten:
        params["prewhiten"] = 1
    if kind != "1d":
        prep.check_iso("psd", kind)
        ny, nx = h.sizes[Y], h.sizes[X]
        dy, dx = prep.spacing(Y), prep.spacing(X)
    if kind == "1d":
        if convention == "persson" or equivalent_1d:
            raise XtopoError("convention='persson' and equivalent_1d apply to 2D/iso spectra only")
        prep.check_dim(dim)
        n, dx = h.sizes[dim], prep.spacing(dim)
        q = 2 * np.pi * np.arange(n // 2 + 1) / (n * dx)
        out = prep.along(_k.psd_profiles, dim, length_coord("q", q, qunits, "angular wavevector"), 2, "psd", dx=dx,
                         window=win, prewhiten=prewhiten)
        if nb_points is not None:
            out = log_bin(out, "q", nb_points)
        out = finish(out, "psd", f"{u}3", "1D power spectral density C1D", prep, direction=dim, **params)
    elif kind == "2d":
        out = apply_lateral(_k.psd_map, h, output_core_dims=[["q_y", "q_x"]], output_sizes={"q_y": ny, "q_x": nx},
                            kwargs=dict(dy=dy, dx=dx, window=win), height_power=(2,), what="psd")
        qy = 2 * np.pi * np.fft.fftshift(np.fft.fftfreq(ny, d=dy))
        qx = 2 * np.pi * np.fft.fftshift(np.fft.fftfreq(nx, d=dx))
        out = out.assign_coords(q_y=length_coord("q_y", qy, qunits, "angular wavevector y"),
                                q_x=length_coord("q_x", qx, qunits, "angular wavevector x"))
        if convention == "persson":
            out = out / (4 * np.pi**2)
        out = finish(out, "psd", f"{u}4", "2D power spectral density C2D", prep, **params)
    else:
        plan = _iso_plan(ny, nx, dy, dx, nb_points)
        out = apply_lateral(_k.psd_iso, h, output_core_dims=[["q"]], output_sizes={"q": len(plan)},
                            kwargs=dict(dy=dy, dx=dx, window=win, plan=plan), height_power=(2,), what="psd")
        out = out.assign_coords(q=length_coord("q", plan.centers, qunits, "magnitude of the angular wavevector"))
        if equivalent_1d:
            out = out * (out["q"] / np.pi)
        elif convention == "persson":
            out = out / (4 * np.pi**2)
        units, name = ((f"{u}3", "1D-equivalent of the isotropic PSD, q Ciso/π (eq. 10)") if equivalent_1d else
                       (f"{u}4", "radially averaged 2D power spectral density Ciso"))
        out = finish(out, "psd", units, name, prep, equivalent_1d=int(equivalent_1d), **params)
    if kind == "2d":
        out.attrs.update(reliable=0, reliability_note="2D maps are not cut; use kind='iso' or '1d'")
    else:
        out = apply_reliability(out, obj, coord="q", kind="q", reliable=reliable)
    return provenance(out, obj, "psd", kind=kind, dim=dim, window=window, nb_points=nb_points,
                      convention=convention, equivalent_1d=equivalent_1d, reliable=reliable,
                      **({"prewhiten": True} if prewhiten else {}))
