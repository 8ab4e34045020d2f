"""Twin averages of the example twin, first and second call in one process: ``tw.topo.plot()`` (Figure 5),
the five averages of :data:`xtopo.stitching.ANALYSES` alone, ``twin_psd`` and ``report``, each in fresh processes,
interleaved between checkouts.

Run: ``python benchmarks/bench_twin_averages.py [--repeat 3] [--profile] CHECKOUT [CHECKOUT ...]``
(each CHECKOUT a repository root put first on ``PYTHONPATH``). Printed per checkout and operation: median
[min–max] of the wall and CPU times (s) of the first and the second call. ``--profile``: cProfile of the second
``plot()`` in this process.
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
       "averages": lambda: [a(tw).compute() for a in xtopo.stitching.ANALYSES.values()],
       "report": lambda: report(tw, os.path.join(d, "r.html"))}[op]
ts = []
for _ in range(2):
    t0, c0 = time.perf_counter(), time.process_time(); run()
    ts += [time.perf_counter() - t0, time.process_time() - c0]
print(*ts)
"""


def main():
    p = argparse.ArgumentParser()
    p.add_argument("checkouts", nargs="*")
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--ops", default="plot,averages,twin_psd,report")
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
                res.setdefault((c, op), []).append([float(v) for v in out.stdout.split()[-4:]])
    for (c, op), ts in sorted(res.items(), key=lambda kv: kv[0][1]):
        print(f"{c:24s} {op:9s} wall first {spread([t[0] for t in ts])} second {spread([t[2] for t in ts])}; "
              f"CPU first {spread([t[1] for t in ts])} second {spread([t[3] for t in ts])}")


if __name__ == "__main__":
    main()
