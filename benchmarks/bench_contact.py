"""Contact mechanics side by side: xtopo vs ContactMechanics vs tamaas (issue 5).

Every case runs in a fresh subprocess (clean timings and peak memory). For each grid the
same seeded fractal surface is solved at the same mean pressure; the area fractions are
printed next to each other, with

* ``ratio``   = xtopo time / fastest peer time (goal ≤ 0.2),
* ``it/fft``  = xtopo time per CG iteration / one forward+inverse real FFT pair on the
  solver's grid (native grid periodic, 2N padded grid free; goal ≤ 1.5); the pair is the
  faster of scipy.fft and a measured FFTW plan (the floor, not the solver's own transforms);
  ``loop`` the same ratio for the iteration loop alone (first to last callback, without the
  per-solve costs: initial pressures, first exact convolution, result Dataset), and
  ``transforms alone`` for the transforms the solver ran, timed in isolation on its own plans
  (:func:`transform_floor`: what the iterations would cost with nothing else in them),
* peak RSS of each process.

Usage::

    python benchmarks/bench_contact.py                    # periodic 256 512 1024, free 256 512
    python benchmarks/bench_contact.py --periodic 256 --free  # quick
    python benchmarks/bench_contact.py --big 4096          # one 4096² free solve: time and peak memory
    python benchmarks/bench_contact.py --big 8192 --boundary periodic
    python benchmarks/bench_contact.py --memory            # bytes per point of a scene set up and solved
    python benchmarks/bench_contact.py --cold --periodic 1024 2048 --free  # first solve vs warm ones, numba floor
    python benchmarks/bench_contact.py --cold --periodic 2048 --free --threads 1 2 2 1  # FFT threads
    python benchmarks/bench_contact.py --cold --new-machine --periodic 1024 --free 512  # + empty numba/FFTW caches

Tolerances: xtopo ``tol`` (largest contact violation / peak-to-valley height); the same
length ``tol·PtV`` is ContactMechanics' ``pentol``; tamaas gets its own relative ``tol``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)
sys.path.insert(0, HERE)

from _timing import median_time  # noqa: E402

MEAN_PRESSURE = 0.005  # p/E*; with an rms slope of 0.1 this gives roughly 10 % contact


def surface(n, periodic):
    from xtopo import datasets

    return datasets.fractal_surface((n, n), 1.0, hurst=0.8, rms_slope=0.1, short_cutoff=4.0 / n, seed=11,
                                    periodic=periodic, units="um")


def peak_rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def fft_pair_time(shape, threads, repeat=7):
    """Fastest forward+inverse real FFT pair on ``shape`` available here (ms-resolution floor).

    Both scipy.fft (pocketfft) and a measured FFTW plan on aligned buffers, with the FFT threads the
    solver uses; the smaller median is the floor the solver is compared with.
    """
    import scipy.fft as sfft

    a = np.random.default_rng(0).random(shape)

    best = median_time(lambda: sfft.irfftn(sfft.rfftn(a, workers=threads), s=shape, workers=threads), repeat)
    try:
        import pyfftw
    except ImportError:
        return best
    r_in = pyfftw.empty_aligned(shape, dtype="float64")
    spec = pyfftw.empty_aligned(shape[:-1] + (shape[-1] // 2 + 1,), dtype="complex128")
    r_out = pyfftw.empty_aligned(shape, dtype="float64")
    fwd = pyfftw.FFTW(r_in, spec, axes=tuple(range(len(shape))), flags=("FFTW_MEASURE",), threads=threads)
    bwd = pyfftw.FFTW(spec, r_out, axes=tuple(range(len(shape))), direction="FFTW_BACKWARD",
                      flags=("FFTW_MEASURE", "FFTW_DESTROY_INPUT"), threads=threads)
    r_in[...] = a
    return min(best, median_time(lambda: (fwd.execute(), bwd.execute()), repeat))


def transform_floor(conv, iterations, exact, repeat=7):
    """Time of the transforms a solve of ``iterations`` ran, per iteration, in isolation (seconds).

    Each iteration transforms in single precision: the search direction forward (its energy by
    Parseval) and the pressure increment forward and back; ``exact`` working-precision
    convolutions refresh the reference (:mod:`xtopo._kernels.pk_solver`).
    """
    single = conv.single_precision()
    rng = np.random.default_rng(0)
    for c in {id(conv): conv, id(single): single}.values():
        c.input[...] = rng.random(conv.shape)

    direction = median_time(lambda: single.energy(single.forward()), repeat)
    increment = median_time(lambda: single.inverse(single.forward()), repeat)
    reference = median_time(lambda: conv.inverse(conv.forward()), repeat)
    return direction + increment + reference * exact / iterations


def run_xtopo(n, periodic, tol, repeat, dtype="float64"):
    from xtopo.contact import Scene

    ds = surface(n, periodic)
    t0 = time.perf_counter()
    scene = Scene(ds, dtype=dtype)
    scene.convolution.input  # Green's function and FFT plans (reported separately as setup)
    setup = time.perf_counter() - t0
    times, loops, r = [], [], None
    for _ in range(repeat):
        stamps = []

        def stamp(i, residual):
            stamps.append(time.perf_counter())
            if n >= 2048:
                progress(i, residual)

        t0 = time.perf_counter()
        r = scene.solve(mean_pressure=MEAN_PRESSURE, tol=tol, maxiter=5000, callback=stamp)
        times.append(time.perf_counter() - t0)
        loops.append(stamps[-1] - stamps[0])
    t, loop = statistics.median(times), statistics.median(loops)
    it = int(r.iterations)
    exact = int(r.attrs["exact_convolutions"])
    pair = fft_pair_time(scene.fft_shape, scene.convolution.workers)
    floor = transform_floor(scene.convolution, it, exact)
    return dict(time=t, setup=setup, area=float(r.area_fraction), iterations=it, converged=bool(r.converged),
                per_iteration=t / it, fft_pair=pair, it_per_fft=t / it / pair, loop_per_fft=loop / it / pair,
                floor_per_fft=floor / pair, convolutions=int(r.attrs["convolutions"]), exact=exact,
                backend=scene.backend, rss=peak_rss_mb())


def progress(it, residual):
    """Progress of a big solve on stderr (every 50 iterations)."""
    if it % 50 == 0:
        print(f"  iteration {it}: residual {residual:.3g}  (RSS {peak_rss_mb():.0f} MB)", file=sys.stderr, flush=True)


def run_contactmechanics(n, periodic, tol, repeat):
    from ContactMechanics import FreeFFTElasticHalfSpace, PeriodicFFTElasticHalfSpace
    from ContactMechanics.Factory import make_system
    from SurfaceTopography import Topography

    h = surface(n, periodic).height.values
    cls = PeriodicFFTElasticHalfSpace if periodic else FreeFFTElasticHalfSpace
    sub = cls((n, n), 1.0, physical_sizes=(1.0, 1.0))
    system = make_system(substrate=sub, surface=Topography(h, physical_sizes=(1.0, 1.0), periodic=periodic))
    pentol = tol * float(h.max() - h.min())
    times, sol = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        sol = system.minimize_proxy(external_force=MEAN_PRESSURE * 1.0, pentol=pentol, maxiter=5000)
        times.append(time.perf_counter() - t0)
    forces = np.asarray(sol.jac)[:n, :n]
    return dict(time=statistics.median(times), area=float(np.count_nonzero(forces)) / n**2,
                iterations=int(sol.nit), converged=bool(sol.success), rss=peak_rss_mb())


def run_tamaas(n, periodic, tol, repeat):
    if not periodic:
        raise RuntimeError("tamaas solves periodic problems only")
    import tamaas as tm

    h = np.ascontiguousarray(surface(n, periodic).height.values)
    times, model = [], None
    for _ in range(repeat):
        model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [1.0, 1.0], [n, n])
        model.E, model.nu = 1.0, 0.0  # E* = E/(1-ν²) = 1
        solver = tm.PolonskyKeerRey(model, h, tol)
        solver.max_iter = 5000
        t0 = time.perf_counter()
        solver.solve(MEAN_PRESSURE)
        times.append(time.perf_counter() - t0)
    traction = np.asarray(model.traction)
    return dict(time=statistics.median(times), area=float(np.count_nonzero(traction > 0)) / n**2,
                iterations=-1, converged=True, rss=peak_rss_mb())


def _status_kb(field):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return 0


def run_memory(n, periodic, tol, repeat, dtype="float64"):
    """Peak memory of one scene set up and solved, over the process's memory before (bytes per point).

    The surface and a 32² warm-up solve (imports, compiled kernels) come first; then the kernel's peak
    RSS mark is reset (``/proc/self/clear_refs``) and the scene is built and solved once (``setup``) and
    again with the first result released (the scene's operators exist). Bytes per measurement point =
    (peak - before) / n².
    Independent of the machine's load.
    """
    from xtopo.contact import Scene

    Scene(surface(32, periodic)).solve(mean_pressure=MEAN_PRESSURE, tol=tol)
    ds = surface(n, periodic)
    import gc

    gc.collect()
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        return {"error": "cannot reset the peak RSS mark (/proc/self/clear_refs)"}
    before = _status_kb("VmRSS")
    t0 = time.perf_counter()
    scene = Scene(ds, dtype=dtype)
    r = scene.solve(mean_pressure=MEAN_PRESSURE, tol=tol, maxiter=5000, callback=progress if n >= 2048 else None)
    cold = time.perf_counter() - t0
    peak = peak_first = _status_kb("VmHWM")
    warm = float("nan")
    if repeat:
        r = None   # the repeat solve is measured on its own (a user keeping both results holds both)
        t0 = time.perf_counter()
        r = scene.solve(mean_pressure=MEAN_PRESSURE, tol=tol, maxiter=5000)
        warm = time.perf_counter() - t0
        peak = _status_kb("VmHWM")
    points = n * n
    return dict(time=warm, cold=cold, area=float(r.area_fraction), iterations=int(r.iterations),
                converged=bool(r.converged), before_mb=before / 1024, peak_mb=peak / 1024,
                bytes_per_point_first=(peak_first - before) * 1024 / points,
                bytes_per_point=(peak - before) * 1024 / points, rss=peak / 1024)


def run_cold(n, periodic, tol, repeat, dtype="float64"):
    """The first solve of a fresh process (scene set up, plans, compiled kernels loaded) beside warm ones.

    Imports and the surface are not counted, but numba (imported by the first solve) is; FFTW wisdom and
    numba's compiled kernels on disk are what a machine that has run xtopo before has (a grid new to the
    wisdom is planned by estimate). ``XTOPO_FFT_THREADS`` in the environment sets the FFT threads.
    """
    from xtopo.contact import Scene

    ds = surface(n, periodic)
    t0 = time.perf_counter()
    scene = Scene(ds, dtype=dtype)
    r = scene.solve(mean_pressure=MEAN_PRESSURE, tol=tol, maxiter=5000)
    cold = time.perf_counter() - t0
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = scene.solve(mean_pressure=MEAN_PRESSURE, tol=tol, maxiter=5000)
        times.append(time.perf_counter() - t0)
    return dict(cold=cold, time=statistics.median(times), min=min(times), max=max(times), iterations=int(r.iterations),
                area=float(r.area_fraction), threads=scene.convolution.workers, rss=peak_rss_mb())


def run_numba_start(n, periodic, tol, repeat, dtype="float64"):
    """What a fresh process spends before its first solve can iterate: ``import numba`` and the solver's compiled
    kernels loaded from numba's cache (a 32² solve of the same boundary loads them; it costs milliseconds itself).
    ``cold / warm`` of a solve cannot fall below ``(warm + start) / warm`` while the kernels are numba's."""
    ds = surface(32, periodic)
    from xtopo.contact import Scene

    scene = Scene(ds, dtype=dtype)
    t0 = time.perf_counter()
    importlib.import_module("numba")
    t1 = time.perf_counter()
    scene.solve(mean_pressure=MEAN_PRESSURE, tol=tol)
    t2 = time.perf_counter()
    return dict(start=t2 - t0, import_numba=t1 - t0)


