"""Scale-dependent analyses: xtopo vs SurfaceTopography, side by side in one process.

Usage::

    PYTHONPATH=. python benchmarks/bench_analysis.py   # 1024² (default, about a minute)
    PYTHONPATH=. python benchmarks/bench_analysis.py --sizes 1024 4096 --repeats 3

Both packages analyse the same nonperiodic fractal surface (Hann window where a
window applies, reliability analysis off, comparable log binning). Each timing is
the median of ``--repeats`` runs after one warm-up; the table prints the
xtopo/SurfaceTopography time ratio (< 1: xtopo faster), xtopo's time in forward+inverse
real FFT pairs of the map (the fastest here, one thread) and xtopo's first call in this
process (the warm-up: plans, compiled kernels, caches; the first analysis of the run also pays
the imports it triggers).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

import xtopo  # noqa: F401
from xtopo.datasets import fractal_surface

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _timing import median_time  # noqa: E402


def cases(ds, st_topo, n):
    dx = float(ds.x[1] - ds.x[0])
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


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=[1024])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--only", nargs="*", default=None, help="subset of analyses (names as printed)")
    p.add_argument("--no-peer", nargs="*", default=[], help="analyses timed for xtopo only (SDRP: ST takes minutes "
                   "from 1024² on)")
    args = p.parse_args(argv)
    from SurfaceTopography import Topography

    print(f"{'size':>6} {'analysis':<12} {'xtopo [s]':>10} {'ST [s]':>10} {'ratio':>7} {'xtopo/FFT pair':>14} "
          f"{'first call [s]':>14}")
    for n in args.sizes:
        pair = fft_pair(n, args.repeats)
        ds = fractal_surface((n, n), (1e-6, 1e-6), hurst=0.8, rms_height=1e-8, periodic=False, seed=1)
        st_topo = Topography(ds.height.values.copy(), (1e-6, 1e-6), periodic=False)
        for name, (fx, fs) in cases(ds, st_topo, n).items():
            if args.only and name not in args.only:
                continue
            t0 = time.perf_counter()
            fx()
            first = time.perf_counter() - t0
            tx = median_time(fx, args.repeats)
            ts = float("nan") if name in args.no_peer else median_time(fs, args.repeats)
            print(f"{n:>6} {name:<12} {tx:>10.4f} {ts:>10.4f} {tx / ts:>7.2f} {tx / pair:>14.2f} {first:>14.4f}",
                  flush=True)


if __name__ == "__main__":
    main()
