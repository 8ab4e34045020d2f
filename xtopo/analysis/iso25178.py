"""ISO 25178-2 areal field parameters and the material ratio curve (docs/iso.md, areal set).

Heights are taken about their mean plane (the reference surface of ISO 25178-2 once form
and filtering are done: apply ``detrend``/``filter`` first). Missing data are ignored by the
height, functional, volume and hybrid parameters; the spatial ones need a complete map.
Extra dims (a batch of measurements) broadcast; dask inputs stay lazy (the lateral dims in
one chunk).
"""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._apply import apply_lateral
from .._kernels import iso_areal as _k
from .._kernels import material_ratio as _mr
from ..conventions import X, Y, height_of, is_nonuniform, is_periodic, lateral_dims, shared_length_unit, spacing
from ..errors import GridError, XtopoError
from ..params import Count, Interval, Names, Numbers, Real, checked
from ._scale import provenance, split_parameters, unit_of

__all__ = ["iso25178", "material_ratio", "areal_material_ratio", "material_volume", "void_volume", "PARAMETERS"]

#: the parameters :func:`iso25178` computes, by group
PARAMETERS = _k.GROUPS

# long names and units (kinds of _scale.unit_of: "L" the length unit, "V" volume per area)
_META = {
    "Sa": ("arithmetic mean height", "L"),
    "Sq": ("root mean square height", "L"),
    "Sp": ("maximum peak height", "L"),
    "Sv": ("maximum pit depth", "L"),
    "Sz": ("maximum height", "L"),
    "Ssk": ("skewness", "1"),
    "Sku": ("kurtosis", "1"),
    "Sdq": ("root mean square gradient (seven-point slopes)", "1"),
    "Sdr": ("developed interfacial area ratio", "%"),
    "Sal": ("autocorrelation length", "L"),
    "Str": ("texture aspect ratio", "1"),
    "Std": ("texture direction (of the largest angular amplitude, from +x towards +y)", "degree"),
    "Sk": ("core height", "L"),
    "Spk": ("reduced peak height", "L"),
    "Svk": ("reduced dale height", "L"),
    "Smr1": ("material ratio at the top of the core", "%"),
    "Smr2": ("material ratio at the bottom of the core", "%"),
    "Sxp": ("peak extreme height", "L"),
    "Smr": ("areal material ratio at height c", "%"),
    "Smc": ("inverse areal material ratio (height at material ratio mr)", "L"),
    "Sdc": ("areal material ratio height difference", "L"),
    "Vmp": ("peak material volume", "V"),
    "Vmc": ("core material volume", "V"),
    "Vvv": ("dale void volume", "V"),
    "Vvc": ("core void volume", "V"),
    "Spd": ("density of peaks", "L-2"),
    "Spc": ("arithmetic mean peak curvature", "L-1"),
    "S10z": ("ten point height", "L"),
    "S5p": ("five point peak height", "L"),
    "S5v": ("five point pit depth", "L"),
}


def _area(obj, what: str):
    """Heights, their length unit and periodicity, after the checks every function here shares."""
    h = height_of(obj)
    if lateral_dims(h) != (Y, X) or is_nonuniform(h) or is_nonuniform(obj):
        raise GridError(f"{what} needs an area scan (dims 'y' and 'x'); for profiles use the ISO 21920 "
                        "profile parameters")
    return h, shared_length_unit(h, what), is_periodic(h) or is_periodic(obj)


_RATIO = Real(0.0, 100.0)
_RATIOS = Interval(0.0, 100.0, what="material ratios in %")