RUNNERS = {"xtopo": run_xtopo, "ContactMechanics": run_contactmechanics, "tamaas": run_tamaas, "memory": run_memory,
           "cold": run_cold, "numba": run_numba_start}
PACKAGES = ("xtopo", "ContactMechanics", "tamaas")   # the side-by-side table


def case(pkg, n, boundary, tol, repeat, show_progress=False):
    cmd = [sys.executable, __file__, "--case", pkg, str(n), boundary, str(tol), str(repeat)]
    out = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=None if show_progress else subprocess.PIPE, text=True,
                         cwd=ROOT)
    for line in out.stdout.splitlines()[::-1]:
        if line.startswith("{"):
            return json.loads(line)
    return {"error": ((out.stderr or "").strip().splitlines() or ["?"])[-1][:120]}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--periodic", type=int, nargs="*", default=[256, 512, 1024])
    ap.add_argument("--free", type=int, nargs="*", default=[256, 512])
    ap.add_argument("--tol", type=float, default=1e-6)
    ap.add_argument("--peer-tol", type=float, default=None, help="tamaas tolerance (default: --tol)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--big", type=int, default=None,
                    help="one solve of this size only (--boundary): time and peak memory per point")
    ap.add_argument("--boundary", choices=("free", "periodic"), default="free", help="boundary of --big")
    ap.add_argument("--memory", action="store_true",
                    help="peak memory per measurement point of xtopo (setup + solve, over the memory before)")
    ap.add_argument("--cold", action="store_true",
                    help="first solve of a fresh process beside the warm median (--periodic/--free sizes)")
    ap.add_argument("--threads", type=int, nargs="*", default=None,
                    help="with --cold: run each case with these XTOPO_FFT_THREADS, interleaved")
    ap.add_argument("--new-machine", action="store_true",
                    help="with --cold: also run each case with empty numba and xtopo caches (no compiled kernels, no "
                         "FFTW wisdom: a machine's first solve after installing)")
    ap.add_argument("--case", nargs=5, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.case:
        pkg, n, boundary, tol, repeat = args.case
        print(json.dumps(RUNNERS[pkg](int(n), boundary == "periodic", float(tol), int(repeat))))
        return
    if args.cold:
        print(f"fresh process per row: first solve (scene, plans, compiled kernels) vs warm solves "
              f"(median [min, max] of {args.repeat}); tol {args.tol}")
        for boundary, sizes in (("periodic", args.periodic), ("free", args.free)):
            for n in sizes:
                for threads in args.threads or [None]:
                    if threads is not None:
                        os.environ["XTOPO_FFT_THREADS"] = str(threads)
                    for new in (False, True) if args.new_machine else (False,):
                        with tempfile.TemporaryDirectory() as empty:
                            saved = {k: os.environ.get(k) for k in ("NUMBA_CACHE_DIR", "XTOPO_CACHE_DIR")}
                            if new:
                                os.environ.update(NUMBA_CACHE_DIR=empty, XTOPO_CACHE_DIR=empty)
                            r = case("cold", n, boundary, args.tol, args.repeat)
                            for k, v in saved.items():
                                os.environ.pop(k, None) if v is None else os.environ.__setitem__(k, v)
                        if "error" in r:
                            print(f"{boundary} {n}: failed: {r['error']}")
                            continue
                        floor = ""
                        if not new:   # numba's own start, in another fresh process
                            s = case("numba", n, boundary, args.tol, 1)
                            if "error" not in s:
                                floor = (f"; numba start {s['start']:.2f} s (import {s['import_numba']:.2f} s), floor "
                                         f"{(r['time'] + s['start']) / r['time']:.2f}")
                        print(f"{boundary + ' ' + str(n):>14} threads {r['threads']}: cold {r['cold']:7.2f} s, warm "
                              f"{r['time']:7.2f} s [{r['min']:.2f}, {r['max']:.2f}], cold/warm "
                              f"{r['cold'] / r['time']:.2f}, {r['iterations']} iterations"
                              + ("  (empty caches: a new machine)" if new else floor))
        return
    if args.memory:
        print(f"peak memory over the process's memory before, per measurement point (tol {args.tol})")
        for boundary, sizes in (("periodic", args.periodic), ("free", args.free)):
            for n in sizes:
                r = case("memory", n, boundary, args.tol, 1)
                if "error" in r:
                    print(f"{boundary} {n}: failed: {r['error']}")
                    continue
                print(f"{boundary + ' ' + str(n):>14}: {r['bytes_per_point_first']:6.1f} B/point (scene set up and "
                      f"solved once), {r['bytes_per_point']:6.1f} B/point after a second solve; peak "
                      f"{r['peak_mb']:.0f} MB over {r['before_mb']:.0f} MB; {r['iterations']} iterations; cold "
                      f"{r['cold']:.2f} s, warm {r['time']:.2f} s")
        return
    if args.big:
        r = case("memory", args.big, args.boundary, args.tol, 0, show_progress=True)
        print(f"{args.boundary} {args.big}²: {json.dumps(r)}")
        return
    print(f"mean pressure {MEAN_PRESSURE} E*, tol {args.tol}, threads {os.environ.get('XTOPO_FFT_THREADS', '1 (default)')}, "
          f"cpus {os.cpu_count()}")
    head = (f"{'grid':>14} {'package':>16} {'time s':>9} {'area':>9} {'iters':>6} {'conv':>5} {'RSS MB':>8}")
    print(head)
    for boundary, sizes in (("periodic", args.periodic), ("free", args.free)):
        for n in sizes:
            rows = {}
            for pkg in PACKAGES:
                if pkg == "tamaas" and boundary == "free":
                    continue
                tol = args.tol if pkg != "tamaas" or args.peer_tol is None else args.peer_tol
                rows[pkg] = r = case(pkg, n, boundary, tol, args.repeat)
                if "error" in r:
                    print(f"{boundary + ' ' + str(n):>14} {pkg:>16}  failed: {r['error']}")
                    continue
                print(f"{boundary + ' ' + str(n):>14} {pkg:>16} {r['time']:9.3f} {r['area']:9.5f} "
                      f"{r['iterations']:6d} {str(r['converged']):>5} {r['rss']:8.0f}")
            x = rows.get("xtopo", {})
            peers = [r["time"] for p, r in rows.items() if p != "xtopo" and "time" in r]
            if "time" in x:
                ratio = x["time"] / min(peers) if peers else float("nan")
                dareas = [abs(r["area"] - x["area"]) for p, r in rows.items() if p != "xtopo" and "area" in r]
                print(f"{'':>14} (a) xtopo/fastest peer = {ratio:.3f}   (b) time per iteration / fastest rFFT "
                      f"pair = {x['it_per_fft']:.2f} [loop {x['loop_per_fft']:.2f}, its transforms alone "
                      f"{x['floor_per_fft']:.2f}] ({x['convolutions']} convolutions, {x['exact']} of them exact, in "
                      f"{x['iterations']} iterations, {x['backend']}; pair {1e3 * x['fft_pair']:.2f} ms; "
                      f"setup {x['setup']:.2f} s)   max |Δarea| vs peers = {max(dareas) if dareas else float('nan'):.2e}")


if __name__ == "__main__":
    main()
