"""A standalone HTML report of a digital surface twin (``xtopo report``).

One file, no network needed to view it (bokeh resources inline): the summary table
of the measurements, the stitched averages (PSD, ACF, VBM, scale-dependent
curvature; each measurement coloured, the average thick black) and a map or
profile of every measurement. Maps are block-averaged to ``max_pixels`` per side,
which keeps the report of a 1024² measurement well under 5 MB.
"""

from __future__ import annotations

import datetime
import html
import os

import xarray as xr

from ._checks import flag, mapping, option
from .errors import XtopoError

__all__ = ["report", "ANALYSES"]

#: the stitched analyses a report shows by default
ANALYSES = ("psd", "acf", "vbm", "sdrp")

_TITLES = {
    "psd": "power spectral density (1D)",
    "acf": "height-difference autocorrelation",
    "vbm": "variable-bandwidth RMS height",
    "sdrp": "scale-dependent RMS curvature",
}

_CSS = """
body { font-family: system-ui, sans-serif; margin: 1.5em; color: #222; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.25em; margin-top: 1.2em; border-bottom: 1px solid #ccc; }
p.meta { color: #666; margin-top: 0; }
table.summary { border-collapse: collapse; font-size: 0.9em; }
table.summary th, table.summary td { padding: 0.25em 0.7em; border-bottom: 1px solid #ddd; text-align: left; }
table.summary th { background: #f2f2f2; }
p.error { color: #a00; }
"""


def _stitch(tree: xr.DataTree, name: str) -> xr.Dataset:
    from . import stitching

    if name == "psd":
        return stitching.twin_psd(tree)
    if name == "acf":
        return stitching.twin_acf(tree)
    if name == "vbm":
        return stitching.twin_vbm(tree)
    if name == "sdrp":
        return stitching.twin_sdrp(tree, 2)
    raise XtopoError(f"unknown analysis {name!r} for the report; choose from {ANALYSES}")


def _analyses(analyses) -> tuple:
    """``analyses`` as a tuple of names from :data:`ANALYSES` (one name may be given as a str)."""
    if isinstance(analyses, str):
        analyses = (analyses,)
    try:
        analyses = tuple(analyses)
    except TypeError:
        raise XtopoError(f"analyses must be a sequence of names from {ANALYSES}, got {analyses!r}") from None
    return tuple(option(a, ANALYSES, "analyses") for a in analyses)


def _as_twin(source) -> xr.DataTree:
    from .twins import twin

    if isinstance(source, xr.DataTree):
        return source
    if isinstance(source, xr.Dataset):
        return twin({str(source.attrs.get("title") or "measurement"): source})
    if isinstance(source, (str, os.PathLike)):
        source = [source]
    return twin(source)


def _table_html(table: xr.Dataset) -> str:
    from .summary import table_rows

    return _cells_html(*table_rows(table))


def _iso_html(ms: dict, options: dict) -> str:
    """The ISO parameters section (:mod:`xtopo.analysis._iso_sets`), errors per measurement included."""
    from .analysis._iso_sets import format_iso_table, iso_table

    table, errors = iso_table(ms, **options)
    cut = ", ".join(f"{k} = {v}" for k, v in options.items() if v is not None) or "no filter, form removed"
    out = f"<h2>ISO parameters</h2><p>{html.escape(cut)}</p>"
    if table.data_vars:
        out += _cells_html(*format_iso_table(table))
    return out + "".join(f'<p class="error">{html.escape(n)}: {html.escape(m)}</p>' for n, m in errors.items())


def _cells_html(header, rows) -> str:
    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>" for r in rows)
    return f'<table class="summary"><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>'


def _labels(table: xr.Dataset) -> dict:
    """Legend text per measurement: name plus instrument where it says more than the name."""
    from .summary import table_rows

    _, rows = table_rows(table)
    out = {}
    for i, row in enumerate(rows):
        name = row[0]
        inst = str(table["instrument"].values[i])
        extra = ", ".join(v for v in (inst if inst and inst != name else "", row[2]) if v)
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


def report(source, path=None, *, title: str | None = None, analyses=ANALYSES, max_pixels: int = 256,
           maps: bool = True, iso: dict | None = None) -> str:
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
    analyses : sequence of {"psd", "acf", "vbm", "sdrp"}, or one of them
        Stitched averages to show (``sdrp`` is the scale-dependent curvature, as in
        the paper's figure 5). An analysis that fails for these data is reported
        on the page with its error message instead of a plot.
    max_pixels : int
        Largest number of pixels per side of a map in the page.
    maps : bool
        Include one map/profile per measurement.
    iso : dict, optional
        Add a table of the ISO parameters (ISO 21920-2 profiles, and the areal set where it is
        installed) with these options: ``{}`` for the defaults, or ``lambda_s``/``lambda_c``
        (see :func:`xtopo.analysis.iso21920.iso21920`; a bare number is in metres). None: no table.

    Returns
    -------
    str
        ``path`` when given, else the HTML text.
    """
    import holoviews as hv
    from bokeh.layouts import gridplot

    from . import plot as _plot
    from ._version import __version__
    from .summary import summary_table
    from .twins import measurements

    analyses = _analyses(analyses)
    maps = flag(maps, "maps")
    tree = _as_twin(source)
    ms = measurements(tree)
    if not ms:
        raise XtopoError("the twin holds no measurements; nothing to report")
    title = str(title) if title is not None else str(tree.attrs.get("title") or "xtopo report")
    table = summary_table(ms)
    labels = _labels(table)
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    blocks = [f"<h1>{html.escape(title)}</h1>"
              f'<p class="meta">{len(ms)} measurement(s) · xtopo {html.escape(__version__)} · {stamp}</p>',
              "<h2>Measurements</h2>" + _table_html(table)]
    if iso is not None:
        blocks.append(_iso_html(ms, mapping(iso, "iso")))
    figures, errors = [], []
    for name in analyses:
        try:
            stitched = _stitch(tree, name)
        except XtopoError as exc:
            errors.append(f'<p class="error">{html.escape(_TITLES.get(name, name))}: not available — '
                          f"{html.escape(str(exc))}</p>")
            continue
        el = _plot.twin_curves(stitched, labels=labels, title=_TITLES[name])
        figures.append(hv.render(el, backend="bokeh"))
    if analyses:
        blocks.append("<h2>Twin averages</h2><p>Coloured: individual measurements over their reliable scales; "
                      "black: the average at common collocation points.</p>" + "".join(errors))
        if figures:
            blocks.append(gridplot(figures, ncols=2, merge_tools=False, toolbar_location=None))
    if maps:
        panels = [hv.render(_plot.topography(ds, max_pixels=max_pixels, title=labels.get(name, name)),
                            backend="bokeh") for name, ds in ms.items()]
        blocks += ["<h2>Topography</h2>", gridplot(panels, ncols=3, merge_tools=False, toolbar_location=None)]
    page = _html_page(title, blocks)
    if path is None:
        return page
    from .io.netcdf import atomic_write

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(page)

    return atomic_write(path, write)
