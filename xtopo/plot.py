"""HoloViews figures of measurements, analysis results, twin averages and contact results.

Every function returns a HoloViews object that renders with the bokeh and the
matplotlib backend (``hv.render(obj, backend=...)``, or displayed in Jupyter after
``hv.extension("bokeh")``). HoloViews is imported on first use, not with xtopo.

* :func:`topography` — height map (image with colorbar) or profile of a measurement,
  also any other map on ``(y, x)`` (pressure, gap, contact);
* :func:`curve` — a scale-dependent result (PSD, ACF, VBM, SDRP) on log-log axes,
  unreliable scales omitted (NaN) or dashed (when a cutoff is known and the points are present);
* :func:`spectrum_map` — a 2D PSD on ``(q_y, q_x)`` with a logarithmic colour scale;
* :func:`twin_curves` — a twin average: each measurement coloured, the average thick black;
  :func:`twin_figure` — the paper's Figure 5 (PSD, ACF, VBM, curvature) of a twin;
* :func:`contact_area` — relative contact area against mean pressure, unconverged
  points translucent; :func:`contact_maps` — pressure, gap and contact maps;
* :func:`measurement_maps` — one panel per measurement of a twin;
* :func:`plot` — dispatches on what the object holds (used by ``.topo.plot()``).

Large maps are block-averaged to at most ``max_pixels`` per side before they are
handed to HoloViews, so a notebook or report never carries a full-resolution map.
"""

from __future__ import annotations

import math
import re
import warnings
from typing import Annotated

import numpy as np
import xarray as xr

from ._optional import require
from .conventions import LATERAL_DIMS, X, Y, height_of, length_factor, normalize_units
from .errors import GridError, UnitsError, XtopoError
from .params import Count, Data, Dict, Flag, Names, Positive, Text, checked
from .stitching import ANALYSES, PER_DECADE
from .twins import measurements

_PIXELS = Count(min=2)

__all__ = ["plot", "topography", "curve", "spectrum_map", "twin_curves", "twin_figure", "contact_area", "contact_maps",
           "measurement_maps", "downsample", "unit_label", "PALETTE"]

#: coordinate names of scale-dependent curves and whether the scale is a wavevector
CURVE_COORDS = {"q": "wavevector", "distance": "length", "bandwidth": "length"}
#: colours of individual measurements (Category10); the average is black
PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
           "#bcbd22", "#17becf")
#: default largest number of pixels per side of a map sent to the browser
MAX_PIXELS = 512
#: default largest number of points of a profile sent to the browser
MAX_POINTS = 8192

_WIDTH, _HEIGHT = 460, 360
_DISPLAY_UNITS = ("m", "mm", "um", "nm", "pm")
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


# --------------------------------------------------------------------------- helpers

def _hv():
    """Import HoloViews with the bokeh (and, when available, matplotlib) plotting backends.

    Importing a plotting backend does not change a backend the user already selected
    with ``hv.extension``.
    """
    hv = require("holoviews", "plotting")  # the [plot] extra, loaded on first use (startup time)
    current = hv.Store.current_backend if hv.Store.renderers else None
    require("holoviews.plotting.bokeh", "plotting")
    try:
        import holoviews.plotting.mpl  # noqa: F401
    except ImportError:  # pragma: no cover - matplotlib is optional
        pass
    if current is not None and hv.Store.current_backend != current:  # setting it costs 0.1-0.3 s: only on a change
        hv.Store.set_current_backend(current)
    return hv


def _style(element, *, common=None, bokeh=None, matplotlib=None):
    """Apply options per backend (only to the backends that are loaded). Style a container empty, then fill it
    (``.clone(elements)``): styling a full one walks its tree once per styled element in it (quadratic, seconds)."""
    hv = _hv()
    common = common or {}
    element = element.opts(**common, **(bokeh or {}), backend="bokeh")
    if "matplotlib" in hv.Store.renderers:
        element = element.opts(**common, **(matplotlib or {}), backend="matplotlib")
    return element


def unit_label(units) -> str:
    """Readable form of a UDUNITS string: ``"um"`` → ``"µm"``, ``"m-1"`` → ``"m⁻¹"``, ``"m3"`` → ``"m³"``."""
    u = "1" if units is None else str(units).strip()
    if u == "1":
        return ""
    u = re.sub(r"\bu(?=m)", "µ", u)
    return re.sub(r"(?<=[A-Za-zµ*])(-?\d+)", lambda m: m.group(1).translate(_SUPERSCRIPT), u)


