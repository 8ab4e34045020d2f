"""Scale-dependent analyses: xtopo vs SurfaceTopography, side by side in one process.

Usage::

    PYTHONPATH=. python benchmarks/bench_analysis.py   # 1024² (default, about a minute)
    PYTHONPATH=. python benchmarks/bench_analysis.py --sizes 1024 4096 --repeats 3

Both packages analyse the same nonperiodic fractal surface (Hann window where a
window applies, reliability analysis off, comparable log binning). Warm timings are
``--repeats`` runs after one warm-up (median [min–max], s); the table prints the
xtopo/SurfaceTopography ratio of the medians (< 1: xtopo faster) and xtopo's time in
forward+inverse real FFT pairs of the map (the fastest here, one thread). Cold is the first
call in a fresh process, after the package's import and the measurement object are made
from the saved heights: what a user's first analysis pays for lazy imports, FFT plans,
compiled kernels and caches (``--cold-repeats`` processes per package; 0 skips them).
One-shot is the whole bill of such a process after numpy: the package's import, the
measurement made, the first call. A line per size gives numba's own start-up (its import
and the built-ins it registers at the first compiled kernel loaded from its cache, after a
measurement was made), which xtopo's first PSD 1D, VBM or SDRP call pays once per process
(docs/tradeoffs.md).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _timing import fresh_process_seconds, median_time, spread, times  # noqa: E402

SIZE = 1e-6  # side of the map (m)


def cases(ds, st_topo, n):
    dx = SIZE / n
    distances = np.geomspace(dx, n * dx / 2, int(np.ceil(10 * np.log10(n / 2))) + 1)
    nb_1d = int(np.ceil(10 * np.log10(n / 2)))
    return {
        "PSD iso": (lambda: ds.topo.psd("iso", reliable=False),
                    lambda: st_topo.power_spectrum_from_area(window="hann", reliable=False)),
        "PSD 1D": (lambda: ds.topo.psd("1d", nb_points=nb_1d, reliable=False),
                   lambda: st_topo.power_spectrum_from_profile(window="hann", reliable=False)),
        "ACF 1D": (lambda: ds.topo.acf("1d", nb_points=nb_1d, reliable=False),
                   lambda: st_topo.autocorrelation_from_profile(reliable=False)),
        "ACF iso": (lambda: ds.topo.acf("iso", reliable=False),
                    lambda: st_topo.autocorrelation_from_area(reliable=False)),
        "VBM": (lambda: ds.topo.vbm(reliable=False),
                lambda: st_topo.variable_bandwidth_from_area(reliable=False)),
        "SDRP slope": (lambda: ds.topo.sdrp(1, distances=distances, reliable=False),
                       lambda: st_topo.scale_dependent_statistical_property(
                           lambda x, y=None: np.mean(x * x), n=1, distance=distances, reliable=False)),
        "SDRP curv": (lambda: ds.topo.sdrp(2, distances=2 * distances[distances <= n * dx / 4], reliable=False),
                      lambda: st_topo.scale_dependent_statistical_property(
                          lambda x, y=None: np.mean(x * x), n=2, distance=2 * distances[distances <= n * dx / 4],
                          reliable=False)),
    }


def fft_pair(n, repeats):
    """Fastest forward+inverse real FFT pair of an n² map here (scipy.fft or a measured FFTW plan, one thread)."""
    import scipy.fft as sfft

    a = np.random.default_rng(0).random((n, n))
    best = median_time(lambda: sfft.irfft2(sfft.rfft2(a), s=a.shape), repeats)
    try:
        import pyfftw
    except ImportError:
        return best
    r = pyfftw.empty_aligned((n, n), dtype="float64")
    c = pyfftw.empty_aligned((n, n // 2 + 1), dtype="complex128")
    fwd = pyfftw.FFTW(r, c, axes=(0, 1), flags=("FFTW_MEASURE",))
    bwd = pyfftw.FFTW(c, r, axes=(0, 1), direction="FFTW_BACKWARD", flags=("FFTW_MEASURE",))
    r[...] = a
    return min(best, median_time(lambda: (fwd.execute(), bwd.execute()), repeats))


def first_call(package, name, path):
    """Seconds of ``package``'s import, of making the measurement from the heights saved at ``path`` and of its
    first call of analysis ``name``, printed on one line (run in a fresh process, numpy imported)."""
    h = np.load(path)
    ds = st_topo = None
    t0 = time.perf_counter()
    if package == "xtopo":  # each child imports only the package it times
        import xtopo

        t1 = time.perf_counter()
        ds = xtopo.make_measurement(h, spacing=SIZE / h.shape[0], periodic=False)
    else:
        from SurfaceTopography import Topography

        t1 = time.perf_counter()
        st_topo = Topography(h, (SIZE, SIZE), periodic=False)
    call = cases(ds, st_topo, h.shape[0])[name][package != "xtopo"]
    t2 = time.perf_counter()
    call()
    print(t1 - t0, t2 - t1, time.perf_counter() - t2)


def numba_start(path):
    """Seconds of ``import numba`` and of the built-ins numba registers before it loads its first compiled
    function (what loading a cached kernel first pays), in a fresh process where xtopo made a measurement from
    the heights saved at ``path`` (as before a first call)."""
    import xtopo

    xtopo.make_measurement(np.load(path), spacing=1.0, periodic=False)
    t0 = time.perf_counter()
    from numba.core.registry import cpu_target

    cpu_target.target_context.refresh()
    print(time.perf_counter() - t0)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=[1024])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--cold-repeats", type=int, default=3, help="fresh processes per package and analysis")
    p.add_argument("--only", nargs="*", default=None, help="subset of analyses (names as printed)")
    p.add_argument("--no-peer", nargs="*", default=[], help="analyses timed for xtopo only (SDRP: ST takes minutes "
                   "from 1024² on)")
    p.add_argument("--first-call", nargs=3, metavar=("PACKAGE", "ANALYSIS", "HEIGHTS"), help=argparse.SUPPRESS)
    p.add_argument("--numba-start", metavar="HEIGHTS", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.first_call:
        return first_call(*args.first_call)
    if args.numba_start:
        return numba_start(args.numba_start)
    from SurfaceTopography import Topography

    from xtopo.datasets import fractal_surface  # registers the .topo accessor too

    print(f"load average {os.getloadavg()[0]:.2f}; times in s, median [min–max]; cold: first call in a fresh process; "
          "one-shot: import + measurement + first call")
    print(f"{'size':>6} {'analysis':<12} {'xtopo warm':>24} {'ST warm':>24} {'ratio':>6} {'/FFT pair':>9} "
          f"{'xtopo cold':>24} {'ST cold':>24} {'ratio':>6} {'xtopo one-shot':>24} {'ST one-shot':>24} {'ratio':>6}")
    for n in args.sizes:
        pair = fft_pair(n, args.repeats)
        ds = fractal_surface((n, n), (SIZE, SIZE), hurst=0.8, rms_height=1e-8, periodic=False, seed=1)
        st_topo = Topography(ds.height.values.copy(), (SIZE, SIZE), periodic=False)
        with tempfile.TemporaryDirectory() as tmp:
            heights = os.path.join(tmp, "heights.npy")
            np.save(heights, ds.height.values)
            if args.cold_repeats:
                start = [t for (t,) in fresh_process_seconds([__file__, "--numba-start", heights], args.cold_repeats)]
                print(f"{n:>6} numba start-up (import + built-ins registered) after a measurement: {spread(start)}")
            for name, (fx, fs) in cases(ds, st_topo, n).items():
                if args.only and name not in args.only:
                    continue
                peer = name not in args.no_peer
                tx = times(fx, args.repeats)
                ts = times(fs, args.repeats) if peer else [float("nan")]
                runs = {pkg: np.array(fresh_process_seconds([__file__, "--first-call", pkg, name, heights],
                                                            args.cold_repeats))
                        if args.cold_repeats and (pkg == "xtopo" or peer) else np.full((1, 3), np.nan)
                        for pkg in ("xtopo", "ST")}
                cold = {pkg: r[:, 2] for pkg, r in runs.items()}
                shot = {pkg: r.sum(axis=1) for pkg, r in runs.items()}
                ratio = [statistics.median(a) / statistics.median(b)
                         for a, b in ((tx, ts), (cold["xtopo"], cold["ST"]), (shot["xtopo"], shot["ST"]))]
                print(f"{n:>6} {name:<12} {spread(tx):>24} {spread(ts):>24} {ratio[0]:>6.2f} "
                      f"{statistics.median(tx) / pair:>9.2f} {spread(cold['xtopo']):>24} {spread(cold['ST']):>24} "
                      f"{ratio[1]:>6.2f} {spread(shot['xtopo']):>24} {spread(shot['ST']):>24} {ratio[2]:>6.2f}",
                      flush=True)
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
