"""Figures render with both HoloViews backends, with units in the axis labels and log axes
where the paper uses them (PSD, ACF, VBM, SDRP, contact area)."""

import importlib

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo import plot as xplot
from xtopo.datasets import fractal_surface
from xtopo.errors import XtopoError
from xtopo.stitching import ANALYSES, average_curves

def _available(module: str, name: str) -> bool:
    """Whether ``module`` provides ``name`` on this branch (analyses/contact are merged from other branches)."""
    try:
        return hasattr(importlib.import_module(module), name)
    except ImportError:
        return False


hv = pytest.importorskip("holoviews")
pytest.importorskip("bokeh")
pytest.importorskip("matplotlib")

BACKENDS = ("bokeh", "matplotlib")


# ----------------------------------------------------------------- synthetic results of the agreed shapes

def _coord(name, values, units, long_name):
    return xr.Variable((name,), np.asarray(values, float), {"units": units, "long_name": long_name})


def psd_like(n=40, cutoff=None, nan_tail=0):
    q = np.geomspace(1e5, 1e9, n)
    c = 1e-30 * (q / 1e5) ** -2.6
    if nan_tail:
        c[-nan_tail:] = np.nan  # lazy reliability masks unreliable points with NaN
    attrs = {"units": "m3", "long_name": "1D power spectral density C1D", "analysis": "psd", "reliable": 0}
    if cutoff is not None:
        attrs.update(reliability_cutoff=cutoff, reliability_cutoff_units="m")
    return xr.DataArray(c, dims="q", coords={"q": _coord("q", q, "m-1", "angular wavevector")}, name="psd",
                        attrs=attrs)


def length_curve(name, coord, units, long_name, n=30):
    d = np.geomspace(1e-9, 1e-5, n)
    v = np.concatenate([[0.0], 1e-8 * (d[1:] / 1e-5) ** 0.8])  # a zero (distance 0) must not break log axes
    return xr.DataArray(v, dims=coord, coords={coord: _coord(coord, d, "m", coord)}, name=name,
                        attrs={"units": units, "long_name": long_name, "analysis": name})


def contact_solution(n=32):
    ds = fractal_surface((n, n), 1e-6, hurst=0.8, rms_height=1e-8, seed=1)
    p = np.clip(ds.height.values / 1e-8, 0, None)
    coords = {"y": ds.y, "x": ds.x}
    dims = ("y", "x")
    return xr.Dataset({
        "pressure": (dims, p, {"units": "E*", "long_name": "contact pressure"}),
        "gap": (dims, np.clip(-ds.height.values, 0, None), {"units": "m", "long_name": "gap between the surfaces"}),
        "displacement": (dims, ds.height.values, {"units": "m", "long_name": "normal displacement"}),
        "contact": (dims, p > 0, {"units": "1", "long_name": "in contact (pressure > 0)"}),
        "load": ((), 1e-14, {"units": "E* m2", "long_name": "normal load"}),
        "mean_pressure": ((), 1e-2, {"units": "E*", "long_name": "mean pressure over the nominal area"}),
        "area_fraction": ((), float((p > 0).mean()), {"units": "1", "long_name": "relative contact area A/A0"}),
        "converged": ((), True, {"units": "1", "long_name": "solver reached tol"}),
    }, coords=coords)


def contact_curve(n=6):
    steps = []
    for k, p in enumerate(np.geomspace(1e-4, 1e-1, n)):
        s = contact_solution(16)
        s["mean_pressure"] = s["mean_pressure"].copy(data=p)
        s["area_fraction"] = s["area_fraction"].copy(data=min(1.0, 3 * p ** 0.9))
        s["converged"] = s["converged"].copy(data=k < n - 2)  # the two highest loads did not converge
        s["load"] = s["load"].copy(data=p * 1e-12)
        steps.append(s.set_coords("load"))
    return xr.concat(steps, dim="load", data_vars="all")


def twin_average():
    rng = np.random.default_rng(0)
    curves = {}
    for name, (lo, hi) in {"afm-5um": (1e6, 1e9), "stylus-5mm": (1e3, 1e6), "optical": (1e4, 1e7)}.items():
        q = np.geomspace(lo, hi, 50)
        c = 1e-20 * (q / 1e3) ** -2.6 * np.exp(0.1 * rng.standard_normal(q.size))
        curves[name] = xr.DataArray(c, dims="q", coords={"q": _coord("q", q, "m-1", "angular wavevector")},
                                    name="psd", attrs={"units": "m3", "long_name": "1D power spectral density C1D"})
    return average_curves(curves)