@checked
def iso25178(obj, parameters: Annotated[tuple | None, Names(*_k.PARAMETERS, *_k.GROUPS)] = None, *,
             s: Annotated[float, Real(0.0, 1.0, closed=False)] = 0.2, p: Annotated[float, _RATIO] = 10.0,
             q: Annotated[float, _RATIO] = 80.0, c: Annotated[float, Real()] = 0.0, mr: Annotated[float, _RATIO] = 10.0,
             sxp: Annotated[tuple, _RATIOS] = (2.5, 50.0), sdc: Annotated[tuple, _RATIOS] = (10.0, 80.0),
             pruning: Annotated[float, _RATIO] = 5.0) -> xr.Dataset:
    """ISO 25178-2 field parameters of an area scan, one variable per ISO symbol.

    Height (Sa, Sq, Sp, Sv, Sz, Ssk, Sku), hybrid (Sdq, Sdr), spatial (Sal, Str, Std),
    functional (Sk, Spk, Svk, Smr1, Smr2, Sxp, Smr(c), Smc(mr), Sdc), volume (Vmp, Vmc,
    Vvv, Vvc) and feature (Spd, Spc, S10z, S5p, S5v) parameters. Definitions and
    discretisations are in docs/iso.md; Sdq here uses the standards' seven-point slope and
    differs from the paper's forward-difference SΔq of :func:`xtopo.analysis.scalars.scalars`
    (both are kept).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        An area scan (extra dims broadcast; dask stays lazy). Level and filter it first:
        heights are taken about their mean plane.
    parameters : str or sequence of str, optional
        ISO symbols and/or groups (``"height"``, ``"hybrid"``, ``"spatial"``, ``"functional"``,
        ``"volume"``, ``"feature"``) to compute; default all.
    s : float
        Threshold of the normalised autocorrelation for Sal and Str, 0 < s < 1 (ISO 25178-3 default 0.2).
    p, q : float
        Material ratios in % of the volume parameters, ``Vmp = Vm(p)``, ``Vmc = Vm(q) - Vm(p)``,
        ``Vvv = Vv(q)``, ``Vvc = Vv(p) - Vv(q)`` (ISO 25178-3 defaults 10 % and 80 %).
    c : float
        Height above the mean plane, in the length unit, of Smr(c).
    mr : float
        Material ratio in % of Smc(mr).
    sxp : tuple of float
        Material ratios (p, q) in % of ``Sxp = Smc(p) - Smc(q)`` (ISO 25178-3 defaults 2.5 %, 50 %).
    sdc : tuple of float
        Material ratios (p, q) in % of ``Sdc = Smc(p) - Smc(q)``.
    pruning : float
        Wolf pruning threshold of the feature parameters, in % of Sz (5 %, the customary default).

    Returns
    -------
    xarray.Dataset
        One variable per ISO symbol with ``units`` and ``long_name`` (heights and lengths in the
        measurement's unit, Sdr and material ratios in %, Std in degrees, volumes in
        ``unit3 unit-2``, Spd in ``unit-2``, Spc in ``unit-1``); the arguments of parametrised
        symbols are in their attrs.

    Notes
    -----
    NaN where a parameter is undefined: Ssk and Sku of a flat map; Sdq/Sdr with fewer than
    7 samples along a direction (nonperiodic) or no complete cell; Sal, Str and Std of a map
    with missing data (fill it first); Str when the autocorrelation does not fall to ``s``
    within the map in some direction, Sal when it does not fall in any; the feature parameters
    of a map with missing data, Spc/S5p/S5v when no complete significant hill or dale is found.
    """
    chosen = _k.PARAMETERS if parameters is None else {n for item in parameters for n in _k.GROUPS.get(item, (item,))}
    names = tuple(n for n in _k.PARAMETERS if n in chosen)
    if not p < q:
        raise XtopoError(f"(p, q) must be two material ratios in % with p < q, got {(p, q)!r}")
    h, units, periodic = _area(obj, "iso25178")
    out = apply_lateral(_k.areal_parameters, h, output_core_dims=[["parameter"]],
                        output_sizes={"parameter": len(names)},
                        kwargs=dict(dy=spacing(h, Y), dx=spacing(h, X), periodic=periodic, names=names, s=s, p=p,
                                    q=q, c=c, mr=mr, sxp=sxp, sdc=sdc, pruning=pruning),
                        what="iso25178")
    args = {"Sal": {"s": s}, "Str": {"s": s}, "Smr": {"c": c, "c_units": units}, "Smc": {"mr": mr},
            "Sxp": {"p": sxp[0], "q": sxp[1]}, "Sdc": {"p": sdc[0], "q": sdc[1]},
            "Vmp": {"p": p}, "Vmc": {"p": p, "q": q}, "Vvv": {"q": q}, "Vvc": {"p": p, "q": q},
            **{name: {"pruning": pruning} for name in _k.GROUPS["feature"]}}
    ds = xr.Dataset(split_parameters(out, {name: {"units": unit_of(_META[name][1], units), "long_name": _META[name][0],
                                                  "standard": "ISO 25178-2", **args.get(name, {})} for name in names}))
    ds.attrs = {"title": "ISO 25178-2 areal field parameters", "periodic": int(periodic)}
    return provenance(ds, obj, "iso25178", parameters=list(names), s=s, p=p, q=q, c=c, mr=mr, sxp=list(sxp),
                      sdc=list(sdc), pruning=pruning)


def _at_kernel(h, *, values, kind):
    h = np.asarray(h, dtype=float)
    out = np.empty(h.shape[:-2] + (values.size,))
    for idx in np.ndindex(h.shape[:-2]):
        dist = _mr.Distribution(h[idx])
        if not dist.n:
            out[idx] = np.nan
        elif kind == "height":
            out[idx] = _k.curve(dist, values)
        elif kind == "ratio":
            out[idx] = _k.ratios(dist, values)
        else:
            out[idx] = _k.volumes(dist, values, kind)
    return out


