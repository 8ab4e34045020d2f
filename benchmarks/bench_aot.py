"""What ahead-of-time compiled solver kernels would do to a cold first solve (issue 27: cold ≤ 1.5× warm).

A measurement for a decision, not a feature: xtopo's solver passes are numba JIT kernels
(:mod:`xtopo._kernels.compiled`), loaded from numba's on-disk cache in a fresh process. Loading the first one
initialises numba's typing and lowering registries (0.4-0.5 s here), which sets a floor of about 1.6 on
cold / warm at 1024². This script builds the same kernel functions ahead of time with ``numba.pycc`` (pending
deprecation since numba 0.57; needs a C compiler) into a temporary extension module, for the signatures that
32² periodic and free float64 and float32 solves call, and times in fresh processes, interleaved (``pycc``
compiles with its own options: the kernels' ``fastmath`` flags are dropped and its wrappers hold the GIL, so
this measures the start-up, not a shippable build):

* ``jit``: today's path (numba, kernels from its cache);
* ``aot``: the module ``xtopo._kernels.compiled`` replaced by a stand-in that calls the ahead-of-time
  functions, chosen by the exact argument types (arrays: dtype, dims, layout; scalars: their type); numba is
  never imported unless a call matches no built signature (the row says how many calls fell back).

Each row: cold first solve (scene + solve), warm median [min, max] of ``--repeat`` solves, their ratio, the
iterations and the contact area (equal in both: the same functions, compiled once by each route).

Usage::

    python benchmarks/bench_aot.py                       # periodic 1024 2048, free 512, 2 rounds
    python benchmarks/bench_aot.py --periodic 1024 --free --rounds 3
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
import types

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
MODULE = "xtopo_solver_aot"


def build(directory: str) -> float:
    """Compile the solver kernels' signatures that small solves use into ``directory``; the build time (s)."""
    sys.path.insert(0, ROOT)
    sys.path.insert(0, HERE)
    from numba.pycc import CC

    from bench_contact import MEAN_PRESSURE, surface
    from xtopo._kernels import compiled
    from xtopo.contact import Scene

    for periodic in (True, False):
        for dtype in ("float64", "float32"):
            scene = Scene(surface(32, periodic), dtype=dtype)
            for _ in range(3):  # the third solve plans with measure: every path the solver takes
                scene.solve(mean_pressure=MEAN_PRESSURE, tol=1e-6, maxiter=5000)
    cc = CC(MODULE)
    cc.output_dir = directory
    cc.target_cpu = "host"   # numba JIT compiles for this CPU too
    table = {}
    for name in dir(compiled):
        kernel = getattr(compiled, name)
        if getattr(kernel, "overloads", None):
            for i, result in enumerate(kernel.overloads.values()):
                cc.export(f"{name}_{i}", result.signature)(kernel.py_func)
                table.setdefault(name, []).append(
                    (f"{name}_{i}", [[t.dtype.name, t.ndim, t.layout] if hasattr(t, "ndim") else str(t)
                                     for t in result.signature.args]))
    with open(os.path.join(directory, "table.json"), "w") as f:
        json.dump(table, f)
    t0 = time.perf_counter()
    cc.compile()
    return time.perf_counter() - t0


def _stand_in(directory: str):
    """A module ``xtopo._kernels.compiled`` whose functions call the ahead-of-time ones (the JIT module on a miss)."""
    import numpy as np

    with open(os.path.join(directory, "table.json")) as f:
        table = json.load(f)
    stub = types.ModuleType("xtopo._kernels.compiled")
    stub.fallbacks = 0
    loaded = {}

    def module(kind):
        if kind not in loaded:
            if kind == "aot":
                sys.path.insert(0, directory)
                loaded[kind] = importlib.import_module(MODULE)
            else:
                spec = importlib.util.spec_from_file_location("_jit_kernels",
                                                              os.path.join(ROOT, "xtopo", "_kernels", "compiled.py"))
                loaded[kind] = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(loaded[kind])
        return loaded[kind]

    def typeof(a):
        """What numba's typing makes of an argument: an array's dtype, dims and layout, a scalar's type (a Python
        int is int64, a float float64): a call must match an export exactly (a float passed where an int64 is
        compiled would be truncated, a float32 array read as float64)."""
        if isinstance(a, np.ndarray):
            return (a.dtype.name, a.ndim, "C" if a.flags.c_contiguous else "F" if a.flags.f_contiguous else "A")
        if isinstance(a, (bool, np.bool_)):
            return "bool"
        if isinstance(a, np.generic):
            return a.dtype.name
        return {int: "int64", float: "float64"}.get(type(a))

    def kernel(name, entries):
        wanted = [(export, [tuple(a) if isinstance(a, list) else a for a in args]) for export, args in entries]

        def call(*args):
            got = [typeof(a) for a in args]
            for export, types_ in wanted:
                if types_ == got:
                    return getattr(module("aot"), export)(*args)
            stub.fallbacks += 1
            return getattr(module("jit"), name)(*args)
        return call

    for name, entries in table.items():
        setattr(stub, name, kernel(name, entries))
    stub.__getattr__ = lambda name: getattr(module("jit"), name)   # kernels no small solve called
    return stub


