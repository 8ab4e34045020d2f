"""Cache hits against computing, for writeable and frozen measurements (issue 27: hits >= 50x faster).

Usage::

    python benchmarks/bench_cache.py [--size 1024] [--repeats 30]

For each analysis (``scalars``, 1D and isotropic ``psd``, ``acf``) on a ``size``² fractal map:
the compute time (median of ``repeats // 5`` calls, at least 3) and the hit time of a
:class:`xtopo.cache.Cache` look-up (median of ``repeats`` calls after one warm-up hit, the
in-process layer on, as a user's session has it) for a writeable measurement (hashed in full at
every look-up) and a frozen one (:func:`xtopo.cache.freeze`: hashed once), with the spread
(min/median/max, ms) and the ratio compute / hit of the medians. A cold hit (the entry read from
disk and verified: key and content checksum) is listed too. The first line times hashing the
height array alone (XXH3, what a writeable look-up cannot skip) and the ``ceiling`` column is
compute / that time: the ratio a writeable hit would reach with nothing but the hash. ``cpu`` is
the ratio of the median CPU times (process time, all threads): closer to the wall ratio of an idle
machine, since load from other processes stretches the wall time of computing more than of a hit.
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time

import xtopo
from xtopo.analysis.acf import acf
from xtopo.analysis.psd import psd
from xtopo.analysis.scalars import scalars
from xtopo import cache as cache_module
from xtopo.cache import Cache, freeze


def _times(fn, n, cpu=None):
    """Wall times (s) of ``n`` calls of ``fn``; their CPU times (all threads) appended to ``cpu``."""
    out = []
    for _ in range(n):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        out.append(time.perf_counter() - t0)
        if cpu is not None:
            cpu.append(time.process_time() - c0)
    return out


def _fmt(ts):
    ms = sorted(t * 1e3 for t in ts)
    return f"{ms[0]:8.3f} {statistics.median(ms):8.3f} {ms[-1]:8.3f}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=30)
    args = ap.parse_args(argv)
    n = args.size
    ds = xtopo.datasets.fractal_surface((n, n), 1e-5, hurst=0.8, rms_height=1e-7, seed=1)
    frozen = freeze(ds)
    cases = {"scalars": (scalars, {}), "psd 1d": (psd, {}), "psd iso": (psd, {"kind": "iso"}),
             "acf": (acf, {})}
    print(f"cache hits vs compute, {n}x{n} map; load average {os.getloadavg()[0]:.2f}; times in ms (min median max)")
    hashes = _times(lambda: cache_module._hash_array(ds.height.values), args.repeats)
    print(f"XXH3 of the {ds.height.nbytes / 2**20:.0f} MiB height array alone: {_fmt(hashes)} "
          f"({ds.height.nbytes / statistics.median(hashes) / 1e9:.0f} GB/s)")
    print(f"{'analysis':10s} {'data':9s} {'compute':>26s} {'hit':>26s} {'ratio':>7s} {'cpu':>5s} {'ceiling':>7s} {'cold hit':>26s}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, (func, params) in cases.items():
            func(ds, **params)  # warm-up: compiled kernels, FFT plans
            compute_cpu = []
            compute = _times(lambda: func(ds, **params), max(3, args.repeats // 5), compute_cpu)
            for label, data in (("writeable", ds), ("frozen", frozen)):
                cache = Cache(tmp)
                cache(func, data, **params)
                cache(func, data, **params)
                hits_cpu = []
                hits = _times(lambda: cache(func, data, **params), args.repeats, hits_cpu)
                cold = Cache(tmp, memory_bytes=0)

                def cold_hit():
                    cache_module._memory.clear(os.path.abspath(tmp))  # the in-process copies are shared: drop them
                    cold(func, data, **params)

                colds = _times(cold_hit, max(3, args.repeats // 5))
                ratio = statistics.median(compute) / statistics.median(hits)
                cpu = statistics.median(compute_cpu) / statistics.median(hits_cpu)
                ceiling = f"{statistics.median(compute) / statistics.median(hashes):7.0f}" if label == "writeable" else ""
                print(f"{name:10s} {label:9s} {_fmt(compute)} {_fmt(hits)} {ratio:7.0f} {cpu:5.0f} {ceiling:>7s} {_fmt(colds)}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
