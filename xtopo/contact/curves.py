"""Load curves: a sequence of warm-started solves stacked along the control given (``load``,
``mean_pressure`` or ``penetration``)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
import xarray as xr

from .._checks import bin_count
from ..conventions import append_history
from ..errors import ContactError, ConvergenceWarning, warn
from ..params import Count, Numbers, checked
from .solve import ONE_SEQUENCE, _control, run_solver, solver_settings, to_dataset

__all__ = ["curve", "stiffness", "gap_distribution"]

#: the values of a curve (each then checked against the scene's models by :func:`~xtopo.contact.solve.control_value`)
_VALUES = Numbers(what="finite numbers")


def _curve_variables(ds, names, what: str):
    if not isinstance(ds, xr.Dataset):
        raise ContactError(f"{what} needs a contact result (xtopo.contact.Scene.curve/solve), a Dataset; "
                           f"got {type(ds).__name__}")
    missing = [n for n in names if n not in ds.variables]
    if missing:
        raise ContactError(f"{what} needs a contact result (xtopo.contact.Scene.curve/solve) with variables {names}; "
                           f"this Dataset lacks {missing}")


def _per_length(units: str, length: str) -> str:
    """``units`` divided by ``length``: ``"E* um2"`` / ``"um"`` → ``"E* um"``, ``"E* um"`` → ``"E*"``."""
    for power, rest in ((f" {length}2", f" {length}"), (f" {length}", "")):
        if units.endswith(power):
            return units[: -len(power)] + rest
    return f"{units} {length}-1"


@checked(ONE_SEQUENCE, error=ContactError)
def curve(scene, *, loads: Annotated[object, _VALUES] = None, mean_pressures: Annotated[object, _VALUES] = None,
          penetrations: Annotated[object, _VALUES] = None, tol=None, maxiter: int | None = None,
          gap_bins: Annotated[int, Count(min=0)] = 50, preset: str | None = None) -> xr.Dataset:
    """Solve ``scene`` for each value of a sequence, each step starting from the previous solution.

    Parameters
    ----------
    scene : xtopo.contact.Scene
    loads, mean_pressures, penetrations : array_like
        Exactly one sequence (units as in :func:`xtopo.contact.solve.solve`).
    tol, maxiter, preset : as in :func:`xtopo.contact.solve.solve`
    gap_bins : int
        Bins of the gap distribution (0 for none).

    Returns
    -------
    xarray.Dataset
        The variables of :func:`~xtopo.contact.solve.solve` stacked along the control given:
        ``load``, ``mean_pressure`` or ``penetration`` (dimension and coordinate, the values the
        solves reached), plus ``stiffness`` (``dF/dδ``) and ``gap_distribution``.
    """
    gap_bins = bin_count(gap_bins, "gap_bins", int(np.prod(scene.shape)), error=ContactError)
    name, values = ONE_SEQUENCE.given(dict(loads=loads, mean_pressures=mean_pressures, penetrations=penetrations))
    values = np.atleast_1d(values)
    tol, maxiter = solver_settings(scene, tol, maxiter, preset)
    dim = name[:-1]  # the curve runs along the control the user gave
    # every value checked before the first solve (a bad last value must not cost the whole curve)
    controls = [_control(scene, **{dim: v}) for v in values]
    steps, previous = [], None
    for v, (load, pen) in zip(values, controls):
        res = run_solver(scene, load=load, penetration=pen, tol=tol, maxiter=maxiter, initial=previous)
        if not res.converged:
            warn(f"contact solve at {dim}={v:g} did not converge in {res.iterations} iterations "
                 f"(residual {res.residual:.3g} > tol {tol:g}); flagged converged=False", ConvergenceWarning)
        previous = res.pressure if np.any(res.pressure) else None
        steps.append(to_dataset(scene, res, tol))
    ds = xr.concat([st.set_coords(dim) for st in steps], dim=dim, data_vars="all", coords="minimal",
                   compat="override", combine_attrs="override")
    # penetrations are known to the solver tolerance (relative to the roughness, or the pixel for a flat)
    scale = float(np.ldexp(-scene.w.min(), scene.height_exponent)) or max(scene.spacing)
    ds["stiffness"] = stiffness(ds, dim=dim, atol=tol * scale)
    if gap_bins:
        ds["gap_distribution"] = gap_distribution(ds, bins=gap_bins)
    ds.attrs.pop("history", None)  # that of the first solve: the measurement's, then one load's line
    ds.attrs.update(scene.provenance)
    return append_history(ds, f"xtopo.contact.curve({name}={len(values)} values)")


def stiffness(ds: xr.Dataset, dim: str = "load", atol: float = 0.0) -> xr.DataArray:
    """Contact stiffness ``dF/dδ`` along a curve, by second-order finite differences.

    Parameters
    ----------
    ds : xarray.Dataset
        A load curve (variables ``load`` and ``penetration`` along ``dim``).
    dim : str
        The curve's dimension.
    atol : float
        Penetration steps ``|Δδ| ≤ atol`` (length units) count as no change.

    Returns
    -------
    xarray.DataArray
        ``dF/dδ`` between neighbours in the order of the ``dim`` coordinate (whatever order the
        values were given in); one-sided at the ends, as :func:`numpy.gradient`. A value of the
        coordinate given more than once (a loading–unloading sequence) is one point of the
        curve (the mean of its solves), and its repetitions get its stiffness. NaN where it is
        undefined: next to a step in which the penetration does not change (full contact of
        a periodic scene, where ``δ`` is fixed and the stiffness infinite) and for curves of
        fewer than two distinct points.
    """
    _curve_variables(ds, ["load", "penetration"], "stiffness")
    if not isinstance(dim, str) or ds["load"].dims != (dim,) or ds["penetration"].dims != (dim,):
        raise ContactError(f"stiffness: 'load' and 'penetration' must run along dim={dim!r}; they have dims "
                           f"{ds['load'].dims} and {ds['penetration'].dims}")
    # neighbours along the curve, not in the order the values were given: sort by the curve's coordinate
    order = np.argsort(ds[dim].values, kind="stable") if dim in ds.coords else np.arange(ds.sizes[dim])
    f = np.asarray(ds["load"].values, dtype=float)[order]
    d = np.asarray(ds["penetration"].values, dtype=float)[order]
    # repeated control values (equal to rounding: a load comes back as Σ p ΔA) are one point
    point = np.zeros(order.size, np.intp)
    if dim in ds.coords and order.size:
        x = np.asarray(ds[dim].values, dtype=float)[order]
        same = np.abs(np.diff(x)) <= 1e-9 * np.max(np.abs(x))
        point[1:] = np.cumsum(~same)
    count = np.bincount(point)
    f = np.bincount(point, weights=f) / count
    d = np.bincount(point, weights=d) / count
    k = np.full(f.shape, np.nan)
    if f.size >= 2:
        h = np.diff(d)
        ok = np.abs(h) > atol
        hs = np.where(ok, h, 1.0)
        s = np.where(ok, np.diff(f) / hs, np.nan)  # slope of every step
        k[0], k[-1] = s[0], s[-1]
        h1, h2 = hs[:-1], hs[1:]
        # np.gradient's second-order formula on a nonuniform grid, from the two step slopes
        both = ok[:-1] & ok[1:] & (h1 + h2 != 0)
        k[1:-1] = np.where(both, (h1 * s[1:] + h2 * s[:-1]) / np.where(both, h1 + h2, 1.0), np.nan)
    k = k[point]                # back to every step, then to the given order
    k[order] = k.copy()
    units = _per_length(ds["load"].attrs.get("units", "1"), ds["penetration"].attrs.get("units", "1"))
    return xr.DataArray(k, dims=(dim,), coords={dim: ds[dim]} if dim in ds.coords else None,
                        attrs={"units": units, "long_name": "contact stiffness dF/dδ"})


@checked(error=ContactError)
def gap_distribution(ds: xr.Dataset, bins: Annotated[int, Count()] = 50) -> xr.DataArray:
    """Probability density of the gap over the non-contacting points, per load step.

    The bin edges span ``[0, max gap]`` over all steps; coordinate ``gap_bin`` holds bin centres.
    A step in full contact (no point outside the contact) has no gap distribution: NaN.
    """
    _curve_variables(ds, ["gap", "contact"], "gap_distribution")
    gap = ds["gap"]
    lateral = [d for d in gap.dims if d in ("x", "y")]
    bins = bin_count(bins, "bins", int(np.prod([gap.sizes[d] for d in lateral])), error=ContactError)
    extra = [d for d in gap.dims if d not in lateral]
    values = gap.transpose(*extra, *lateral).values
    contact = ds["contact"].transpose(*extra, *lateral).values
    gmax = float(values.max()) if values.size else 0.0
    edges = np.linspace(0.0, gmax if gmax > 0 else 1.0, bins + 1)
    flat_v = values.reshape((-1,) + values.shape[len(extra):]).reshape(int(np.prod(values.shape[:len(extra)])), -1)
    flat_c = contact.reshape(flat_v.shape)
    dens = np.stack([np.histogram(v[~c], bins=edges, density=False)[0] for v, c in zip(flat_v, flat_c)])
    width = np.diff(edges)
    with np.errstate(invalid="ignore", divide="ignore"):
        total = dens.sum(axis=1, keepdims=True)
        dens = np.where(total > 0, dens / np.where(total > 0, total, 1) / width, np.nan)
    dens = dens.reshape(values.shape[:len(extra)] + (bins,))
    centres = 0.5 * (edges[1:] + edges[:-1])
    lu = gap.attrs.get("units", "1")
    coords = {d: gap.coords[d] for d in extra if d in gap.coords}  # the steps' load/penetration
    coords["gap_bin"] = ("gap_bin", centres, {"units": lu, "long_name": "gap (bin centre)"})
    return xr.DataArray(dens, dims=(*extra, "gap_bin"), coords=coords,
                        attrs={"units": f"{lu}-1", "long_name": "probability density of the gap outside contact"})