def _evaluate(obj, values, dim, dim_attrs, kernel, kwargs, name, units, long_name, what, params, scalar):
    h, length, _ = _area(obj, what)
    out = apply_lateral(kernel, h, output_core_dims=[[dim]], output_sizes={dim: values.size},
                        kwargs=kwargs, what=what)
    dim_attrs = {**dim_attrs, "units": dim_attrs["units"].replace("L", length)}
    out = out.assign_coords({dim: (dim, values, dim_attrs)})
    if scalar:
        out = out.squeeze(dim)
    out.attrs = {"units": units.replace("L", length), "long_name": long_name, "standard": "ISO 25178-2"}
    out.name = name
    return provenance(out, obj, what, **params)


_PERCENTS = Numbers(0.0, 100.0, what="material ratios in % between 0 and 100")


@checked
def material_ratio(obj, mr: Annotated[np.ndarray | None, _PERCENTS] = None, *,
                   nb_points: Annotated[int, Count(min=2)] = 1001) -> xr.DataArray:
    """The areal material ratio (Abbott–Firestone) curve: height above the mean plane vs material ratio.

    ``Smc(mr)`` of ISO 25178-2 §4.5.2 as a function: at material ratio 0 % the highest point
    (Sp), at 100 % the lowest (-Sv). The material ratio at a height is the share of the area
    at or above it (docs/iso.md).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        An area scan (extra dims broadcast; dask stays lazy).
    mr : float or sequence of float, optional
        Material ratios in % at which to evaluate the curve; default ``nb_points`` equally spaced
        from 0 to 100 %.
    nb_points : int
        Number of samples when ``mr`` is not given (at least 2).

    Returns
    -------
    xarray.DataArray
        ``height`` (length unit) on dim ``material_ratio`` (%); plot it with
        ``.plot(x="material_ratio")``.
    """
    values = np.linspace(0.0, 100.0, nb_points) if mr is None else np.atleast_1d(mr)
    return _evaluate(obj, values, "material_ratio", {"units": "%", "long_name": "areal material ratio"},
                     _at_kernel, dict(values=values, kind="height"), "height", "L",
                     "height of the material ratio curve", "material_ratio", dict(mr=values),
                     np.ndim(mr) == 0 and mr is not None)


@checked
def areal_material_ratio(obj, c: Annotated[np.ndarray, Numbers(what="finite heights in the length unit")]
                         ) -> xr.DataArray:
    """Smr(c): the areal material ratio (%) at heights ``c`` above the mean plane (ISO 25178-2 §4.5.1).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        An area scan (extra dims broadcast; dask stays lazy).
    c : float or sequence of float
        Heights above the mean plane, in the measurement's length unit.

    Returns
    -------
    xarray.DataArray
        ``Smr`` in % on dim ``c`` (no dim for a single ``c``).
    """
    values = np.atleast_1d(c)
    return _evaluate(obj, values, "c", {"units": "L", "long_name": "height above the mean plane"},
                     _at_kernel, dict(values=values, kind="ratio"), "Smr", "%", "areal material ratio",
                     "areal_material_ratio", dict(c=values), np.ndim(c) == 0)


def _volume(obj, p, kind: str, name: str, long_name: str, what: str) -> xr.DataArray:
    values = np.atleast_1d(p)
    return _evaluate(obj, values, "p", {"units": "%", "long_name": "material ratio"}, _at_kernel,
                     dict(values=values, kind=kind), name, "L3 L-2", long_name, what, dict(p=values), np.ndim(p) == 0)


@checked
def material_volume(obj, p: Annotated[np.ndarray, _PERCENTS]) -> xr.DataArray:
    """Vm(p): the material volume per unit area above the height at material ratio ``p`` (ISO 25178-2 §4.5.6).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        An area scan (extra dims broadcast; dask stays lazy).
    p : float or sequence of float
        Material ratios in %.

    Returns
    -------
    xarray.DataArray
        ``Vm`` in ``unit3 unit-2`` on dim ``p`` (no dim for a single ``p``).
    """
    return _volume(obj, p, "material", "Vm", "material volume", "material_volume")


@checked
def void_volume(obj, p: Annotated[np.ndarray, _PERCENTS]) -> xr.DataArray:
    """Vv(p): the void volume per unit area below the height at material ratio ``p`` (ISO 25178-2 §4.5.7).

    Arguments and result as for :func:`material_volume` (``Vv`` instead of ``Vm``); see :func:`material_volume`.
    """
    return _volume(obj, p, "void", "Vv", "void volume", "void_volume")