@pytest.fixture(scope="module")
def area():
    return fractal_surface((64, 48), (2e-6, 1.5e-6), hurst=0.8, rms_height=5e-9, seed=2)


# ----------------------------------------------------------------- helpers reading the rendered figures

def _bokeh_figures(model):
    from bokeh.models import GridPlot, Plot

    if isinstance(model, Plot):
        return [model]
    if isinstance(model, GridPlot):
        return [child[0] for child in model.children if isinstance(child[0], Plot)]
    raise AssertionError(f"unexpected bokeh model {type(model).__name__}")


def axes_of(element, backend):
    """(xlabel, ylabel, xlog, ylog) of every panel of the rendered figure."""
    fig = hv.render(element, backend=backend)
    out = []
    if backend == "bokeh":
        from bokeh.models import LogScale

        for f in _bokeh_figures(fig):
            out.append((f.xaxis[0].axis_label, f.yaxis[0].axis_label, isinstance(f.x_scale, LogScale),
                        isinstance(f.y_scale, LogScale)))
    else:
        import matplotlib.pyplot as plt

        for ax in fig.axes:
            if ax.get_label() == "<colorbar>" or not ax.get_xlabel():
                continue
            out.append((ax.get_xlabel(), ax.get_ylabel(), ax.get_xscale() == "log", ax.get_yscale() == "log"))
        plt.close(fig)
    assert out, "nothing rendered"
    return out


CASES = {
    # name: (builder, expected units in x label, in y label, log-log?)
    "psd": (lambda a: psd_like(), "m⁻¹", "m³", True),
    "psd_masked": (lambda a: psd_like(nan_tail=5), "m⁻¹", "m³", True),
    "acf": (lambda a: length_curve("acf", "distance", "m2", "height-difference ACF"), "(m)", "m²", True),
    "vbm": (lambda a: length_curve("vbm", "bandwidth", "m", "mean tilt-corrected RMS height"), "(m)", "(m)", True),
    "sdrp": (lambda a: length_curve("sdrp", "distance", "m-1", "scale-dependent RMS curvature"), "(m)", "m⁻¹", True),
    "twin": (lambda a: twin_average(), "m⁻¹", "m³", True),
    "contact_area": (lambda a: contact_curve(), "p/E*", "A/A₀", True),
    "map": (lambda a: a, "(µm)", "(µm)", False),
    "profile": (lambda a: a.isel(y=0, drop=True), "(µm)", "height (nm)", False),
    "contact_maps": (lambda a: contact_solution(), "(nm)", "(nm)", False),
}


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("case", list(CASES))
def test_every_plot_renders_with_units_and_log_axes(area, case, backend):
    build, xunit, yunit, loglog = CASES[case]
    obj = build(area)
    element = obj.topo.plot()
    for xlabel, ylabel, xlog, ylog in axes_of(element, backend):
        assert xunit in xlabel, (case, xlabel)
        if case != "contact_maps":  # maps of pressure/contact have their unit on the colour bar
            assert yunit in ylabel, (case, ylabel)
        assert xlog == loglog and ylog == loglog, (case, xlog, ylog)


@pytest.mark.parametrize("backend", BACKENDS)
def test_map_colorbar_carries_height_unit(area, backend):
    fig = hv.render(area.topo.plot(), backend=backend)
    if backend == "bokeh":
        from bokeh.models import ColorBar

        bars = [r for r in fig.right if isinstance(r, ColorBar)]
        assert bars and "nm" in bars[0].title
    else:
        labels = [ax.get_ylabel() for ax in fig.axes]
        assert any("height (nm)" in lab for lab in labels), labels


def test_unreliable_part_is_dashed_and_masked_part_omitted():
    q = psd_like().q.values
    cut = 2 * np.pi / q[30]  # points 31.. are beyond the reliable wavevector
    overlay = xplot.curve(psd_like(cutoff=cut))
    curves = list(overlay)
    assert len(curves) == 2
    solid, dashed = (np.asarray(c.dimension_values(1)) for c in curves)
    assert np.isnan(solid[31:]).all() and np.isfinite(solid[:31]).all()
    assert np.isfinite(dashed[31:]).all() and np.isnan(dashed[:29]).all()
    fig = hv.render(overlay, backend="bokeh")
    dashes = [r.glyph.line_dash for r in fig.renderers]
    assert [] in dashes and any(d for d in dashes)
    # a lazily masked result (NaN) is drawn without those points and without a dashed part
    masked = list(xplot.curve(psd_like(nan_tail=5)))
    assert len(masked) == 1 and np.isnan(masked[0].dimension_values(1)[-5:]).all()


