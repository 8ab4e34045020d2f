"""Preprocessing of measurements (paper §3.2): detrending and filling missing data.

Both functions take a measurement Dataset (or a height DataArray), never modify it, and
return a new object whose ``history`` records the step. ``detrend`` in mode ``"plane"`` or
``"curvature"`` sets ``periodic`` to 0 (the removed tilt or curvature is no periodic function). Extra (batch) dims broadcast and
dask-backed inputs stay lazy; the lateral dims must each be a single chunk.

``fill_missing`` replaces the ``mask`` variable by ``filled`` (``True`` where a value was
interpolated): after filling nothing is missing, and keeping the record under ``mask``
would make :func:`xtopo.conventions.height_of` hide the filled values again.
"""

from __future__ import annotations

import inspect
from typing import Annotated

import numpy as np
import xarray as xr

from ._apply import apply_lateral
from ._kernels import polyfit as _poly
from .conventions import (MASK, X, Y, height_of, is_nonuniform, is_periodic, lateral_dims,
                          length_factor, spacing)
from ._heights import fit_positions as _positions
from ._heights import subtract_polynomial
from ._heights import replace_heights as _finish
from .errors import GridError, UnitsError, XtopoError
from .filtration import filter as _filter
from .params import Choice, Flag, checked, preflight

__all__ = ["detrend", "fill_missing", "apply_steps", "checked_steps"]

_FILLED = "filled"


@checked
def detrend(obj, mode: Annotated[str, Choice(*_poly.DEGREES)] = "plane", per_line: Annotated[bool, Flag()] = False):
    """Subtract the least-squares polynomial background that minimises the RMS height.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement (heights in any length unit) or a height DataArray with coordinates.
    mode : {"mean", "plane", "curvature"}
        Polynomial of degree 0 (mean), 1 (tilt) or 2 (tilt and curvature, incl. the ``xy`` term)
        in the lateral positions.
    per_line : bool
        Fit every profile along ``x`` (every row of a map) separately.

    Returns
    -------
    Same type as ``obj``
        Detrended heights (same units, float64); missing data stay missing and are ignored by
        the fit. Nonuniform line scans are fitted at their positions. A periodic measurement
        stays periodic with ``mode="mean"`` only: a tilt or curvature is no periodic function,
        so its subtraction leaves a step where the surface wraps around, and the result has
        ``periodic=0`` (analyses then window it instead of differentiating across the step).
    """
    degree = _poly.DEGREES[mode]
    h = height_of(obj)
    dims = lateral_dims(h)
    breaks_periodicity = degree > 0 and is_periodic(h)
    out = subtract_polynomial(h, dims, degree, "detrend", bool(per_line), height_power=(1,), heights_out=True)
    return _finish(obj, out, f"detrend(mode={mode!r}, per_line={bool(per_line)})", nonperiodic=breaks_periodicity)


def fill_missing(obj):
    """Fill missing data: harmonic (Laplace) interpolation for maps, linear for line scans (paper §3.2).

    Each island of missing pixels gets the solution of the discrete Laplace equation with the
    surrounding measured heights as Dirichlet values (spacing-weighted, so anisotropic pixels
    are handled); periodic maps wrap around, at a nonperiodic border the fill has zero normal
    slope. The fill is exact for linear fields (holes away from nonperiodic borders) and its mean
    over a hole equals the mean over the hole's edge (mean-value property). Islands of up to 32768
    pixels are solved with a sparse direct solve, larger ones with multigrid-preconditioned conjugate
    gradients to about 1e-12 of the height range (:mod:`xtopo._kernels.laplace_fill`).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        Missing data are NaN in ``height`` or ``True`` in ``mask``.

    Returns
    -------
    Same type as ``obj``
        Heights without missing data. For a Dataset the ``mask`` variable is replaced by
        ``filled`` (``True`` where a value was interpolated, by this call or an earlier one).

    Raises
    ------
    GridError
        If a measurement has no valid data at all.
    """
    h = height_of(obj)
    dims = lateral_dims(h)
    periodic = is_periodic(obj)
    from ._kernels import laplace_fill as _fill  # lazy: scipy.sparse and numba (startup time, issue 26)

    if dims == (Y, X):
        dy, dx = _fill_spacings(h)
        kernel, kwargs = _fill.harmonic_fill_2d, {"periodic": periodic, "dy": dy, "dx": dx}
    else:
        period = h.sizes[X] * spacing(h, X) if periodic and not is_nonuniform(obj) else None
        kernel, kwargs = _fill.linear_fill_1d, {"x": _positions(h, X), "periodic": period is not None, "period": period}
    out = apply_lateral(_checked(kernel), h, output_core_dims=[dims], kwargs=kwargs, height_power=(1,),
                        what="fill_missing")
    res = _finish(obj, out, "fill_missing(harmonic)" if dims == (Y, X) else "fill_missing(linear)")
    if isinstance(obj, xr.Dataset):
        filled = ~np.isfinite(h)  # what the kernels fill: NaN and ±inf
        if _FILLED in obj.data_vars:  # filled before: keep that record too
            filled = filled | obj[_FILLED].astype(bool)
        res = res.drop_vars(MASK, errors="ignore")
        res[_FILLED] = filled.assign_attrs(long_name="interpolated by fill_missing", flag_meanings="filled")
    return res