def _dimension(name: str, attrs: dict, label: str | None = None, units: str | None = None):
    hv = _hv()
    label = label or attrs.get("long_name") or name
    unit = unit_label(units if units is not None else attrs.get("units"))
    return hv.Dimension(name, label=str(label), unit=unit or None)


def _is_length(units) -> bool:
    try:
        normalize_units(units)
    except UnitsError:
        return False
    return True


def _display_unit(units: str, magnitude: float) -> str:
    """The largest of m, mm, µm, nm, pm in which ``magnitude`` (given in ``units``) is at least 1."""
    if not (np.isfinite(magnitude) and magnitude > 0):
        return normalize_units(units)
    in_m = magnitude * length_factor(units, "m")
    return next((u for u in _DISPLAY_UNITS if in_m >= length_factor(u, "m") * (1 - 1e-9)), _DISPLAY_UNITS[-1])


def _title(obj, title):
    if title is not None:
        return str(title)
    a = obj.attrs
    return str(a.get("title") or a.get("instrument") or a.get("long_name") or getattr(obj, "name", "") or "")


@checked
def downsample(da: Annotated[xr.DataArray, Data("DataArray")],
               max_pixels: Annotated[int, _PIXELS] = MAX_PIXELS) -> xr.DataArray:
    """Block-average ``da`` so that no lateral dimension exceeds ``max_pixels`` points.

    Boolean maps become fractions (e.g. the fraction of a block in contact). Dask
    arrays are reduced lazily and only the reduced array is computed by the caller.

    Parameters
    ----------
    da : xarray.DataArray
        A map on ``(y, x)`` or a profile on ``x`` (other dims are kept).
    max_pixels : int
        Largest number of points per lateral dimension (at least 2).
    """
    factors = {d: math.ceil(da.sizes[d] / max_pixels) for d in LATERAL_DIMS if d in da.dims}
    factors = {d: f for d, f in factors.items() if f > 1}
    if da.dtype == bool:
        da = da.astype(float)  # keeps the name and attrs
    if not factors:
        return da
    with warnings.catch_warnings(), np.errstate(all="ignore"):  # all-NaN blocks
        warnings.simplefilter("ignore", RuntimeWarning)
        out = da.coarsen(factors, boundary="trim").mean(keep_attrs=True)  # keeps the name too
    return out.assign_attrs(downsampled=f"block mean over {factors}")


def _cmap(cmap):
    """``cmap`` if HoloViews knows it as a colour map (a name or a list of colours), else an XtopoError."""
    from holoviews.plotting.util import process_cmap

    try:
        colours = process_cmap(cmap)
    except (TypeError, ValueError, KeyError) as exc:
        raise XtopoError(f"cmap={cmap!r} is not a colour map ({exc})") from None
    if not len(colours):
        raise XtopoError("cmap=[] has no colours; give a colour map name like 'viridis' or a list of colours")
    return cmap


def _color(color):
    """``color`` if it is None or a colour name or hex string both plotting backends accept."""
    from bokeh.core.properties import Color

    if color is not None and not (isinstance(color, str) and Color().is_valid(color)):
        raise XtopoError(f"color must be a colour name or hex string like '#1f77b4' (or None), got {color!r}")
    return color


def _frame(x, y) -> dict:
    """Bokeh frame size of an image with equal scales on both axes (aspect clipped to 1:4..4:1)."""
    width = _WIDTH - 120
    ratio = (np.ptp(y) / np.ptp(x)) if np.size(x) > 1 and np.size(y) > 1 and np.ptp(x) > 0 else 1.0
    return dict(frame_width=width, frame_height=int(round(width * float(np.clip(ratio, 0.25, 4.0)))))


# --------------------------------------------------------------------------- maps