def run(kind: str, n: int, periodic: bool, repeat: int, directory: str) -> dict:
    """Cold first solve and warm ones in this (fresh) process."""
    sys.path.insert(0, ROOT)
    sys.path.insert(0, HERE)
    if kind == "aot":
        sys.modules["xtopo._kernels.compiled"] = _stand_in(directory)
    from bench_contact import MEAN_PRESSURE, surface
    from xtopo.contact import Scene

    ds = surface(n, periodic)
    t0 = time.perf_counter()
    scene = Scene(ds, dtype="float64")
    r = scene.solve(mean_pressure=MEAN_PRESSURE, tol=1e-6, maxiter=5000)
    cold = time.perf_counter() - t0
    warm = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = scene.solve(mean_pressure=MEAN_PRESSURE, tol=1e-6, maxiter=5000)
        warm.append(time.perf_counter() - t0)
    return dict(cold=cold, warm=warm, iterations=int(r.iterations), area=float(r.area_fraction),
                numba="numba" in sys.modules,
                fallbacks=getattr(sys.modules["xtopo._kernels.compiled"], "fallbacks", None))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periodic", type=int, nargs="*", default=[1024, 2048])
    ap.add_argument("--free", type=int, nargs="*", default=[512])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--rounds", type=int, default=2, help="fresh-process pairs (jit, aot) per grid, interleaved")
    ap.add_argument("--case", nargs=5, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.case:
        kind, n, boundary, repeat, directory = args.case
        print(json.dumps(run(kind, int(n), boundary == "periodic", int(repeat), directory)))
        return
    if shutil.which(os.environ.get("CC", "cc")) is None:
        print("no C compiler (cc): numba.pycc cannot build the module; nothing to compare")
        return
    directory = tempfile.mkdtemp(prefix="xtopo-aot-")
    try:
        seconds = subprocess.run([sys.executable, "-c", f"import sys; sys.path.insert(0, {HERE!r}); import bench_aot; "
                                  f"print(bench_aot.build({directory!r}))"], check=True, capture_output=True,
                                 text=True, cwd=ROOT).stdout.split()[-1]
        so = [f for f in os.listdir(directory) if f.startswith(MODULE)][0]
        print(f"built {so} ({os.path.getsize(os.path.join(directory, so)) / 2**20:.1f} MiB) in {float(seconds):.1f} s "
              f"with numba.pycc; load average {os.getloadavg()[0]:.2f}")
        print(f"{'grid':>14} {'kernels':>7} {'cold s':>7} {'warm s (median [min, max])':>27} {'cold/warm':>9} "
              f"{'iters':>5} {'area':>9}  numba imported, fallbacks")
        for boundary, sizes in (("periodic", args.periodic), ("free", args.free)):
            for n in sizes:
                for _ in range(args.rounds):
                    for kind in ("jit", "aot"):
                        out = subprocess.run([sys.executable, __file__, "--case", kind, str(n), boundary,
                                              str(args.repeat), directory], capture_output=True, text=True, cwd=ROOT)
                        lines = [ln for ln in out.stdout.splitlines() if ln.startswith("{")]
                        if not lines:
                            print(f"{boundary} {n} {kind}: failed: {(out.stderr.strip().splitlines() or ['?'])[-1]}")
                            continue
                        r = json.loads(lines[-1])
                        w = statistics.median(r["warm"])
                        print(f"{boundary + ' ' + str(n):>14} {kind:>7} {r['cold']:7.2f} {w:13.2f} "
                              f"[{min(r['warm']):.2f}, {max(r['warm']):.2f}] {r['cold'] / w:9.2f} "
                              f"{r['iterations']:5d} {r['area']:9.6f}  {r['numba']}, {r['fallbacks']}")
        print(f"load average after: {os.getloadavg()[0]:.2f}")
    finally:
        shutil.rmtree(directory, ignore_errors=True)


if __name__ == "__main__":
    main()
