"""ISO 25178-2 areal parameter set: xtopo vs surfalize, side by side in one process.

Usage::

    PYTHONPATH=. python benchmarks/bench_iso.py                 # 2048², 5 repeats
    PYTHONPATH=. python benchmarks/bench_iso.py --sizes 512 2048 --repeats 7

Both packages compute the same 30 parameters of the same nonperiodic random surface
(self-affine, H = 0.8, rolled off at a tenth of the map so that the autocorrelation decays):
Sa Sq Sp Sv Sz Ssk Sku, Sdq Sdr, Sal Str Std, Sk Spk Svk Smr1 Smr2 Sxp Smr(c) Smc(mr)
Sdc, Vmp Vmc Vvv Vvc, Spd Spc S10z S5p S5v with Wolf pruning at 5 % of Sz. "cold" is each
package's first call in this process (numba cache loading, FFT plans, windows); "warm" are
``--repeats`` further calls, run in alternating order, each on a fresh surfalize ``Surface``
(surfalize caches results on the object, which would make repeated calls free) and a fresh
xtopo call (xtopo keeps no results). The table gives min/median/max and the ratio of the
medians (xtopo/surfalize, < 1: xtopo faster) with the machine's load average before and after.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import xtopo  # noqa: F401
from xtopo.datasets import fractal_surface


def xtopo_all(ds):
    return ds.topo.iso25178().compute()


def surfalize_all(z, step):
    import warnings

    import surfalize

    warnings.filterwarnings("ignore", "Str is undefined", RuntimeWarning)

    s = surfalize.Surface(z, step, step)
    return [s.Sa(), s.Sq(), s.Sp(), s.Sv(), s.Sz(), s.Ssk(), s.Sku(), s.Sdq(), s.Sdr(), s.Sal(), s.Str(), s.Std(),
            s.Sk(), s.Spk(), s.Svk(), s.Smr1(), s.Smr2(), s.Sxp(), s.Smr(0.0), s.Smc(10.0), s.Sdc(10.0, 80.0),
            s.Vmp(), s.Vmc(), s.Vvv(), s.Vvc(), s.Spd(), s.Spc(), s.S10z(), s.S5p(), s.S5v()]


def timed(fn):
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def spread(times):
    return f"{min(times):7.3f} {statistics.median(times):7.3f} {max(times):7.3f}"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", type=int, nargs="+", default=[2048])
    p.add_argument("--repeats", type=int, default=5)
    args = p.parse_args(argv)
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    print(f"{'size':>6} {'package':<10} {'cold [s]':>9}   {'warm min / median / max [s]':>27}")
    for n in args.sizes:
        ds = fractal_surface((n, n), (1e-4, 1e-4), hurst=0.8, rms_height=1e-6, long_cutoff=1e-5, periodic=False,
                             seed=1, units="um")
        z = ds.height.values
        z = (z - z.mean())[::-1].copy()  # surfalize: row 0 at the top
        step = float(ds.x[1] - ds.x[0])
        cold = {"xtopo": timed(lambda: xtopo_all(ds)), "surfalize": timed(lambda: surfalize_all(z, step))}
        warm = {"xtopo": [], "surfalize": []}
        for i in range(args.repeats):
            order = ["xtopo", "surfalize"] if i % 2 == 0 else ["surfalize", "xtopo"]
            for name in order:
                fn = (lambda: xtopo_all(ds)) if name == "xtopo" else (lambda: surfalize_all(z, step))
                warm[name].append(timed(fn))
        for name in ("xtopo", "surfalize"):
            print(f"{n:>6} {name:<10} {cold[name]:9.3f}   {spread(warm[name])}")
        ratio = statistics.median(warm["xtopo"]) / statistics.median(warm["surfalize"])
        print(f"{n:>6} {'ratio':<10} {cold['xtopo'] / cold['surfalize']:9.3f}   {'median ratio':>19} {ratio:7.3f}")
    print(f"load average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