def test_twin_average_is_thick_black_over_coloured_measurements():
    overlay = twin_average().topo.plot(labels={"afm-5um": "afm-5um (AFM, 5 µm)"})
    fig = hv.render(overlay, backend="bokeh")
    glyphs = [r.glyph for r in fig.renderers]
    black = [g for g in glyphs if g.line_color == "black"]
    assert len(black) == 1 and black[0].line_width == 4
    others = {g.line_color for g in glyphs if g.line_color != "black"}
    assert len(others) == 3 and all(g.line_width < 4 for g in glyphs if g.line_color != "black")
    legend = [item.label["value"] for item in fig.legend[0].items]
    assert "average" in legend and "afm-5um (AFM, 5 µm)" in legend and "stylus-5mm" in legend


def test_unconverged_contact_points_are_translucent():
    fig = hv.render(contact_curve().topo.plot(), backend="bokeh")
    from bokeh.models import Scatter

    alphas = sorted(r.glyph.fill_alpha for r in fig.renderers if isinstance(r.glyph, Scatter))
    assert alphas == [0.3, 1.0]
    sizes = {r.glyph.fill_alpha: r.data_source.data for r in fig.renderers if isinstance(r.glyph, Scatter)}
    assert len(next(iter(sizes[0.3].values()))) == 2  # the two unconverged steps


def test_contact_area_overlays_several_results():
    overlay = xplot.contact_area({"smooth sphere": contact_curve(), "rough sphere": contact_curve(4)})
    labels = {el.label for el in overlay}
    assert {"smooth sphere", "rough sphere", "smooth sphere (not converged)"} <= labels


def test_contact_maps_of_a_load_curve_step():
    layout = xplot.contact_maps(contact_curve(), step=0)
    assert len(layout) == 3
    assert "1e-04" in layout[0].opts.get().kwargs["title"] or "0.0001" in layout[0].opts.get().kwargs["title"]


def test_large_map_is_downsampled_before_plotting():
    big = fractal_surface((1024, 1024), 1e-5, hurst=0.8, rms_height=1e-8, seed=3)
    img = big.topo.plot()
    assert img.data[img.vdims[0].name].shape == (512, 512)
    assert img.data[img.vdims[0].name].dtype == np.float32
    small = xplot.downsample(big.height, 100)
    assert max(small.shape) <= 100
    # block means preserve the mean height
    np.testing.assert_allclose(float(small.mean()), float(big.height.isel(x=slice(0, 1020), y=slice(0, 1020)).mean()),
                               atol=1e-12)


def test_dask_map_is_reduced_before_computing(area):
    lazy = area.chunk({"y": 16})
    small = xplot.downsample(xtopo.conventions.height_of(lazy), 16)
    assert small.chunks is not None  # still lazy
    img = lazy.topo.plot(max_pixels=16)
    assert img.data[img.vdims[0].name].shape == (16, 16)  # 64x48 by blocks of 4x3


def test_masked_points_are_blank(area):
    h = area.height.values.copy()
    h[:4, :4] = np.nan
    ds = xtopo.make_measurement(h, spacing=2e-6 / 48, units="m")
    img = ds.topo.plot()
    z = img.data[img.vdims[0].name]
    assert np.isnan(z).sum() == 16


def test_line_and_nonuniform_profiles():
    x = np.sort(np.random.default_rng(0).uniform(0, 1e-6, 300))
    line = xtopo.make_measurement(np.sin(x / 1e-7) * 1e-9, x=x, units="m")
    el = line.topo.plot()
    assert isinstance(el, hv.Curve)
    np.testing.assert_allclose(el.dimension_values(0), x * 1e9)  # shown in nm