@checked
def topography(obj: Annotated[xr.Dataset | xr.DataArray, Data()], *,
               max_pixels: Annotated[int, _PIXELS] = MAX_PIXELS, cmap: str = "viridis",
               title: Annotated[str | None, Text()] = None, variable: Annotated[str, Text()] = "height"):
    """Height map (area scan) or profile (line scan) with units on every axis.

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        A measurement, a height DataArray or any map on ``(y, x)`` / profile on ``x``
        (pressure, gap, ...). Missing data (``mask``) are shown blank.
    max_pixels : int
        Maps are block-averaged to at most this many pixels per side (profiles to
        at most ``MAX_POINTS`` points).
    cmap : str
        Colour map of the image.
    title : str, optional
        Default: the measurement's ``title``/``instrument``.
    variable : str
        Variable of a Dataset to show (default ``"height"``, missing data masked).

    Returns
    -------
    holoviews.Image or holoviews.Curve
        Lengths are shown in a readable unit (mm, µm, nm, ...).
    """
    hv = _hv()
    cmap = _cmap(cmap)
    if isinstance(obj, xr.Dataset):
        if variable != "height" and variable not in obj.data_vars:
            raise XtopoError(f"variable={variable!r} is not a data variable of the Dataset; choose from "
                             f"{sorted(map(str, obj.data_vars))}")
        da = height_of(obj) if variable == "height" else obj[variable]
        da = da.assign_attrs({k: v for k, v in obj.attrs.items() if k in ("title", "instrument")} | dict(da.attrs))
    else:
        da = obj
    lat = tuple(d for d in LATERAL_DIMS if d in da.dims)
    extra = [d for d in da.dims if d not in lat]
    if X not in lat:
        raise XtopoError(f"{da.name!r} has no 'x' dimension (dims {da.dims}); nothing to draw as a map or profile")
    if extra:
        raise XtopoError(f"{da.name!r} has dims {extra} besides the lateral ones; select one item first, "
                         f"e.g. .isel({extra[0]}=0)")
    if any(da.sizes[d] < 2 for d in lat):
        raise GridError(f"{da.name!r} has {dict(da.sizes)} points; a map or profile needs at least 2 along "
                        f"{' and '.join(lat)}")
    name = str(da.name or "value")
    units = da.attrs.get("units")
    small = downsample(da, max_pixels if len(lat) == 2 else MAX_POINTS)
    z = small.values.astype(np.float32 if len(lat) == 2 else np.float64)
    finite, zu = z[np.isfinite(z)], units
    if finite.size and _is_length(units):  # heights in a readable length unit
        zu = _display_unit(units, float(np.max(np.abs(finite))))
        z = z * length_factor(units, zu)
    coords = {d: np.asarray(small[d].values, dtype=float) for d in lat}
    extent = max([0.0] + [float(np.ptp(v)) for v in coords.values()])
    xunits = da[X].attrs.get("units")
    lu = _display_unit(xunits, extent) if _is_length(xunits) else xunits
    dims = {}
    for d in lat:
        cu = small[d].attrs.get("units")
        if _is_length(cu):
            coords[d], cu = coords[d] * length_factor(cu, lu), lu
        dims[d] = _dimension(d, small[d].attrs, units=cu)
    vdim = _dimension(name, da.attrs, units=zu)
    label = _title(da, title)
    if len(lat) == 2:
        el = hv.Image((coords[X], coords[Y], z), kdims=[dims[X], dims[Y]], vdims=[vdim],
                      label="").relabel(group="Topography" if name == "height" else "Map")
        return _style(el, common=dict(cmap=cmap, colorbar=True, title=label),
                      bokeh=dict(tools=["hover"], toolbar="above", **_frame(coords[X], coords[Y])),
                      matplotlib=dict(fig_inches=5, aspect="equal"))
    el = hv.Curve((coords[X], z), kdims=[dims[X]], vdims=[vdim])
    return _style(el, common=dict(title=label, color="#1f77b4"),
                  bokeh=dict(frame_width=_WIDTH - 80, frame_height=_HEIGHT - 150, line_width=1, tools=["hover"],
                             toolbar="above"),
                  matplotlib=dict(linewidth=1, aspect=1.8))


@checked
def spectrum_map(da: Annotated[xr.DataArray, Data("DataArray")], *, max_pixels: Annotated[int, _PIXELS] = MAX_PIXELS,
                 cmap: str = "inferno", title: Annotated[str | None, Text()] = None):
    """A 2D power spectrum on ``(q_y, q_x)`` with a logarithmic colour scale."""
    hv = _hv()
    cmap = _cmap(cmap)
    if "q_x" not in da.dims or "q_y" not in da.dims:
        raise XtopoError(f"spectrum_map() needs a 2D power spectrum on (q_y, q_x), got {da.name!r} with dims {da.dims}")
    small = downsample(da.rename({"q_y": Y, "q_x": X}), max_pixels).rename({Y: "q_y", X: "q_x"})
    z = small.values.astype(np.float32)
    z = np.where(z > 0, z, np.nan)
    el = hv.Image((small["q_x"].values, small["q_y"].values, z), vdims=[_dimension(str(da.name or "psd"), da.attrs)],
                  kdims=[_dimension(q, small[q].attrs) for q in ("q_x", "q_y")])
    return _style(el, common=dict(cmap=cmap, colorbar=True, logz=True, title=_title(da, title)),
                  bokeh=_frame(small["q_x"].values, small["q_y"].values), matplotlib=dict(fig_inches=5, aspect="equal"))


