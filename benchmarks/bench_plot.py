"""Figure 5 of the example twin and its report, side by side for source trees (e.g. before/after a change).

Run: ``python benchmarks/bench_plot.py [--repeat 3] TREE [TREE ...]`` (each TREE a checkout of xtopo; default: this one).

Each run is a fresh process per tree (trees interleaved) that times, after a warm-up call of each:
``twin.topo.plot()`` (:func:`xtopo.plot.twin_figure`: the twin's analyses and the figure), the figure alone
(``twin_figure`` with the analyses computed beforehand) and :func:`xtopo.report.report`. Printed: median
[min–max] of the runs, in seconds, and the load average before and after.
"""

from __future__ import annotations

import argparse
import os

from _timing import fresh_process_seconds, spread

CHILD = """
import tempfile, time
import holoviews as hv, xtopo
from xtopo import plot as P
from xtopo.datasets import example_twin
from xtopo.preprocess import fill_missing
from xtopo.report import report
hv.extension("bokeh", inline=True)
tree = example_twin()
twin = xtopo.twin({n: fill_missing(ds) if "mask" in ds else ds for n, ds in tree.topo.measurements().items()},
                  name="t")

class Computed:  # an analysis of ANALYSES whose result is computed beforehand
    def __init__(self, analysis):
        self.title, self.result = analysis.title, analysis(twin).compute()
    def __call__(self, tree, **kwargs):
        return self.result

computed = {a: Computed(f) for a, f in P.ANALYSES.items()}
def figure_alone():
    analyses, P.ANALYSES = P.ANALYSES, computed
    try:
        P.twin_figure(twin)
    finally:
        P.ANALYSES = analyses
directory = tempfile.TemporaryDirectory()
path = directory.name + "/report.html"
out = []
for fn in (lambda: twin.topo.plot(), figure_alone, lambda: report(twin, path)):
    fn()
    t = time.perf_counter()
    fn()
    out.append(time.perf_counter() - t)
print(*out)
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("trees", nargs="*", default=[os.path.dirname(os.path.dirname(os.path.abspath(__file__)))])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    print("load average before:", os.getloadavg())
    runs = {tree: [] for tree in args.trees}
    for _ in range(args.repeat):
        for tree in args.trees:
            os.environ["PYTHONPATH"] = os.path.abspath(tree)
            runs[tree] += fresh_process_seconds(["-c", CHILD], 1)
    for tree, rows in runs.items():
        plot, alone, rep = zip(*rows)
        print(f"{tree}: twin.topo.plot() {spread(plot)} s, figure alone {spread(alone)} s, report {spread(rep)} s")
    print("load average after:", os.getloadavg())


if __name__ == "__main__":
    main()