def test_spectrum_map_has_log_colour_scale(area):
    q = np.linspace(-1e8, 1e8, 32)
    da = xr.DataArray(np.exp(-np.add.outer(q ** 2, q ** 2) / 1e16), dims=("q_y", "q_x"), name="psd",
                      coords={"q_y": _coord("q_y", q, "m-1", "wavevector y"), "q_x": _coord("q_x", q, "m-1", "wavevector x")},
                      attrs={"units": "m4", "long_name": "2D PSD"})
    fig = hv.render(da.topo.plot(), backend="bokeh")
    from bokeh.models import LogColorMapper

    assert isinstance(fig.renderers[0].glyph.color_mapper, LogColorMapper)
    assert "m⁻¹" in fig.xaxis[0].axis_label


def test_batch_of_curves_gives_one_line_each():
    da = xr.concat([psd_like() * s for s in (1, 2, 3)], dim="sample")
    overlay = da.topo.plot()
    assert len(overlay) == 3


def test_twin_plot_measurements_has_one_panel_per_measurement(area):
    tree = xtopo.twin({"a": area, "b": area.isel(y=0, drop=True)})
    layout = tree.topo.plot_measurements()
    assert len(layout) == 2
    assert axes_of(layout, "bokeh")


def test_twin_maps_keep_their_own_axes_and_colour_scales(area):
    """Measurements differ in extent and units: linked ranges drew each map on the union of the numbers (a 5 mm
    scan shown on 0-1000 beside a µm one, one colour scale for mm and nm heights). On main before the fix: one
    x range, one colour range for both."""
    big = area.assign_coords(x=area.x * 3, y=area.y * 3).assign(height=area.height * 3)
    fig = hv.render(xtopo.twin({"small": area, "big": big}).topo.plot_measurements(), backend="bokeh")
    (small, *_), (large, *_) = fig.children
    assert small.x_range is not large.x_range and small.x_range.end != large.x_range.end
    mappers = [next(r.glyph.color_mapper for r in p.renderers if hasattr(r.glyph, "color_mapper")) for p in (small, large)]
    assert mappers[0].high != mappers[1].high


@pytest.fixture(scope="module")
def figure_5():
    """Figure 5 of a twin of 12 measurements by 3 instruments."""
    ms = {}
    for k, (size, inst) in enumerate([(1e-4, "stylus"), (1e-5, "AFM"), (1e-6, "TEM")]):
        for r in range(4):
            s = fractal_surface((32, 32), size, hurst=0.8, rms_height=size / 100, seed=4 * k + r, periodic=False)
            s.attrs.update(instrument=inst, resolution=size / 16, resolution_units="m")
            ms[f"{inst}-{r}"] = s
    return xtopo.twin(ms).topo.plot()


def test_twin_plot_is_the_papers_figure_5(figure_5):
    """twin.topo.plot() drew 24 topography panels; it draws PSD, ACF, VBM and curvature averages on log-log
    axes with units, thin curves coloured by instrument, the average thick black on top, and one legend
    entry per instrument (12 measurements of 3 instruments: 3 entries, not 12)."""
    layout = figure_5
    assert len(layout) == len(ANALYSES)  # one panel per declared twin analysis, the paper's four first
    panels = axes_of(layout, "bokeh")
    assert [p[2:] for p in panels] == [(True, True)] * len(ANALYSES)
    assert "m⁻¹" in panels[0][0] and "m³" in panels[0][1] and all("(m" in p[0] for p in panels[1:])
    fig = hv.render(layout, backend="bokeh")
    figures = list(_bokeh_figures(fig))
    legends = [item.label["value"] for f in figures for leg in f.legend for item in leg.items]
    assert sorted(legends) == sorted(["stylus", "AFM", "TEM", "average", "average ± standard error"])
    for f in figures:
        lines = [r.glyph for r in f.renderers if type(r.glyph).__name__ == "Line" and r.glyph.line_color == "black"]
        assert len(lines) == 1 and lines[0].line_width == 4
        assert f.renderers[-1].glyph.line_color == "black"  # the average is drawn on top


def test_figure_5_with_matplotlib_has_grey_bands_and_no_overlapping_text(figure_5):
    """With matplotlib the uncertainty bands were light blue (the Area's default facecolor cycle) and panel
    titles overlapped the x labels of the panels above."""
    import matplotlib.colors as mc
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = hv.render(figure_5, backend="matplotlib")
    bands = [c.get_facecolor()[0] for ax in fig.axes for c in ax.collections]
    assert len(bands) == len(ANALYSES) and all(mc.to_hex(c, keep_alpha=True) == "#88888859" for c in bands)
    texts = [t for ax in fig.axes for t in (ax.title, ax.xaxis.label, ax.yaxis.label, *ax.texts) if t.get_text()]
    renderer = FigureCanvasAgg(fig).get_renderer()
    boxes = [t.get_window_extent(renderer) for t in texts]
    plt.close(fig)
    assert not [(texts[i].get_text(), texts[j].get_text()) for i, a in enumerate(boxes) for j, b in enumerate(boxes)
                if i < j and a.overlaps(b)]