# --------------------------------------------------------------------------- curves

def _curve_dim(da) -> str:
    dims = [d for d in da.dims if d in CURVE_COORDS]
    if len(dims) != 1:
        raise XtopoError(f"{da.name!r} is not a scale-dependent curve: expected one of the dims "
                         f"{tuple(CURVE_COORDS)}, got {da.dims}")
    return dims[0]


def _cutoff_of(da, cutoff):
    """Reliability cutoff (length) of a result: the argument, the coordinate, or the attribute."""
    if cutoff is not None:
        return Positive().check(getattr(cutoff, "values", cutoff), "cutoff (a length in the curve's length unit)")
    coord = da.coords.get("reliability_cutoff")
    cutoff = coord if coord is not None and coord.ndim == 0 else da.attrs.get("reliability_cutoff")
    value = np.nan if cutoff is None else float(np.asarray(getattr(cutoff, "values", cutoff)))
    return value if np.isfinite(value) and value > 0 else None


def _positive(x, y):
    """Points that can be drawn on log-log axes (both positive); others become gaps (NaN)."""
    ok = (x > 0) & np.isfinite(x)
    x, y = x[ok], y[ok]
    return x, np.where(y > 0, y, np.nan)


def _safe_label(label, *dims) -> str:
    """A legend label that HoloViews cannot mistake for a dimension name (it would map it to data)."""
    label = str(label)
    return label + "\u00a0" if label in {d.name for d in dims} else label


def _line(data, xdim, ydim, label, width, dashed=False, **common):
    """An hv.Curve ``width`` wide (``dashed``) with the options ``common`` (colour, alpha, ...) on both backends."""
    el = _hv().Curve(data, kdims=[xdim], vdims=[ydim], label=label)
    return _style(el, common=common, bokeh=dict(line_width=width, **({"line_dash": "dashed"} if dashed else {})),
                  matplotlib=dict(linewidth=width, **({"linestyle": "--"} if dashed else {})))


def _line_elements(x, y, *, xdim, ydim, label, color, unreliable, line_width=2):
    """One or two hv.Curve elements: reliable part solid, ``unreliable`` (bool mask) part dashed."""
    label = _safe_label(label, xdim, ydim)
    out = [_line((x, np.where(unreliable, np.nan, y)), xdim, ydim, label, line_width, color=color)]
    if unreliable.any():
        # overlap by one point so the dashed part joins the solid one
        edge = unreliable | np.r_[False, unreliable[:-1]] | np.r_[unreliable[1:], False]
        out.append(_line((x, np.where(edge, y, np.nan)), xdim, ydim, f"{label} (unreliable)", line_width, True,
                         color=color))
    return out


def _axes_opts(title, logx=True, logy=True, legend_outside=False):
    where = "right" if legend_outside else "bottom_left"  # many entries (a twin): beside the axes, not over the curves
    return dict(common=dict(logx=logx, logy=logy, title=title, show_grid=True),
                bokeh=dict(frame_width=_WIDTH - 80, frame_height=_HEIGHT - 90, legend_position=where, tools=["hover"],
                           toolbar="above"),
                matplotlib=dict(aspect=1.3, legend_position=where))


