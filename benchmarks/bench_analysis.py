"""Scale-dependent analyses: xtopo vs SurfaceTopography, side by side in one process.

Usage::

    PYTHONPATH=. python benchmarks/bench_analysis.py   # 1024² (default, about a minute)
    PYTHONPATH=. python benchmarks/bench_analysis.py --sizes 1024 4096 --repeats 3

Both packages analyse the same nonperiodic fractal surface (Hann window where a
window applies, reliability analysis off, comparable log binning). Each timing is
the median of ``--repeats`` runs after one warm-up; the table prints the
xtopo/SurfaceTopography time ratio (< 1: xtopo faster).
"""

from __future__ import annotations

import argparse
import os
import sys

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
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=[1024])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--only", nargs="*", default=None, help="subset of analyses (names as printed)")
    args = p.parse_args(argv)
    from SurfaceTopography import Topography

    print(f"{'size':>6} {'analysis':<12} {'xtopo [s]':>10} {'ST [s]':>10} {'ratio':>7}")
    for n in args.sizes:
        ds = fractal_surface((n, n), (1e-6, 1e-6), hurst=0.8, rms_height=1e-8, periodic=False, seed=1)
        st_topo = Topography(ds.height.values.copy(), (1e-6, 1e-6), periodic=False)
        for name, (fx, fs) in cases(ds, st_topo, n).items():
            if args.only and name not in args.only:
                continue
            tx = median_time(fx, args.repeats)
            ts = median_time(fs, args.repeats)
            print(f"{n:>6} {name:<12} {tx:>10.4f} {ts:>10.4f} {tx / ts:>7.2f}", flush=True)


if __name__ == "__main__":
    main()
