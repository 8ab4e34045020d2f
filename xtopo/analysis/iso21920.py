"""ISO 21920-2 profile parameters of line scans and of every line of a map (issue 22)."""

from __future__ import annotations

from typing import Annotated

import xarray as xr

from .._apply import apply_lateral
from .._kernels import profile_iso as _k
from ..conventions import height_of, spacing
from ..errors import GridError
from ..filtration import END_CORRECTIONS, Cutoff, Form
from ..filtration import filter as _filter
from ..params import Choice, Count, Real, checked
from ._scale import prepare, provenance, split_parameters

__all__ = ["iso21920", "PARAMETERS"]

#: name → (long name, unit kind: "length", "1" or "%")
PARAMETERS = {
    "Ra": ("arithmetic mean height", "length"),
    "Rq": ("root mean square height", "length"),
    "Rp": ("maximum peak height (mean over sections)", "length"),
    "Rv": ("maximum pit depth (mean over sections)", "length"),
    "Rz": ("maximum height (mean over sections)", "length"),
    "Rt": ("total height of the evaluation length", "length"),
    "Rsk": ("skewness", "1"),
    "Rku": ("kurtosis", "1"),
    "Rdq": ("root mean square slope (7-point differentiation)", "1"),
    "RSm": ("mean width of the profile elements", "length"),
    "Rmr": ("material ratio at height c about the mean line", "%"),
    "Rk": ("core height (ISO 13565-2)", "length"),
    "Rpk": ("reduced peak height (ISO 13565-2)", "length"),
    "Rvk": ("reduced dale depth (ISO 13565-2)", "length"),
    "Rmr1": ("material ratio of the peaks (upper limit of the core)", "%"),
    "Rmr2": ("material ratio of the dales (lower limit of the core)", "%"),
}


@checked
def iso21920(obj, dim: Annotated[str, Choice("x", "y", error=GridError)] = "x",
             lambda_s: Annotated[float | str | None, Cutoff()] = None,
             lambda_c: Annotated[float | str | None, Cutoff()] = None, form: Annotated[str | int | None, Form()] = "line",
             sections: Annotated[int, Count()] = 5, c: Annotated[float, Real()] = 0.0,
             convention: Annotated[str, Choice(*_k.CONVENTIONS)] = "iso21920",
             end: Annotated[str, Choice(*END_CORRECTIONS)] = "normalized") -> xr.Dataset:
    """ISO 21920-2 profile parameters of a line scan or of every line of a map along ``dim``.

    The profile is made as ISO 21920-3 says (S-filter ``λs``, F-operator ``form``, L-filter
    ``λc``, see :func:`xtopo.filtration.filter`), then evaluated over an evaluation length of
    ``sections`` sampling lengths.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement; a nonuniform line scan is linearly interpolated onto a uniform grid with
        as many points (attribute ``resampled`` says so).
    dim : {"x", "y"}
        Direction of the profiles (for a map, every line along ``dim`` is one profile).
    lambda_s : float, str, "auto" or None
        S-filter nesting index (a length in the measurement's unit, or ``"2.5 um"``); None: none.
    lambda_c : float, str, "auto" or None
        L-filter cut-off; the sampling length is ``λc``. ``"auto"``: the ISO 4288 / 21920-3 class
        by Ra (:func:`xtopo.filtration.iso_cutoffs`). None: no L-filter; the profile after the
        form removal is evaluated, its mean line the least-squares one, and the sampling length
        is the length over ``sections``.
    form : {"mean", "line", "curvature"}, int or None
        F-operator: least-squares polynomial removed from each profile before the L-filter.
    sections : int
        Number of sampling lengths in the evaluation length (ISO 21920-3 default: 5).
    c : float
        Height about the mean line (measurement's length unit) of the material ratio ``Rmr``.
    convention : {"iso21920", "iso4287"}
        ``"iso21920"`` (ISO 21920-2:2021): Rp, Rv and Rz are means over the sections, the other
        parameters are evaluated over the evaluation length. ``"iso4287"`` (ISO 4287:1997): Ra, Rq,
        Rsk, Rku, RΔq and RSm too are means of their values per sampling length. Rt, Rmr(c) and
        the Rk family (ISO 13565-2) are over the evaluation length in both.
    end : {"normalized", "linear"}
        End correction of the filters (see :func:`xtopo.filtration.filter`).

    Returns
    -------
    xarray.Dataset
        One variable per parameter (Ra, Rq, Rp, Rv, Rz, Rt, Rsk, Rku, Rdq, RSm, Rmr, Rk, Rpk,
        Rvk, Rmr1, Rmr2) with ``units`` and ``long_name``; dims are those of the heights without
        ``dim`` (one value per profile, batch dims kept). Attributes ``lambda_s``, ``lambda_c``,
        ``sampling_length``, ``evaluation_length`` (in the length unit), ``sections``, ``c`` and
        ``convention`` say how they were evaluated. Lazy on dask.

    Raises
    ------
    GridError
        If the evaluation length (``sections × λc``) is longer than the profile, or a profile has
        fewer than 2 points per section.

    Notes
    -----
    The evaluation length is centred in the profile when the profile is longer (the filters
    need no run-in: their end correction keeps the full length). RSm counts profile elements with
    a height discrimination of 10 % of Rz (hysteresis about the mean line) and a width
    discrimination of 1 % of the sampling length (a narrower element joins the next one). The material ratio curve: the
    heights sorted, the ``i``-th of ``n`` at ``100 i/(n-1)`` %, linear in between.
    """
    prepared = prepare(obj)  # a nonuniform line scan interpolated onto a uniform grid of as many points
    h, units = prepared.h, prepared.units
    prepared.check_dim(dim)
    filtered = _filter(h if prepared.resampled else obj, lambda_s=lambda_s, lambda_c=lambda_c, form=form, dim=dim,
                       component="primary" if lambda_c is None else "roughness", end=end)
    profile = height_of(filtered)
    ls, lc = float(filtered.attrs["lambda_s"]), float(filtered.attrs["lambda_c"])  # NaN: filter not applied
    dx = spacing(h, dim)
    n = h.sizes[dim]
    per = int(round(lc / dx)) if lc == lc else n // sections
    if per * sections > n:
        raise GridError(f"the evaluation length sections × lambda_c = {sections} × {lc:.4g} {units} is longer than "
                        f"the profile ({n * dx:.4g} {units}); give fewer sections or a shorter lambda_c")
    if per < 2:
        raise GridError(f"{n} points along {dim!r} make fewer than 2 per section with sections={sections}")
    start = (n - per * sections) // 2
    z = profile.isel({dim: slice(start, start + per * sections)})
    res = apply_lateral(_k.profile_parameters, z, core_dims=(dim,), output_core_dims=[["parameter"]],
                        output_sizes={"parameter": len(_k.PARAMETERS)}, what="iso21920",
                        kwargs={"dx": dx, "sections": sections, "c": c, "convention": convention,
                                "center": lc != lc})
    ds = xr.Dataset(split_parameters(res, {name: {"units": units if kind == "length" else kind, "long_name": long_name}
                                           for name, (long_name, kind) in PARAMETERS.items()}))  # _k.PARAMETERS' order
    ds.attrs = prepared.attrs(title="ISO 21920-2 profile parameters", direction=dim, lambda_s=ls, lambda_c=lc,
                              sampling_length=per * dx, evaluation_length=per * sections * dx, sections=sections,
                              c=c, convention=convention, length_units=units, form=str(form), end=end)
    return provenance(ds, obj, "iso21920")