@checked
def curve(da: Annotated[xr.DataArray, Data("DataArray")], *, cutoff=None, title: Annotated[str | None, Text()] = None,
          label: Annotated[str | None, Text()] = None, color: str | None = None):
    """A scale-dependent result (PSD, ACF, VBM, SDRP, ...) on log-log axes.

    Parameters
    ----------
    da : xarray.DataArray
        A curve on one of the coordinates ``q`` (wavevector), ``distance`` or
        ``bandwidth`` (lengths), with ``units``/``long_name`` attrs. Further dims
        (directions, a batch of samples) give one coloured curve each. NaN points
        (scales masked as unreliable) are left out.
    cutoff : float or xarray.DataArray, optional
        Short reliability cutoff (a length, in the curve's length unit). Default:
        the result's ``reliability_cutoff`` coordinate or attribute. Points on the
        unreliable side that are still present (``reliable=False`` results) are dashed.
    title, label, color : str, optional

    Returns
    -------
    holoviews.Overlay
    """
    hv = _hv()
    coord = _curve_dim(da)
    cut = _cutoff_of(da, cutoff)
    color = _color(color)
    if da.sizes[coord] == 0:
        raise XtopoError(f"{da.name!r} has no points along {coord!r}; nothing to draw")
    xdim = _dimension(coord, da[coord].attrs)
    ydim = _dimension(str(da.name or "value"), da.attrs)
    da = da.transpose(..., coord)
    x = np.asarray(da[coord].values, dtype=float)
    rows = da.values.reshape(-1, x.size)
    others = [d for d in da.dims if d != coord]
    keys = [", ".join(str(da[d].values[i]) if d in da.coords else f"{d}={i}" for d, i in zip(others, idx))
            for idx in np.ndindex(*[da.sizes[d] for d in others])]  # one empty key without other dims
    elements, wave = [], CURVE_COORDS[coord] == "wavevector"
    for k, (key, row) in enumerate(zip(keys, rows)):
        xs, ys = _positive(x, row.astype(float))
        # scales below the cutoff: wavevectors above 2π/cut, lengths below cut
        bad = np.zeros(xs.shape, dtype=bool) if cut is None else xs > 2 * np.pi / cut if wave else xs < cut
        lab = f"{label or ''} {key}".strip()
        col = color if color is not None and len(rows) == 1 else PALETTE[k % len(PALETTE)]
        elements += _line_elements(xs, ys, xdim=xdim, ydim=ydim, label=lab, color=col, unreliable=bad)
    return _style(hv.Overlay(), **_axes_opts(_title(da, title))).clone(elements)


def group_colours(groups: dict) -> dict:
    """Colour of each group of ``groups`` (measurement name → group), in order of first appearance:
    the colours :func:`twin_curves` draws the groups in."""
    return {g: PALETTE[k % len(PALETTE)] for k, g in enumerate(dict.fromkeys(groups.values()))}


@checked
def twin_curves(ds: Annotated[xr.Dataset, Data("Dataset")], *, labels: Annotated[dict | None, Dict()] = None,
                title: Annotated[str | None, Text()] = None, groups: Annotated[dict | None, Dict()] = None,
                legend: Annotated[bool, Flag()] = True):
    """A twin average as in the paper's Figure 5: thin coloured measurements, the thick black average.

    Each measurement's curve is drawn thin over its reliable range (the values averaged),
    the average thick black on top with its predicted standard error as a grey band.

    Parameters
    ----------
    ds : xarray.Dataset
        The result of a twin average (:func:`xtopo.stitching.average_curves`): ``average``
        on the collocation coordinate and ``curves`` on (``measurement``, coordinate);
        ``uncertainty`` where present gives the band.
    labels : dict, optional
        Legend text per measurement name or group (e.g. ``"afm-5um (AFM, 5 µm)"``); default: the names.
    title : str, optional
        Default: the average's ``long_name``.
    groups : dict, optional
        Group per measurement name (e.g. its instrument): one colour and one legend entry
        per group, which keeps the legend short for a twin of many replicates.
    legend : bool
        Show the legend (outside the axes on the right, one column).

    Returns
    -------
    holoviews.Overlay
    """
    hv = _hv()
    labels, groups = labels or {}, groups or {}
    if "average" not in ds or "curves" not in ds:
        raise XtopoError(f"twin_curves() needs a twin average with 'average' and 'curves' (got {list(ds.data_vars)})")
    coord = _curve_dim(ds["average"])
    curves = ds["curves"].transpose("measurement", coord)
    xdim = _dimension(coord, ds[coord].attrs)
    long_name = ds["average"].attrs.get("long_name") or curves.attrs.get("long_name") or str(curves.name or "value")
    yname = re.sub(r"\W+", "_", str(curves.attrs.get("long_name") or long_name)).strip("_") or "value"
    ydim = _dimension(yname, curves.attrs or ds["average"].attrs)
    x = np.asarray(ds[coord].values, dtype=float)
    names = [str(n) for n in np.asarray(curves["measurement"].values)]
    group_of = {n: str(groups.get(n, n)) for n in names}  # the name is its own group unless ``groups`` say
    colours = group_colours(group_of)
    elements = []
    first = {g: n for n, g in reversed(group_of.items())}  # replicates share their group's one legend entry
    avg = ds["average"].values.astype(float)
    if "uncertainty" in ds:  # the band: average ± its standard error (clipped above zero for log axes)
        se = ds["uncertainty"].values.astype(float)
        ok = np.isfinite(avg) & np.isfinite(se) & (avg > 0) & (x > 0)
        if ok.any():
            lo = np.maximum(avg - se, avg / 10)
            band = hv.Area((x[ok], lo[ok], (avg + se)[ok]), kdims=[xdim],
                           vdims=[ydim, hv.Dimension(f"{yname}_upper")], label="average ± standard error")
            # matplotlib fills an Area with its default facecolor (a colour cycle) over ``color``: give it grey too
            elements.append(_style(band, common=dict(color="#888888", alpha=0.35),
                                   bokeh=dict(line_alpha=0), matplotlib=dict(facecolor="#888888", linewidth=0)))
    for name, row in zip(names, curves.values):
        xs, ys = _positive(x, row.astype(float))
        group = group_of[name]
        label = _safe_label(labels.get(group, group), xdim, ydim)
        elements.append(_line((xs, ys), xdim, ydim, label, 1.2, color=colours[group], alpha=0.8,
                              show_legend=first[group] == name))
    elements.append(_line(_positive(x, avg), xdim, ydim, "average", 4, color="black"))
    opts = _axes_opts(title or long_name, legend_outside=True)
    opts["common"]["show_legend"] = legend
    return _style(hv.Overlay(), **opts).clone(elements)


