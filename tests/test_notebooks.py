"""The notebooks in notebooks/ execute top to bottom (nbclient) without errors and show their figures.

Nothing here asserts wall time (a loaded machine took 148 s for a notebook that takes 20 s idle):
the cell timeout is only a hang guard.

A notebook is skipped only when a module it needs is not part of this checkout (the
analyses, contact mechanics and batch modules are developed on separate branches).
"""

import importlib
import os
import pathlib

import pytest

nbformat = pytest.importorskip("nbformat")
nbclient = pytest.importorskip("nbclient")
pytest.importorskip("ipykernel")

REPO = pathlib.Path(__file__).resolve().parents[1]
NOTEBOOKS = REPO / "notebooks"
#: seconds per cell before nbclient gives up: a hang guard, not a speed test (notebooks take 5-20 s
#: in all on an idle 2-core machine)
HANG_GUARD = 900

#: notebook → (module, attribute) pairs it needs
NEEDS = {
    "01-quickstart": [("xtopo.analysis.psd", "psd")],
    "02-digital-twin": [("xtopo.analysis.psd", "psd"), ("xtopo.analysis.reliability", "reliability_cutoff"),
                        ("xtopo.preprocess", "fill_missing")],
    "03-contact": [("xtopo.contact", "Scene")],
    "04-dask-cluster": [("xtopo.batch", "run"), ("xtopo.contact", "Scene")],
    "05-real-files": [("xtopo.contact", "Scene"), ("xtopo.preprocess", "fill_missing")],
}
#: notebooks that read the shared real instrument files (skipped without them)
REAL_FILES = {"05-real-files"}
REAL_DATA = REPO.parent / "shared" / "data" / "real"


def _missing(needs):
    out = []
    for module, name in needs:
        try:
            ok = hasattr(importlib.import_module(module), name)
        except ImportError:
            ok = False
        if not ok:
            out.append(f"{module}.{name}")
    return out


def test_every_notebook_is_listed_and_stripped():
    found = sorted(p.stem for p in NOTEBOOKS.glob("*.ipynb"))
    assert found == sorted(NEEDS)
    for path in NOTEBOOKS.glob("*.ipynb"):
        nb = nbformat.read(path, as_version=4)
        for cell in nb.cells:
            if cell.cell_type == "code":
                assert not cell.outputs and cell.execution_count is None, f"{path.name}: outputs not stripped"


@pytest.mark.parametrize("name", sorted(NEEDS))
def test_notebook_executes(name, tmp_path, monkeypatch):
    missing = _missing(NEEDS[name])
    if missing:
        pytest.skip(f"{name} needs {', '.join(missing)}, not on this branch")
    if name in REAL_FILES and not REAL_DATA.is_dir():
        pytest.skip(f"{name} reads the real instrument files, not present in {REAL_DATA}")
    monkeypatch.setenv("XTOPO_REAL_DATA", str(REAL_DATA))
    # the kernel imports xtopo from this checkout, not from an installed copy
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    monkeypatch.setenv("XTOPO_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(NOTEBOOKS / f"{name}.ipynb", as_version=4)
    client = nbclient.NotebookClient(nb, timeout=HANG_GUARD, kernel_name="python3",
                                     resources={"metadata": {"path": str(tmp_path)}})
    client.execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors
    # every plotting cell produced a rich (HTML/JS) display, i.e. the figures rendered in the kernel
    shown = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs
             if o.output_type in ("display_data", "execute_result") and
             any(k in o.get("data", {}) for k in ("text/html", "application/vnd.holoviews_load.v0+json",
                                                  "application/vnd.holoviews_exec.v0+json"))]
    assert shown, f"{name} displayed no figure"


_COUNTS = {"two": 2, "three": 3, "four": 4, "five": 5, "six": 6}


def test_twin_notebook_text_matches_the_example_twin():
    """What 02-digital-twin says of the example twin: how many measurements, which have missing data."""
    import re

    from xtopo.datasets import example_twin

    nb = nbformat.read(NOTEBOOKS / "02-digital-twin.ipynb", as_version=4)
    text = " ".join(c.source for c in nb.cells if c.cell_type == "markdown")
    tree = example_twin()
    n = re.search(r"campaign of (\d+) simulated measurements", text)
    assert n and int(n[1]) == len(tree.children)
    m = re.search(r"(\w+) scans have missing points \(the optical map and the three 5 µm AFM maps\)", text)
    assert m, "the notebook no longer says which scans have missing points; update this test"
    masked = sorted(name for name, node in tree.children.items() if "mask" in node and bool(node["mask"].any()))
    assert _COUNTS[m[1].lower()] == len(masked)
    assert masked == sorted(["optical-1mm", "afm-5um", "afm-5um-2", "afm-5um-3"])


def test_bokeh_figures_embed_their_resources():
    """Exported notebooks were blank offline: BokehJS came from a CDN. Every notebook that loads the bokeh
    extension embeds it (issue 26)."""
    for path in sorted(NOTEBOOKS.glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        for cell in nb.cells:
            if cell.cell_type == "code" and "hv.extension(" in cell.source:
                assert "inline=True" in cell.source, f"{path.name}: hv.extension without inline=True"


def test_inline_extension_output_needs_no_network(tmp_path, monkeypatch):
    """The extension cell's output carries BokehJS itself, no <script src=https://cdn...>."""
    pytest.importorskip("holoviews")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell('import holoviews as hv\n'
                                                                   'hv.extension("bokeh", inline=True)')])
    nbclient.NotebookClient(nb, timeout=HANG_GUARD, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    text = "".join(str(o.get("data", {})) for o in nb.cells[0].outputs)
    assert "Bokeh" in text and len(text) > 500_000  # BokehJS (~1 MB) is in the page
    assert "cdn.bokeh.org" not in text
