"""Whether two source trees draw the same figures: bokeh document JSON and matplotlib pixels, per figure.

Run: ``python benchmarks/compare_figures.py TREE_A TREE_B`` (checkouts of xtopo, e.g. before/after a change to
xtopo/plot.py). Each tree renders, in a fresh process, Figure 5 of the example twin, a twin average without legend,
a multi-curve PSD with dashed unreliable scales, contact areas, a height map and the twin's measurement maps:
with bokeh (the document JSON, its model ids renumbered in order of appearance) and with matplotlib (PNG).
Printed: identical or DIFFERENT per file, then ALL IDENTICAL or DIFFERENCES.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile

CHILD = """
import json, re, sys
import numpy as np, xarray as xr, holoviews as hv, xtopo
from bokeh.embed import json_item
from xtopo import plot as P
from xtopo.datasets import example_twin
from xtopo.preprocess import fill_missing
hv.extension("bokeh", inline=True)
tree = example_twin()
twin = xtopo.twin({n: fill_missing(ds) if "mask" in ds else ds for n, ds in tree.topo.measurements().items()},
                  name="t")
psd = P.ANALYSES["psd"](twin).compute()
contact = {"a": xr.Dataset({"mean_pressure": ("load", [1e-3, 1e-2, 1e-1], {"units": "E*"}),
                            "area_fraction": ("load", [0.01, 0.05, 0.3]), "converged": ("load", [True, True, False])}),
           "b": xr.Dataset({"mean_pressure": ("load", [2e-3, 2e-2], {"units": "E*"}),
                            "area_fraction": ("load", [0.02, 0.1])})}
figures = {"twin_figure": twin.topo.plot(), "twin_curves": P.twin_curves(psd, legend=False),
           "curve": P.curve(psd["curves"].rename(measurement="m"), cutoff=float(2 * np.pi / np.nanmedian(psd["q"]))),
           "contact_area": P.contact_area(contact, labels={"a": "rough"}),
           "topography": P.topography(next(iter(twin.topo.measurements().values()))),
           "measurement_maps": P.measurement_maps(twin)}
for name, fig in figures.items():
    ids = {}
    doc = json.dumps(json_item(hv.render(fig, backend="bokeh"))["doc"], sort_keys=True)
    doc = re.sub(r'"(p\\d+)"', lambda m: '"%s"' % ids.setdefault(m.group(1), f"ID{len(ids)}"), doc)
    open(f"{sys.argv[1]}/{name}.json", "w").write(doc)
    hv.save(fig, f"{sys.argv[1]}/{name}.png", backend="matplotlib")
"""


def main() -> None:
    import matplotlib.image
    import numpy as np

    trees = sys.argv[1:3]
    with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b:
        for tree, out in zip(trees, (a, b)):
            # in the tree: ``python -c`` puts its working directory before PYTHONPATH on sys.path
            subprocess.run([sys.executable, "-c", CHILD, out], check=True, capture_output=True,
                           cwd=os.path.abspath(tree), env=dict(os.environ, PYTHONPATH=os.path.abspath(tree)))
        same = {}
        for f in sorted(os.listdir(a)):
            pa, pb = os.path.join(a, f), os.path.join(b, f)
            if f.endswith(".png"):
                same[f] = np.array_equal(matplotlib.image.imread(pa), matplotlib.image.imread(pb))
            else:
                same[f] = open(pa, "rb").read() == open(pb, "rb").read()
            print(f, "identical" if same[f] else "DIFFERENT")
    print("ALL IDENTICAL" if same and all(same.values()) else "DIFFERENCES")


if __name__ == "__main__":
    main()