@checked
def twin_figure(tree, *, analyses: Annotated[tuple | None, Names(*ANALYSES)] = None,
                groups: Annotated[dict | None, Dict()] = None, labels: Annotated[dict | None, Dict()] = None,
                per_decade: int | None = None, cols: Annotated[int, Count()] = 2):
    """The paper's Figure 5 for a twin: PSD, ACF, VBM and scale-dependent curvature averages.

    One log-log panel per analysis of :data:`xtopo.stitching.ANALYSES` (with units): each
    measurement a thin curve over its reliable range, coloured by instrument (its
    ``instrument`` attr, else its name), the average thick black with its uncertainty band.
    One legend, outside the first row's last panel in one column, with one entry per instrument.

    Parameters
    ----------
    tree : xarray.DataTree
        A twin (:func:`xtopo.twin`).
    analyses : sequence of str, optional
        Names from :data:`xtopo.stitching.ANALYSES` (default: all).
    groups : dict, optional
        Legend group per measurement name (default: its ``instrument`` attr).
    labels : dict, optional
        Legend text per group.
    per_decade : int, optional
        Collocation points per decade (default that of :func:`xtopo.stitching.twin_psd`).
    cols : int
        Panels per row.

    Returns
    -------
    holoviews.Layout
    """
    hv = _hv()

    ms = measurements(tree)
    names = list(ANALYSES) if analyses is None else analyses
    groups = {n: str(ds.attrs.get("instrument") or n) for n, ds in ms.items()} if groups is None else groups
    per_decade = PER_DECADE if per_decade is None else per_decade
    # the one legend sits right of the last panel of the first row, where it covers no other panel
    panels = [twin_curves(ANALYSES[a](tree, per_decade=per_decade).compute(), groups=groups, labels=labels,
                          title=ANALYSES[a].title, legend=k == min(cols, len(names)) - 1) for k, a in enumerate(names)]
    # matplotlib: panels large enough for their long axis labels, rows apart enough that no title meets the x label
    # above, the letters (A, B, ...) above the panels, clear of the y labels
    return _style(hv.Layout(), common=dict(shared_axes=False),
                  matplotlib=dict(fig_size=150, vspace=0.4, sublabel_position=(-0.3, 1.08))).clone(panels).cols(cols)


# --------------------------------------------------------------------------- contact

def _contact_steps_dim(ds) -> str | None:
    return next((d for d in ("load", "mean_pressure", "penetration") if d in ds.dims), None)


