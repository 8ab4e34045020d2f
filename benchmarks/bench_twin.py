"""Twin benchmarks (issue 6): result-cache speedup and a 200-measurement twin on a 2-worker LocalCluster.

Run: ``python benchmarks/bench_twin.py [--measurements 200] [--skip-cluster]``.
Prints medians; the cluster run reports wall time and the peak RSS of each worker
(sampled every 0.2 s while the graph runs).
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import threading
import time

import numpy as np
import xarray as xr

import xtopo
from xtopo.analysis.psd import psd
from xtopo.cache import Cache


def twin_curves(ds):
    """What a twin average needs of one measurement: the four 1D curves, as one Dataset."""
    from xtopo.analysis.acf import acf
    from xtopo.analysis.sdrp import sdrp
    from xtopo.analysis.vbm import vbm

    return xr.merge([psd(ds, kind="1d").rename("psd"), acf(ds, kind="1d").rename("acf").rename({"distance": "lag"}),
                     vbm(ds).rename("vbm"), sdrp(ds).rename("sdrp")], compat="override", combine_attrs="drop")


def bench_cache(repeats: int = 5) -> None:
    """Compute+store vs hit on a 1024² measurement, as a writeable array (hashed on every look-up)
    frozen (:func:`xtopo.cache.freeze`: immutable memory, hashed once) and as a node of a twin
    (``xtopo.twin`` stores measurements frozen)."""
    from xtopo.cache import freeze

    plain = xtopo.datasets.fractal_surface((1024, 1024), 1e-5, hurst=0.8, periodic=False, seed=1)
    node = xtopo.twin({"m": plain})["m"].to_dataset()  # a twin stores its measurements frozen
    for label, func, kw in (("iso PSD", psd, {"kind": "iso"}), ("twin curves (PSD, ACF, VBM, SDRP)", twin_curves, {})):
        func(plain, **kw)  # warm-up (imports, FFT plans)
        for data_label, ds in (("writeable", plain), ("frozen", freeze(plain)), ("twin-node", node)):
            with tempfile.TemporaryDirectory() as d:
                compute, hit = [], []
                for r in range(repeats):
                    cache = Cache(os.path.join(d, str(r)))
                    t = time.perf_counter()
                    a = cache(func, ds, **kw)
                    compute.append(time.perf_counter() - t)
                    t = time.perf_counter()
                    b = cache(func, ds, **kw)
                    hit.append(time.perf_counter() - t)
                    assert cache.hits == 1
                    xr.testing.assert_identical(a.compute(), b)
            mc, mh = statistics.median(compute), statistics.median(hit)
            print(f"cache, 1024² {label}, {data_label} data: compute+store median {mc * 1e3:.1f} ms, "
                  f"hit median {mh * 1e3:.2f} ms, speedup {mc / mh:.0f}x")


def _make_files(directory: str, n: int) -> list[str]:
    rng = np.random.default_rng(0)
    paths = []
    for i in range(n):
        if i % 4 == 3:
            ds = xtopo.datasets.fractal_surface(int(rng.choice([4096, 16384])), 1e-3, hurst=0.8, periodic=False, seed=i)
        else:
            n_px = int(rng.choice([256, 512, 1024]))
            ds = xtopo.datasets.fractal_surface((n_px, n_px), 1e-5, hurst=0.8, periodic=False, seed=i)
        ds.attrs["tip_radius"] = 1e-8
        ds.attrs["tip_radius_units"] = "m"
        paths.append(xtopo.to_netcdf(ds, os.path.join(directory, f"m{i:03d}.nc")))
    return paths


def bench_cluster(n: int) -> None:
    from dask.distributed import Client, LocalCluster

    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        paths = _make_files(d, n)
        print(f"wrote {n} measurement files in {time.perf_counter() - t:.1f} s")
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, memory_limit="4GB") as cluster, \
                Client(cluster) as client:
            peaks: dict[str, int] = {}
            stop = threading.Event()

            def rss():
                import psutil

                return psutil.Process().memory_info().rss

            def sample():
                while not stop.is_set():
                    try:
                        for w, v in client.run(rss).items():
                            peaks[w] = max(peaks.get(w, 0), v)
                    except Exception:
                        pass
                    time.sleep(0.2)

            sampler = threading.Thread(target=sample, daemon=True)
            sampler.start()
            t = time.perf_counter()
            tree = xtopo.twin(paths)
            graph = tree.topo.psd()
            built = time.perf_counter() - t
            result = graph.compute()
            wall = time.perf_counter() - t
            stop.set()
            sampler.join()
        print(f"{n}-measurement twin, 2 workers: graph built in {built:.1f} s, averaged in {wall:.1f} s; "
              f"count max {int(result['count'].max())}")
        for w, v in sorted(peaks.items()):
            print(f"  peak RSS {w}: {v / 2**30:.2f} GiB")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--measurements", type=int, default=200)
    p.add_argument("--skip-cluster", action="store_true")
    args = p.parse_args()
    bench_cache()
    if not args.skip_cluster:
        bench_cluster(args.measurements)


if __name__ == "__main__":
    main()