@pytest.mark.parametrize("units,label", [("um", "µm"), ("m-1", "m⁻¹"), ("m3", "m³"), ("E* m2", "E* m²"),
                                         ("1", ""), ("nm-2", "nm⁻²")])
def test_unit_label(units, label):
    assert xplot.unit_label(units) == label


def test_unplottable_objects_raise():
    with pytest.raises(XtopoError, match="don't know how to plot"):
        xr.Dataset({"a": ("t", [1.0, 2.0])}).topo.plot()
    with pytest.raises(XtopoError, match="curve coordinate"):
        xr.DataArray([1.0, 2.0], dims="t").topo.plot()
    with pytest.raises(XtopoError, match="select one item"):
        xplot.topography(xr.concat([fractal_surface((8, 8), 1.0, hurst=0.8).height] * 2, dim="sample"))


def test_a_missing_variable_names_those_there_are():
    """A missing variable= raised a bare KeyError."""
    ds = fractal_surface((16, 16), 1.0, hurst=0.8)
    with pytest.raises(XtopoError, match=r"variable='pressure' is not a data variable.*\['height'\]"):
        xplot.topography(ds, variable="pressure")


def test_spectrum_map_needs_a_2d_spectrum():
    """A 1D PSD or a height map raised xarray's "cannot rename 'q_y'" ValueError."""
    for obj in [psd_like(), fractal_surface((8, 8), 1.0, hurst=0.8).height]:
        with pytest.raises(XtopoError, match=r"needs a 2D power spectrum on \(q_y, q_x\)"):
            xplot.spectrum_map(obj)


def test_topography_refuses_bad_options():
    """variable=<list> raised 'unhashable type', variable=<array> 'truth value ambiguous'; title/cmap were
    taken whatever they were (a bad cmap failed only when the figure was rendered)."""
    for kwargs, match in [
        (dict(cmap="notacmap"), "cmap='notacmap' is not a colour map"), (dict(cmap=None), "is not a colour map"),
        (dict(cmap=-1), "is not a colour map"), (dict(cmap=[]), "has no colours"),
    ]:
        with pytest.raises(XtopoError, match=match):
            xplot.topography(fractal_surface((8, 8), 1.0, hurst=0.8), **kwargs)


def test_topography_of_a_single_point_raises():
    """A 1×1 (or one-row) map raised HoloViews' 'Supplied Image bounds do not match' ValueError."""
    for shape in [(1, 1), (1, 8), (8, 1), 1]:
        ds = fractal_surface((8, 8), 1.0, hurst=0.8)
        ds = ds.isel(x=slice(0, 1)) if shape == 1 else ds.isel(y=slice(0, shape[0]), x=slice(0, shape[1]))
        if shape == 1:
            ds = ds.isel(y=0, drop=True)
        with pytest.raises(xtopo.GridError, match="needs at least 2"):
            xplot.topography(ds["height"])


def test_curve_refuses_a_bad_cutoff():
    """cutoff='abc' raised numpy's ValueError, a list a TypeError; -1, 0, NaN and inf were silently ignored."""
    for cutoff in [-1.0, 0, np.nan, np.inf, True, "abc", [1e-7, 2e-7], xr.DataArray([1.0, 2.0])]:
        with pytest.raises(XtopoError, match="cutoff .* must be a positive finite number"):
            xplot.curve(psd_like(), cutoff=cutoff)


def test_curve_cutoff_as_a_dataarray_still_dashes():
    solid_only = xplot.curve(psd_like())
    dashed = xplot.curve(psd_like(), cutoff=xr.DataArray(1e-7))
    assert len(dashed) == len(solid_only) + 1


def test_curve_refuses_bad_options():
    """label=<array> raised 'truth value ambiguous'; color=-1 was taken and failed only when rendered."""
    for kwargs, match in [
        (dict(color=-1), "color must be a colour name"), (dict(color="notacolour"), "color must be a colour name"),
    ]:
        with pytest.raises(XtopoError, match=match):
            xplot.curve(psd_like(), **kwargs)