@checked
def contact_area(results, *, labels: Annotated[dict | None, Dict()] = None, title: Annotated[str | None, Text()] = None,
                 x: Annotated[str, Text()] = "mean_pressure", y: Annotated[str, Text()] = "area_fraction"):
    """Relative contact area against mean pressure on log-log axes; unconverged points translucent.

    Parameters
    ----------
    results : xarray.Dataset or dict of str to xarray.Dataset
        Load curves (:meth:`xtopo.contact.Scene.curve`, stacked along ``load`` or
        ``penetration``) or single solutions; a dict overlays several (e.g. smooth
        sphere, rough sphere, nominally flat roughness).
    labels : dict, optional
        Legend text per key of ``results``.
    title : str, optional
        Figure title (default none).
    x, y : str
        Variables on the axes (default: ``mean_pressure`` in units of E*, ``area_fraction``).

    Returns
    -------
    holoviews.Overlay
    """
    hv = _hv()
    if isinstance(results, xr.Dataset):
        results = {"": results}
    results, labels = Dict().check({} if results is None else results, "results"), labels or {}
    if not results:
        raise XtopoError("contact_area() needs at least one contact result")
    elements = []
    for k, (key, ds) in enumerate(results.items()):
        Data("Dataset").check(ds, f"contact_area() result {key!r}")
        for v in (x, y):
            if v not in ds:
                raise XtopoError(f"contact result {key!r} has no variable {v!r} (variables: {list(ds.data_vars)})")
        xv = np.atleast_1d(ds[x].values).astype(float)
        yv = np.atleast_1d(ds[y].values).astype(float)
        conv = (np.atleast_1d(ds["converged"].values).astype(bool) if "converged" in ds
                else np.ones(xv.shape, dtype=bool))
        ok = (xv > 0) & (yv > 0)
        color = PALETTE[k % len(PALETTE)]
        relative = x == "mean_pressure" and ds[x].attrs.get("units") == "E*"  # p/E*: its unit is in the label
        xdim = _dimension(x, ds[x].attrs, "mean pressure p/E*" if relative else None, "1" if relative else None)
        ydim = _dimension(y, ds[y].attrs, label="relative contact area A/A₀" if y == "area_fraction" else None)
        name = _safe_label(labels.get(key, key), xdim, ydim)
        elements.append(_line((xv[ok], yv[ok]), xdim, ydim, name, 1, color=color))
        for flag, alpha, suffix in ((True, 1.0, ""), (False, 0.3, " (not converged)")):
            sel = ok & (conv == flag)
            if not sel.any():
                continue
            pts = hv.Scatter((xv[sel], yv[sel]), kdims=[xdim], vdims=[ydim], label=(name + suffix).strip())
            elements.append(_style(pts, common=dict(color=color, alpha=alpha),
                                   bokeh=dict(size=8, tools=["hover"]), matplotlib=dict(s=30)))
    return _style(hv.Overlay(), **_axes_opts(title or "contact area", logx=True, logy=True)).clone(elements)


@checked
def contact_maps(ds: Annotated[xr.Dataset, Data("Dataset")], *, variables=("pressure", "gap", "contact"),
                 step: Annotated[int, Count(min=-2**62)] = -1, max_pixels: Annotated[int, _PIXELS] = MAX_PIXELS):
    """Maps of a contact solution (pressure, gap, contact; profiles for line contacts).

    Parameters
    ----------
    ds : xarray.Dataset
        A solution (:meth:`xtopo.contact.Scene.solve`) or a load curve, of which
        ``step`` (an index along ``load``/``penetration``) is shown.
    variables : sequence of str
        Maps to show, in order.
    step : int
        Index of the load step of a load curve (default: the last, highest load).
    max_pixels : int
        See :func:`topography`.

    Returns
    -------
    holoviews.Layout
    """
    hv = _hv()
    variables = [variables] if isinstance(variables, str) else variables
    if not isinstance(variables, (list, tuple)) or not variables or not all(isinstance(v, str) for v in variables):
        raise XtopoError(f"variables must be a name or a non-empty list of names of maps, got {variables!r}")
    dim = _contact_steps_dim(ds)
    steps = 1 if dim is None else ds.sizes[dim]
    if not -steps <= step < steps:
        raise XtopoError(f"step must be an index of the {steps} step(s) of the result (-{steps} to {steps - 1}), "
                         f"got {step!r}")
    if dim is not None:
        ds = ds.isel({dim: step})
    missing = [v for v in variables if v not in ds]
    if missing:
        raise XtopoError(f"the contact result has no map {missing[0]!r} (variables: {list(ds.data_vars)})")
    at = ""
    if "mean_pressure" in ds:
        at = f" at p = {float(ds['mean_pressure']):.3g} {unit_label(ds['mean_pressure'].attrs.get('units', ''))}"
    cmaps = {"pressure": "inferno", "gap": "viridis", "contact": "gray_r", "displacement": "viridis"}
    return hv.Layout([topography(ds[v], max_pixels=max_pixels, cmap=cmaps.get(v, "viridis"),
                                 title=f"{ds[v].attrs.get('long_name', v)}{at}") for v in variables]).cols(3)


