"""A standalone HTML report of a digital surface twin (``xtopo report``).

One file, no network needed to view it (bokeh resources inline): the summary table
of the measurements, the stitched averages of :data:`xtopo.stitching.ANALYSES` (each
measurement coloured, the average thick black) and a map or
profile of every measurement. Maps are block-averaged to ``max_pixels`` per side,
which keeps the report of a 1024² measurement well under 5 MB.
"""

from __future__ import annotations

import datetime
import html
import os
import pathlib
from typing import Annotated

import xarray as xr

from . import plot as _plot
from ._format import format_length
from ._optional import require
from ._progress import progress_bar
from ._version import __version__
from .analysis._iso_sets import format_iso_table, iso_table
from .analysis.reliability import reliability_cutoff
from .conventions import MASK, length_factor
from .errors import XtopoError
from .io.netcdf import atomic_write
from .params import Count, Dict, Flag, Names, Path, Text, checked
from .plot import group_colours
from .preprocess import STEPS
from .stitching import _complete
from .stitching import ANALYSES as _REGISTRY
from .summary import summary_table, table_rows
from .twins import measurements, twin

__all__ = ["report", "ANALYSES"]

#: the stitched analyses a report shows by default (declared in :data:`xtopo.stitching.ANALYSES`)
ANALYSES = tuple(_REGISTRY)

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; max-width: 1340px; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; margin-top: 1.2em; border-bottom: 1px solid #ccc; }
p.meta { color: #666; margin-top: 0; }
div.table { max-width: 100%; overflow-x: auto; }
table.summary { border-collapse: collapse; font-size: 0.85em; }
table.summary th, table.summary td { padding: 0.25em 0.6em; border-bottom: 1px solid #ddd; text-align: left;
  vertical-align: top; }
table.summary td { overflow-wrap: anywhere; max-width: 28em; }
table.summary th { background: #f2f2f2; }
ul.legend { list-style: none; padding: 0; margin: 0.5em 0; display: flex; flex-wrap: wrap; gap: 0.3em 1.2em;
  font-size: 0.9em; }
ul.legend span.swatch { display: inline-block; width: 1.8em; height: 0.35em; vertical-align: middle;
  margin-right: 0.4em; }
p.error { color: #a00; }
"""


def _stitch(tree: xr.DataTree, name: str) -> xr.Dataset:
    """The twin average ``name`` of :data:`xtopo.stitching.ANALYSES`, computed."""
    return _REGISTRY[name](tree).compute()


def _as_twin(source) -> xr.DataTree:
    """A twin as is; one measurement (or one file) as a twin of one."""
    if isinstance(source, xr.Dataset):
        source = {str(source.attrs.get("title") or "measurement"): source}
    elif isinstance(source, (str, os.PathLike)):
        source = [source]
    return twin(source)


def _iso_html(ms: dict, options: dict) -> str:
    """The ISO parameters section (:mod:`xtopo.analysis._iso_sets`), errors per measurement included."""
    table, errors = iso_table(ms, **options)
    cut = ", ".join(f"{k} = {v}" for k, v in options.items() if v is not None) or "no filter, form removed"
    out = f"<h2>ISO parameters</h2><p>{html.escape(cut)}</p>"
    if table.data_vars:
        out += _cells_html(*format_iso_table(table))
    return out + "".join(f'<p class="error">{html.escape(n)}: {html.escape(m)}</p>' for n, m in errors.items())


def _cells_html(header, rows) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f'<div class="table"><table class="summary"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table></div>'


def _preprocessing(ds: xr.Dataset) -> str:
    """What was done to a measurement's heights: its recorded preprocessing steps (``history``) and
    the harmonic fill of missing data the twin averages apply (paper §3.2)."""
    steps = [line.strip() for line in str(ds.attrs.get("history", "")).splitlines()
             if line.strip().split("(")[0].rsplit(".", 1)[-1] in STEPS]
    missing = bool(ds[MASK].any()) if MASK in ds else bool(ds["height"].isnull().any())
    if missing and not any(s.startswith("fill_missing") for s in steps):
        steps.append("missing data filled harmonically for the averages")
    return "; ".join(steps) if steps else "none (heights as read; mean removed in each analysis)"


def _reliability_rows(ms: dict) -> list:
    """Per measurement: preprocessing, short reliability cutoff (paper §4.9) and its cause."""
    causes = {"resolution": "instrument resolution", "tip_radius": "tip radius (eq. 13, c = 1/2)",
              "none": "no resolution or tip radius given"}
    rows = []
    for name, ds in ms.items():
        try:
            cut = reliability_cutoff(_complete(ds, name)).compute()  # on the filled heights, as the averages
            value, method = float(cut.max()), str(cut.attrs.get("method", "none"))
        except XtopoError as exc:
            value, method = float("nan"), f"not available: {exc}"
        units = ds["x"].attrs.get("units", "m")
        cause = causes.get(method, method)
        if method == "tip_radius" and ds.attrs.get("tip_radius") is not None:
            radius = float(ds.attrs["tip_radius"]) * length_factor(ds.attrs.get("tip_radius_units", units), "m")
            cause += f", R = {format_length(radius)}"
        if method == "tip_radius" and value == 0:
            cause += ": the tip limits no scale the data resolve"
        text = format_length(value * length_factor(units, "m")) if value > 0 else "—"
        rows.append([name, str(ds.attrs.get("instrument") or ""), _preprocessing(ds), text, cause])
    return rows


def _legend_html(groups: dict, labels: dict) -> str:
    """One legend for all twin panels: a coloured swatch per instrument group, the average in black."""
    items = [(colour, labels.get(g, g)) for g, colour in group_colours(groups).items()]
    items.append(("#000", "average (band: ± predicted standard error)"))
    return '<ul class="legend">' + "".join(
        f'<li><span class="swatch" style="background:{c}"></span>{html.escape(str(t))}</li>' for c, t in items) + "</ul>"


def _labels(table: xr.Dataset) -> dict:
    """Legend text per measurement: name plus instrument where it says more than the name."""
    out = {}
    for (name, _, size, *_), inst in zip(table_rows(table)[1], map(str, table["instrument"].values)):
        extra = ", ".join(v for v in (inst if inst != name else "", size) if v)
        out[name] = f"{name} ({extra})" if extra else name
    return out


def _html_page(title: str, blocks: list) -> str:
    """One standalone page from HTML snippets (str) and bokeh models, bokeh JS/CSS inline.

    Text and tables are plain HTML (readable without JavaScript); each bokeh model
    gets a ``<div>`` filled by the one embedded script at the end of the page.
    """
    from bokeh.core.validation import silence
    from bokeh.core.validation.warnings import FIXED_SIZING_MODE
    from bokeh.embed import components
    from bokeh.embed.bundle import bundle_for_objs_and_resources
    from bokeh.resources import INLINE

    models = [b for b in blocks if not isinstance(b, str)]
    # HoloViews sizes figures by their frame (frame_width/height), which bokeh's check does not count
    silence(FIXED_SIZING_MODE, True)
    try:
        script, divs = components(models) if models else ("", ())
        js, css = bundle_for_objs_and_resources(models, INLINE) if models else ("", "")  # only the bundles used
    finally:
        silence(FIXED_SIZING_MODE, False)
    divs = iter(divs)
    body = "\n".join(b if isinstance(b, str) else next(divs) for b in blocks)
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n<title>{html.escape(title)}</title>\n'
            f"{css}\n{js}\n<style>{_CSS}</style>\n</head>\n<body>\n{body}\n"
            f"{script}\n</body>\n</html>\n")


@checked
def report(source, path: Annotated[str | None, Path("file path")] = None, *,
           title: Annotated[str | None, Text()] = None, analyses: Annotated[tuple, Names(*ANALYSES)] = ANALYSES,
           max_pixels: Annotated[int, Count(min=2)] = 256, maps: Annotated[bool, Flag()] = True,
           iso: Annotated[dict | None, Dict()] = None,
           progress: Annotated[bool | None, Flag(optional=True)] = False) -> str:
    """Write (or return) a standalone HTML report of a digital surface twin.

    Parameters
    ----------
    source : xarray.DataTree, dict, xarray.Dataset, path or list of paths
        A twin (:func:`xtopo.twin`), measurements by name, one measurement or
        measurement files.
    path : str or os.PathLike, optional
        Where to write the page (atomically). Without it the HTML text is returned.
    title : str, optional
        Page title (default: the twin's ``title``).
    analyses : sequence of str, or one str
        Stitched averages to show, names of :data:`xtopo.stitching.ANALYSES` (default: all;
        ``sdrp`` is the scale-dependent curvature, as in the paper's figure 5). An analysis
        that fails for these data is reported on the page with its error message instead of a plot.
    max_pixels : int
        Largest number of pixels per side of a map in the page.
    maps : bool
        Include one map/profile per measurement.
    iso : dict, optional
        Add a table of the ISO parameters (ISO 21920-2 profiles, and the areal set where it is
        installed) with these options: ``{}`` for the defaults, or ``lambda_s``/``lambda_c``
        (see :func:`xtopo.analysis.iso21920.iso21920`; a bare number is in metres). None: no table.
    progress : bool, optional
        A progress bar over the analyses (None: on a terminal or in a notebook).

    Returns
    -------
    str
        ``path`` when given, else the HTML text.
    """
    hv = require("holoviews", "the report")  # the [plot] extra, loaded on first use (startup time)
    gridplot = require("bokeh.layouts", "the report").gridplot

    tree = _as_twin(source)
    ms = measurements(tree)
    if not ms:
        raise XtopoError("the twin holds no measurements; nothing to report")
    title = title if title is not None else str(tree.attrs.get("title") or "xtopo report")
    table = summary_table(ms)
    labels = _labels(table)
    groups = {n: str(ds.attrs.get("instrument") or n) for n, ds in ms.items()}
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    # the page: sections of HTML snippets and bokeh models, in order (a new section is one more entry)
    sections = [("", [f"<h1>{html.escape(title)}</h1>"
                      f'<p class="meta">{len(ms)} measurement(s) · xtopo {html.escape(__version__)} · {stamp}</p>']),
                ("Measurements", [_cells_html(*table_rows(table))]),
                ("Preprocessing and reliability (paper §3.2, §4.9)",
                 [_cells_html(["measurement", "instrument", "preprocessing", "short reliability cutoff", "cause"],
                              _reliability_rows(ms))])]
    if iso is not None:
        sections.append(("", [_iso_html(ms, iso)]))
    if analyses:
        figures, errors = [], []
        for name in progress_bar(analyses, desc="twin averages", unit="analysis", enabled=progress):
            try:
                stitched = _stitch(tree, name)
            except XtopoError as exc:
                errors.append(f'<p class="error">{html.escape(_REGISTRY[name].title)}: not available — '
                              f"{html.escape(str(exc))}</p>")
                continue
            el = _plot.twin_curves(stitched, groups=groups, title=_REGISTRY[name].title, legend=False)
            figures.append(hv.render(el, backend="bokeh"))
        blocks = ["<p>Thin coloured lines: the individual measurements over their reliable scales; thick black: "
                  "the arithmetic mean with equal weight per measurement at log-spaced collocation points (paper "
                  "§4.10), grey band: its predicted standard error.</p>" + _legend_html(groups, {}) + "".join(errors)]
        if figures:
            blocks.append(gridplot(figures, ncols=2, merge_tools=False, toolbar_location=None))
        sections.append(("Twin averages", blocks))
    if maps:
        panels = [hv.render(_plot.topography(ds, max_pixels=max_pixels, title=labels.get(name, name)),
                            backend="bokeh") for name, ds in ms.items()]
        sections.append(("Topography", [gridplot(panels, ncols=2, merge_tools=False, toolbar_location=None)]))
    blocks = []
    for heading, items in sections:
        blocks += ([f"<h2>{html.escape(heading)}</h2>"] if heading else []) + items
    page = _html_page(title, blocks)
    if path is None:
        return page
    return atomic_write(path, lambda tmp: pathlib.Path(tmp).write_text(page, encoding="utf-8"))
