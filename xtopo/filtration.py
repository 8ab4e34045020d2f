"""Filtration of ISO 16610: Gaussian S- and L-filters and the F-operator (form removal).

The ISO chain turns the primary (measured) topography into the surfaces the ISO parameters
are defined on:

* **S-filter** (nesting index ``λs``): a Gaussian low-pass that removes the shortest
  wavelengths (probe and noise); the result is the *primary* profile or surface.
* **F-operator** (``form``): the least-squares polynomial of the nominal form is subtracted
  (mean, line/plane, or a polynomial of given degree); the result is the **S-F surface**.
* **L-filter** (nesting index ``λc``): a Gaussian low-pass whose output is the mean line
  (*waviness*); the primary minus it is the *roughness*, the **S-L surface**.

Profiles (line scans, or every line of a map along ``dim``) use the profile Gaussian filter of
ISO 16610-21, maps the areal Gaussian filter of ISO 16610-61 (isotropic: the same nesting index
along ``x`` and ``y``). Both keep the full length: near the ends the weights outside the data are
left out and the rest renormalised, or (``end="linear"``) a weighted line/plane is fitted at each
point (:mod:`xtopo._kernels.gaussian_filter`). Periodic data are
filtered circularly.

Default nesting indices (``"auto"``): ``λc`` from the ISO 4288 / ISO 21920-3 table for
nonperiodic profiles by their Ra, and ``λs`` from ``λc`` by the ISO 3274 table; see :func:`iso_cutoffs`.
"""

from __future__ import annotations

import numbers
import re
from typing import Annotated

import numpy as np
import xarray as xr

from ._apply import apply_lateral
from ._kernels import gaussian_filter as _gauss
from .conventions import X, Y, height_of, is_nonuniform, is_periodic, lateral_dims, length_factor, \
    shared_length_unit, spacing
from ._heights import replace_heights, subtract_polynomial
from .errors import GridError, UnitsError, XtopoError
from .params import Choice, Kind, Refused, checked

__all__ = ["filter", "iso_cutoffs", "CUTOFFS_MM", "COMPONENTS", "END_CORRECTIONS"]

#: what :func:`filter` returns: the S-L surface (roughness), the L-filter's output (waviness) or the S-F surface
COMPONENTS = ("roughness", "waviness", "primary")
#: the cut-off series of ISO 4288 / ISO 21920-3 (mm) and the upper Ra bound (µm) of each class (nonperiodic profiles)
CUTOFFS_MM = (0.08, 0.25, 0.8, 2.5, 8.0)
_RA_UPPER_UM = (0.02, 0.1, 2.0, 10.0)
#: λs (µm) that goes with each λc of :data:`CUTOFFS_MM` (ISO 3274 Table 1, ISO 21920-3)
_LAMBDA_S_UM = (2.5, 2.5, 2.5, 8.0, 25.0)
#: end corrections: name → order of the Gaussian regression filter (ISO 16610-31) that is used near the ends
END_CORRECTIONS = {"normalized": 0, "linear": 1}
#: the F-operator named by a word: polynomial degree
_FORMS = {"mean": 0, "line": 1, "plane": 1, "curvature": 2}
_QUANTITY = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([^\s\d].*?)\s*$")


class Cutoff(Kind):
    """A nesting index: None, "auto", a positive finite number (in the data's unit) or a string such as "0.8 mm"."""

    expects = "a length (a number or a string such as '0.8 mm'), 'auto' or None"
    takes_none = True

    def convert(self, value):
        if isinstance(value, str):
            m = _QUANTITY.match(value)
            if value != "auto" and not m:
                raise Refused
            if m:
                try:
                    length_factor(m.group(2), "m")
                except UnitsError as exc:
                    raise Refused(f"{{name}}={value!r}: {exc}", UnitsError) from None
                if not (np.isfinite(float(m.group(1))) and float(m.group(1)) > 0):
                    raise Refused("{name} must be a positive finite length, got " + repr(value))
            return value
        if not isinstance(value, numbers.Real) or isinstance(value, (bool, np.bool_)):
            raise Refused
        if not (np.isfinite(value) and value > 0):
            raise Refused(f"{{name}} must be a positive finite length, got {value!r}")
        return float(value)


class Form(Kind):
    """An F-operator: None, a word of ``_FORMS`` or a polynomial degree 0..8."""

    expects = f"None, one of {tuple(_FORMS)} or a polynomial degree 0..8"
    takes_none = True

    def convert(self, form):
        if (isinstance(form, str) and form in _FORMS) or (
                isinstance(form, numbers.Integral) and not isinstance(form, (bool, np.bool_)) and 0 <= form <= 8):
            return form
        raise Refused


def _length(value, units: str):
    """A nesting index declared as :class:`Cutoff`, as a number in ``units`` (None and "auto" as they are)."""
    if isinstance(value, str) and value != "auto":
        m = _QUANTITY.match(value)
        return float(m.group(1)) * length_factor(m.group(2), units)
    return value