# --------------------------------------------------------------------------- twins

@checked
def measurement_maps(tree, *, max_pixels: Annotated[int, _PIXELS] = 256, cols: Annotated[int, Count()] = 3):
    """One panel per measurement of a twin: height maps of area scans, profiles of line scans.

    Parameters
    ----------
    tree : xarray.DataTree or dict of str to xarray.Dataset
        A twin (:func:`xtopo.twin`) or measurements by name.
    max_pixels : int
        See :func:`topography` (default 256 keeps a twin overview light).
    cols : int
        Panels per row.
    """
    hv = _hv()

    ms = measurements(tree) if isinstance(tree, xr.DataTree) else Dict().check(tree, "measurement_maps() tree")
    if not ms:
        raise XtopoError("measurement_maps() needs at least one measurement; the twin has none")
    for name, ds in ms.items():
        Data().check(ds, f"measurement_maps() measurement {name!r}")
    # each panel its own axes and colour scale: measurements differ in extent and in units (mm, µm, nm), and linked
    # ranges showed every map on the union of the numbers (most of them as a dot in an empty frame)
    panels = [topography(ds, max_pixels=max_pixels, title=name).opts(axiswise=True) for name, ds in ms.items()]
    return _style(hv.Layout(), common=dict(shared_axes=False),
                  matplotlib=dict(vspace=0.4, sublabel_position=(-0.35, 1.08))).clone(panels).cols(cols)


# --------------------------------------------------------------------------- dispatch

def plot(obj, **kwargs):
    """Plot whatever ``obj`` is: a measurement, an analysis result, a twin average or a contact result.

    ========================================================  ==============================
    object                                                    figure
    ========================================================  ==============================
    twin (DataTree)                                           :func:`twin_figure`
    twin average (Dataset with ``average`` and ``curves``)    :func:`twin_curves`
    contact load curve (``area_fraction`` along ``load``)     :func:`contact_area`
    contact solution (``pressure`` map)                       :func:`contact_maps`
    measurement (Dataset with ``height``), map, profile       :func:`topography`
    curve on ``q``, ``distance`` or ``bandwidth``             :func:`curve`
    2D PSD on ``(q_y, q_x)``                                  :func:`spectrum_map`
    ========================================================  ==============================

    Parameters
    ----------
    obj : xarray.DataTree, xarray.Dataset or xarray.DataArray
        What to plot (see the table).
    **kwargs
        Keyword arguments of the chosen function.

    Returns
    -------
    holoviews object
        Displayed by Jupyter; ``holoviews.save`` writes it to HTML or PNG.
    """
    if isinstance(obj, xr.DataTree):
        return twin_figure(obj, **kwargs)
    if isinstance(obj, xr.Dataset):
        if "average" in obj and "curves" in obj:
            return twin_curves(obj, **kwargs)
        if "area_fraction" in obj and _contact_steps_dim(obj) is not None:
            return contact_area(obj, **kwargs)
        if "pressure" in obj and any(d in obj["pressure"].dims for d in LATERAL_DIMS):
            return contact_maps(obj, **kwargs)
        if "height" in obj:
            return topography(obj, **kwargs)
        raise XtopoError(f"don't know how to plot a Dataset with variables {list(obj.data_vars)}; "
                         "plot one variable (ds[name].topo.plot())")
    if isinstance(obj, xr.DataArray):
        if "q_x" in obj.dims and "q_y" in obj.dims:
            return spectrum_map(obj, **kwargs)
        if any(d in CURVE_COORDS for d in obj.dims):
            return curve(obj, **kwargs)
        if X in obj.dims:
            return topography(obj, **kwargs)
        raise XtopoError(f"don't know how to plot {obj.name!r} with dims {obj.dims}: expected lateral dims "
                         f"(y, x) or a curve coordinate {tuple(CURVE_COORDS)}")
    raise XtopoError(f"plot() needs an xarray object, got {type(obj).__name__}")