def _fill_spacings(h) -> tuple[float, float]:
    """``(dy, dx)`` of a map in one length unit, for the weights of the harmonic fill.

    An axis of a single pixel has no neighbours along it, so its spacing does not enter the
    fill (a 1×N map needs no y spacing); it is given as 1. A ``y`` in another unit than ``x``
    (a Dataset that :func:`~xtopo.conventions.validate` would refuse) is converted: only the
    ratio of the spacings matters.
    """
    dy = spacing(h, Y) if h.sizes[Y] > 1 else 1.0
    dx = spacing(h, X) if h.sizes[X] > 1 else 1.0
    if h.sizes[Y] > 1 and h.sizes[X] > 1:
        uy, ux = (h.coords[d].attrs.get("units") for d in (Y, X))
        if uy is not None and ux is not None:
            try:
                dy *= length_factor(uy, ux)
            except UnitsError:
                pass  # not length units: take the spacings as they are
    return dy, dx


def _checked(kernel):
    """Turn the kernels' "nothing to fill from" ValueError into a GridError (also inside dask tasks)."""
    def run(*args, **kwargs):
        try:
            return kernel(*args, **kwargs)
        except ValueError as exc:
            raise GridError(f"fill_missing: {exc}") from None

    return run


# --------------------------------------------------------------------------- steps requested by name

#: the steps a batch (``preprocess=``) or the command line (``--detrend``, ``--fill-missing``) requests by name:
#: name → the function (its options checked by :func:`xtopo.params.preflight`)
_STEPS = {"detrend": detrend, "fill_missing": fill_missing, "filter": _filter}
STEPS = tuple(_STEPS)


def _step_options(step: str, options, name: str) -> dict | None:
    """Every option of ``step`` (defaults filled in) from what was given for it; None: the step is left out."""
    func = _STEPS[step]
    signature = inspect.signature(func)
    params = list(signature.parameters)[1:]  # after the measurement
    if options is None or (isinstance(options, (bool, np.bool_)) and not options):
        return None
    if isinstance(options, (bool, np.bool_)):
        kwargs = {}
    elif isinstance(options, dict):
        kwargs = dict(options)
    elif params:
        kwargs = {params[0]: options}
    else:
        raise XtopoError(f"{name}: step {step!r} takes no options, got {options!r}; give True")
    bound = signature.bind(None, **preflight(func, kwargs, f"{name}: step {step!r}"))
    bound.apply_defaults()
    return {k: v for k, v in bound.arguments.items() if k in params}


def checked_steps(steps, name: str = "preprocess") -> tuple:
    """Preprocessing steps requested by name, checked: ``((step, options), ...)`` in the order given.

    The form in which :mod:`xtopo.batch` (``preprocess=``) and the command line
    (``--detrend``, ``--fill-missing``) request preprocessing; :func:`apply_steps` applies it.

    Parameters
    ----------
    steps : None, str, dict or sequence
        None or empty: no preprocessing. A step name (``"fill_missing"``). A dict
        ``{step: options}``, or a sequence of step names and ``(step, options)`` pairs, applied
        in the order given, where ``options`` is True (the step's defaults), False or None (the
        step is left out), a dict of the step's keywords (``{"mode": "plane", "per_line": True}``)
        or the value of its first keyword (``"plane"`` for ``detrend``'s ``mode``). The steps:
        ``"detrend"`` (:func:`detrend`), ``"fill_missing"`` (:func:`fill_missing`) and ``"filter"``
        (ISO 16610 filtration, :func:`xtopo.filtration.filter`); detrend first, so that the fill
        does not enter the fitted background.
    name : str
        What the steps are called in an error message (the argument or option that gave them).

    Returns
    -------
    tuple of (str, dict)
        Each step's name and all its options (defaults included), JSON-serialisable; the same
        request in another form gives the same tuple (``{"detrend": "plane"}`` and
        ``[("detrend", {"mode": "plane", "per_line": False})]``).

    Raises
    ------
    XtopoError
        For an unknown step, an option the step does not have, or a bad option value; the
        message names ``name`` and the step.
    """
    if steps is None:
        return ()
    if isinstance(steps, str):
        items = [(steps, True)]
    elif isinstance(steps, dict):
        items = list(steps.items())
    elif isinstance(steps, (list, tuple)):
        items = [(s, True) if isinstance(s, str) else s for s in steps]
    else:
        raise XtopoError(f"{name} must be a step name, a dict {{step: options}} or a sequence of steps, got "
                         f"{type(steps).__name__}; the steps: {', '.join(STEPS)}")
    out = []
    for item in items:
        if not (isinstance(item, (list, tuple)) and len(item) == 2 and isinstance(item[0], str)):
            raise XtopoError(f"{name}: a step is a name or a (name, options) pair, got {item!r}")
        step, options = item
        if step not in _STEPS:
            raise XtopoError(f"{name}: unknown preprocessing step {step!r}; the steps: {', '.join(STEPS)}")
        kwargs = _step_options(step, options, name)
        if kwargs is not None:
            out.append((step, kwargs))
    return tuple(out)


def apply_steps(obj, steps):
    """``obj`` after preprocessing steps requested by name (as a batch or the command line requests them).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement.
    steps : None, str, dict or sequence
        The steps and their options, e.g. ``{"detrend": "plane", "fill_missing": True}``; see
        :func:`checked_steps`.

    Returns
    -------
    Same type as ``obj``
        After each step in turn, each recorded in its ``history``; ``obj`` itself is unchanged.
    """
    for step, kwargs in checked_steps(steps, "steps"):
        obj = _STEPS[step](obj, **kwargs)
    return obj