def test_curve_without_points_raises():
    """An empty curve raised numpy's 'cannot reshape array of size 0'."""
    with pytest.raises(XtopoError, match="no points along 'q'"):
        xplot.curve(psd_like().isel(q=slice(0, 0)))


def test_contact_area_refuses_bad_results():
    """{} gave an empty figure, a list raised "'list' object has no attribute 'items'", {'a': 1} a TypeError."""
    for results, match in [
        ({}, "at least one contact result"), ([contact_solution(8)], "results must be a dict"),
        ({"a": 1}, r"result 'a' needs an xarray Dataset"), (None, "at least one contact result"),
    ]:
        with pytest.raises(XtopoError, match=match):
            xplot.contact_area(results)


def test_contact_maps_refuses_bad_variables():
    """variables=None/3 raised "'int' object is not iterable", [] gave an empty layout."""
    for variables, match in [
        ([], "non-empty list"), (None, "non-empty list"), (3, "non-empty list"), ([np.zeros(2)], "non-empty list of names"),
    ]:
        with pytest.raises(XtopoError, match=match):
            xplot.contact_maps(contact_solution(8), variables=variables)


def test_contact_maps_takes_one_variable_name():
    assert len(xplot.contact_maps(contact_solution(8), variables="gap")) == 1


def test_contact_maps_refuses_a_step_out_of_range():
    """step=6 of 6 steps raised xarray's IndexError, 1.5/'a' a TypeError 'invalid indexer array'."""
    for step in [6, -7, 1.5, "a", None, True]:
        with pytest.raises(XtopoError, match="step must be"):
            xplot.contact_maps(contact_curve(6), step=step)


def test_contact_maps_of_one_solution_has_one_step():
    """A single solution ignored any step."""
    for step in [1, -2]:
        with pytest.raises(XtopoError, match=r"step must be"):
            xplot.contact_maps(contact_solution(8), step=step)


def test_measurement_maps_refuses_what_is_no_twin():
    """A list or a string raised 'dictionary update sequence element' errors, a Dataset was taken as a dict of
    its variables, an empty twin gave an empty layout."""
    for tree, match in [
        ([fractal_surface((8, 8), 1.0, hurst=0.8)], "must be a dict"), ("abc", "must be a dict"),
        (fractal_surface((8, 8), 1.0, hurst=0.8), "must be a dict"), ({}, "at least one measurement"),
        (xr.DataTree(), "at least one measurement"), ({"a": 1}, r"measurement 'a' needs an xarray"),
    ]:
        with pytest.raises(XtopoError, match=match):
            xplot.measurement_maps(tree)


def test_importing_xtopo_does_not_import_holoviews():
    import subprocess
    import sys

    code = "import sys, xtopo; print('holoviews' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# ----------------------------------------------------------------- real analysis results (when on this branch)

@pytest.mark.skipif(not _available("xtopo.analysis.psd", "psd"), reason="xtopo.analysis.psd not on this branch")
@pytest.mark.parametrize("analysis", ["psd", "acf", "vbm", "sdrp"])
def test_real_analysis_results_plot(area, analysis):
    ds = area.assign_attrs(periodic=0)
    result = getattr(importlib.import_module(f"xtopo.analysis.{analysis}"), analysis)(ds)
    for backend in BACKENDS:
        for xlabel, ylabel, xlog, ylog in axes_of(result.topo.plot(), backend):
            assert xlog and ylog
            assert "(m" in xlabel
            assert ("(" in ylabel) == (result.attrs["units"] != "1"), ylabel  # dimensionless slope: no unit


@pytest.mark.skipif(not _available("xtopo.contact", "Scene"), reason="xtopo.contact not on this branch")
def test_real_contact_results_plot():
    from xtopo.contact import Scene

    ds = fractal_surface((32, 32), 1e-6, hurst=0.8, rms_height=1e-8, seed=4)
    scene = Scene(ds, modulus=1.0)
    curve = scene.curve(mean_pressures=[1e-3, 1e-2])
    for backend in BACKENDS:
        assert all(xl and yl for *_, xl, yl in axes_of(curve.topo.plot(), backend))
        assert axes_of(scene.solve(mean_pressure=1e-2).topo.plot(), backend)