def iso_cutoffs(ra: float, units: str) -> tuple[float, float]:
    """``(λs, λc)`` of ISO 4288 / ISO 3274 (also ISO 21920-3) for a nonperiodic profile of mean height ``ra``.

    Parameters
    ----------
    ra : float
        Ra of the profile, in ``units``.
    units : str
        Length unit of ``ra`` and of the result.

    Returns
    -------
    tuple of float
        ``λs`` and ``λc`` in ``units``: Ra ≤ 0.02 µm → 0.08 mm (λs 2.5 µm), ≤ 0.1 µm → 0.25 mm
        (2.5 µm), ≤ 2 µm → 0.8 mm (2.5 µm), ≤ 10 µm → 2.5 mm (8 µm), above → 8 mm (25 µm).
    """
    ra_um = ra * length_factor(units, "um")
    k = int(np.searchsorted(_RA_UPPER_UM, ra_um, side="left"))
    return _LAMBDA_S_UM[k] * length_factor("um", units), CUTOFFS_MM[k] * length_factor("mm", units)


def _lowpass(h, dims, cutoff, periodic, end="normalized"):
    """The Gaussian low-pass of ``h`` over ``dims`` (lazy on dask)."""
    return apply_lateral(_gauss.gaussian_lowpass, h, core_dims=dims, output_core_dims=[dims], what="filter",
                         kwargs={"cutoffs": [cutoff] * len(dims), "spacings": [spacing(h, d) for d in dims],
                                 "periodic": periodic, "order": END_CORRECTIONS[end]}).transpose(*h.dims)


def _auto_lambda_c(h, dims, degree, units, periodic):
    """λc by the ISO 4288 procedure: Ra measured with a trial cut-off (0.8 mm first), then the table's class."""
    lc = CUTOFFS_MM[2] * length_factor("mm", units)
    tried = []
    base = subtract_polynomial(h, dims, degree, "filter") if degree is not None else h
    longest = min(h.sizes[d] * spacing(h, d) for d in dims)
    for _ in range(len(CUTOFFS_MM)):
        tried.append(lc)
        r = base - _lowpass(base, dims, lc, periodic) if lc <= longest else base - base.mean(dims)
        new = iso_cutoffs(float(np.abs(r).mean()), units)[1]  # the class of the profiles' Ra
        if new in tried:
            return new
        lc = new
    return lc


def _auto_lambda_s(lc, units: str) -> float:
    """λs for ``lc``: the ISO 3274 ratio λc/λs of the nearest (logarithmically) cut-off of the series.

    On the series this is the table (0.8 mm → 2.5 µm); off it the ratio carries over, so that a
    scan of a few µm gets a λs in proportion instead of a 2.5 µm S-filter. Without an L-filter: 2.5 µm.
    """
    if lc is None:
        return _LAMBDA_S_UM[0] * length_factor("um", units)
    series = np.array(CUTOFFS_MM) * length_factor("mm", units)
    k = int(np.argmin(np.abs(np.log(series / lc))))
    return lc * _LAMBDA_S_UM[k] * length_factor("um", units) / series[k]


