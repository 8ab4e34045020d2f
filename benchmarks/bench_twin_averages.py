"""Twin averages of the example twin, first and second call in one process: ``tw.topo.plot()`` (Figure 5),
``twin_psd`` and ``report``, each in fresh processes, interleaved between checkouts.

Run: ``python benchmarks/bench_twin_averages.py [--repeat 3] [--profile] CHECKOUT [CHECKOUT ...]``
(each CHECKOUT a repository root put first on ``PYTHONPATH``). Printed per checkout and operation: median
[min–max] of the first and the second call (s). ``--profile``: cProfile of the second ``plot()`` in this process.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _timing import spread  # noqa: E402

_CHILD = """
import sys, time, tempfile, os
import xtopo
from xtopo.report import report
from xtopo.stitching import twin_psd
tw = xtopo.datasets.example_twin()
op = sys.argv[1]
d = tempfile.mkdtemp()
run = {"plot": lambda: tw.topo.plot(), "twin_psd": lambda: twin_psd(tw),
       "report": lambda: report(tw, os.path.join(d, "r.html"))}[op]
ts = []
for _ in range(2):
    t0 = time.perf_counter(); run(); ts.append(time.perf_counter() - t0)
print(xtopo.__file__, file=sys.stderr)
print(*ts)
"""


def main():
    p = argparse.ArgumentParser()
    p.add_argument("checkouts", nargs="*")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--ops", default="plot,twin_psd,report")
    p.add_argument("--profile", action="store_true")
    a = p.parse_args()
    if a.profile:
        import cProfile
        import pstats

        import xtopo
        tw = xtopo.datasets.example_twin()
        tw.topo.plot()
        pr = cProfile.Profile()
        pr.runcall(tw.topo.plot)
        pstats.Stats(pr).sort_stats("cumulative").print_stats(30)
        return
    res = {}
    for _ in range(a.repeat):
        for op in a.ops.split(","):
            for c in a.checkouts:
                env = {**os.environ, "PYTHONPATH": os.path.abspath(c), "XTOPO_CACHE_DIR": tempfile.mkdtemp()}
                out = subprocess.run([sys.executable, "-c", _CHILD, op], env=env, check=True, capture_output=True,
                                     text=True, cwd=tempfile.gettempdir())
                res.setdefault((c, op), []).append([float(v) for v in out.stdout.split()[-2:]])
    for (c, op), ts in res.items():
        print(f"{c:30s} {op:9s} first {spread([t[0] for t in ts])}  second {spread([t[1] for t in ts])}")


if __name__ == "__main__":
    main()