@checked
def filter(obj, lambda_s: Annotated[float | str | None, Cutoff()] = "auto",
           lambda_c: Annotated[float | str | None, Cutoff()] = "auto",
           form: Annotated[str | int | None, Form()] = "plane",
           component: Annotated[str, Choice(*COMPONENTS)] = "roughness",
           dim: Annotated[str | None, Choice(None, X, Y, error=GridError)] = None,
           end: Annotated[str, Choice(*END_CORRECTIONS)] = "normalized"):
    """ISO 16610 filtration: S-filter, F-operator and L-filter; the roughness, waviness or S-F surface.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement on a uniform grid (line scan or map); missing data are ignored by the
        filters and stay missing.
    lambda_s : float, str, "auto" or None
        Nesting index of the S-filter (short-wavelength cut-off), a length in the measurement's
        unit (``2.5`` with heights in µm) or with its unit (``"2.5 um"``). ``"auto"``: from ``λc``
        by the ISO 3274 table (2.5 µm up to λc = 0.8 mm, 8 µm at 2.5 mm, 25 µm at 8 mm; for a λc
        off that series, the ratio λc/λs of the nearest one). None: no S-filter. An S-filter
        shorter than the pixel spacing leaves the heights as they are.
    lambda_c : float, str, "auto" or None
        Nesting index of the L-filter (long-wavelength cut-off, the ``λc`` of profiles), as
        ``lambda_s``. ``"auto"``: the ISO 4288 / ISO 21920-3 class of the profiles' Ra (Ra measured
        with λc = 0.8 mm, then with the class's cut-off until the class holds; for maps the Ra of
        the lines along ``x``); this computes Ra, so a dask input is evaluated once. None: no
        L-filter (only ``component="primary"`` makes sense then).
    form : {"mean", "line", "plane", "curvature"}, int or None
        F-operator: the least-squares polynomial subtracted after the S-filter (``"line"`` and
        ``"plane"`` are degree 1, ``"curvature"`` degree 2, an int any degree up to 8; for a map the
        polynomial in ``x`` and ``y``, for profiles one per line). None: no form removal.
    component : {"roughness", "waviness", "primary"}
        ``"roughness"``: the S-L surface (S-F surface minus the L-filter's mean surface);
        ``"waviness"``: the L-filter's output; ``"primary"``: the S-F surface (no L-filter).
    dim : {None, "x", "y"}
        None: profiles are filtered as profiles (ISO 16610-21) and maps with the areal filter
        (ISO 16610-61). ``"x"`` or ``"y"``: every line of a map along ``dim`` is filtered as a
        profile, with its own form removal.
    end : {"normalized", "linear"}
        End correction (ISO 16610-28/-31), where the kernel reaches past an end or a missing
        point: ``"normalized"`` leaves those weights out and renormalises the rest (the Gaussian
        regression filter of order 0); ``"linear"`` fits a line (a plane for the areal filter)
        by Gaussian-weighted least squares at each point (order 1), which keeps a sloped
        profile or plane straight up to the ends, at about twice the cost. Both are the plain
        Gaussian filter where the whole kernel lies on data.

    Returns
    -------
    Same type as ``obj``
        The filtered heights (same units, float64). Attributes ``lambda_s`` and ``lambda_c`` (in
        the measurement's length unit, ``nan`` for a filter not applied) record the nesting
        indices, and ``history`` the step. A periodic measurement is filtered circularly and
        stays periodic unless the form removal (degree ≥ 1) breaks its periodicity; with
        missing points it is filtered with the end correction instead.

    Raises
    ------
    GridError
        For a nonuniform line scan, ``λs ≥ λc``, or a cut-off longer than the measurement.

    Notes
    -----
    Weighting function ``s(x) = exp(-π (x/(α λ))²)/(α λ)`` with ``α = sqrt(ln 2/π)``: 50 %
    amplitude transmission at the nesting index. The filters keep the full length (the end
    correction renormalises the weights inside the data).
    """
    h = height_of(obj)
    if is_nonuniform(h) or (isinstance(obj, xr.Dataset) and is_nonuniform(obj)):
        raise GridError("filter needs a uniform grid; this is a nonuniform line scan (interpolate it first)")
    units = shared_length_unit(h, "filter")
    lat = lateral_dims(h)
    if dim is not None and dim not in lat:
        raise GridError(f"dim={dim!r} is not a lateral dimension of these data (they have {lat})")
    dims = lat if dim is None else (dim,)
    ls, lc = _length(lambda_s, units), _length(lambda_c, units)
    degree = _FORMS[form] if isinstance(form, str) else None if form is None else int(form)
    periodic = is_periodic(obj)
    if component == "primary" and lc not in (None, "auto"):
        raise XtopoError("component='primary' is the S-F surface, which has no L-filter; give lambda_c=None")
    if component == "primary":
        lc = None
    elif lc is None:
        raise XtopoError(f"component={component!r} needs the L-filter; give lambda_c (or 'auto')")
    elif lc == "auto":
        lc = _auto_lambda_c(h, dims, degree, units, periodic and degree in (None, 0))
    if ls == "auto":
        ls = _auto_lambda_s(lc, units)
    longest = min(h.sizes[d] * spacing(h, d) for d in dims)
    for name, value in (("lambda_s", ls), ("lambda_c", lc)):
        if value is not None and value > longest:
            raise GridError(f"{name}={value:.4g} {units} is longer than the measurement ({longest:.4g} {units} "
                            f"along {'/'.join(dims)}); give a shorter cut-off")
    if ls is not None and lc is not None and ls >= lc:
        raise GridError(f"lambda_s={ls:.4g} {units} must be shorter than lambda_c={lc:.4g} {units}")
    out = h.astype(float)
    if ls is not None:
        out = _lowpass(out, dims, ls, periodic, end)
    breaks = degree is not None and degree > 0
    if degree is not None:
        out = subtract_polynomial(out, dims, degree, "filter")
    if lc is not None:
        mean = _lowpass(out, dims, lc, periodic and not breaks, end)
        out = out - mean if component == "roughness" else mean
    line = (f"filter(lambda_s={_fmt(ls)}, lambda_c={_fmt(lc)} {units}, form={form!r}, component={component!r}, "
            f"end={end!r}, {'areal ISO 16610-61' if len(dims) == 2 else f'profiles along {dims[0]} ISO 16610-21'})")
    res = replace_heights(obj, out, line, nonperiodic=breaks and periodic)
    res.attrs.update(lambda_s=float("nan") if ls is None else ls, lambda_c=float("nan") if lc is None else lc)
    return res


def _fmt(value) -> str:
    return "None" if value is None else f"{value:.6g}"
