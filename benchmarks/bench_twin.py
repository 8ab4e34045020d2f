"""Twin benchmarks (issues 6, 27): result-cache speedup and a twin of many measurements on a LocalCluster.

Run: ``python benchmarks/bench_twin.py [--count 1000] [--workers 2] [--dir DIR] [--serial-sample N]
[--skip-cache] [--skip-cluster]``.

The twin is ``--count`` xtopo NetCDF files (maps of 256²–1024², line scans of 4096 and
16384 points) averaged with ``xtopo.twin(paths).topo.psd()`` on a LocalCluster of
``--workers`` one-thread processes. Printed: the sum of the per-measurement analysis times
(read + 1D PSD, serially in this process: all, or ``--serial-sample`` of them extrapolated),
the cluster's wall time from the paths to the computed average (split into opening the
twin, building the graph and computing it), its ratio to the goal 1.3 × sum / workers,
each worker's peak RSS (``getrusage``: the whole life of the worker, warm-up included), the
load average before and after, and CPU times, which do not depend on the machine's load (the
client's opening and graph building, the client and scheduler while computing, each worker),
with the wall time they imply on free cores. The average is checked: count > 0 at every collocation
point inside the union of the measurements' reliable ranges.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import tempfile
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
    """``n`` measurements as xtopo NetCDF files in ``directory`` (kept there: a rerun reuses them):
    three in four are maps of 256², 512² or 1024² over 10 µm, one in four a line scan of 4096 or 16384 points
    over 1 mm, of one self-affine surface (Hurst 0.8, 100 nm rms over 10 µm) measured with a 10 nm tip."""
    rng = np.random.default_rng(0)
    paths = []
    for i in range(n):
        line = i % 4 == 3
        n_px = int(rng.choice([4096, 16384])) if line else int(rng.choice([256, 512, 1024]))
        path = os.path.join(directory, f"m{i:04d}.nc")
        paths.append(path)
        if os.path.exists(path):
            continue
        size = 1e-3 if line else 1e-5  # one self-affine surface: rms height grows as size**hurst
        ds = xtopo.datasets.fractal_surface(n_px if line else (n_px, n_px), size, hurst=0.8,
                                            rms_height=1e-7 * (size / 1e-5) ** 0.8, periodic=False, seed=i)
        ds.attrs["tip_radius"] = 1e-8
        ds.attrs["tip_radius_units"] = "m"
        xtopo.to_netcdf(ds, path)
    return paths


def _analysis(path):
    """One measurement's analysis, as a user runs it: read the file, its 1D PSD (reliable scales only)."""
    ds = xtopo.open_topography(path)
    return psd(ds, kind="1d", dim="x") if ds["height"].ndim == 2 else psd(ds, kind="1d")


def _serial(paths, sample: int | None) -> tuple[float, str]:
    """Sum of the per-measurement analysis times, in this process, one after the other."""
    _analysis(paths[0])  # warm-up: imports, FFT plans
    chosen = paths if not sample or sample >= len(paths) else paths[:: max(1, len(paths) // sample)][:sample]
    t, cpu = time.perf_counter(), time.process_time()
    for p in chosen:
        _analysis(p)
    spent, cpu = time.perf_counter() - t, time.process_time() - cpu
    if len(chosen) == len(paths):
        return spent, cpu, f"all {len(paths)} measured"
    scale = len(paths) / len(chosen)
    return spent * scale, cpu * scale, f"{len(chosen)} of {len(paths)} measured, extrapolated"


def _worker_peak():
    """Peak RSS of this worker process since it started (bytes), its RSS now and its CPU time (s)."""
    import resource

    import psutil

    cpu = psutil.Process().cpu_times()
    return (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, psutil.Process().memory_info().rss,
            cpu.user + cpu.system)


def _check_counts(result) -> str:
    """Count > 0 at every collocation point inside the union of the measurements' reliable ranges."""
    q = result["q"].values
    inside = np.zeros(q.shape, bool)
    for f in np.isfinite(result["curves"].values):
        if f.any():
            inside |= (q >= q[f].min()) & (q <= q[f].max())
    empty = int((result["count"].values[inside] == 0).sum())
    if empty:
        raise SystemExit(f"twin average has count 0 at {empty} points inside the measurements' reliable ranges")
    return (f"count > 0 at all {int(inside.sum())} points inside the reliable ranges (of {q.size}; "
            f"max count {int(result['count'].max())})")


def bench_cluster(n: int, workers: int, directory: str | None, sample: int | None) -> None:
    from dask.distributed import Client, LocalCluster

    with contextlib.ExitStack() as stack:
        if directory is None:
            directory = stack.enter_context(tempfile.TemporaryDirectory(prefix="xtopo-twin-"))
        os.makedirs(directory, exist_ok=True)
        t = time.perf_counter()
        paths = _make_files(directory, n)
        print(f"{n} measurement files in {directory} ({time.perf_counter() - t:.1f} s to write the missing ones)")
        load0 = os.getloadavg()
        serial, serial_cpu, how = _serial(paths, sample)
        print(f"serial: sum of per-measurement analysis times (read + 1D PSD) {serial:.1f} s, CPU {serial_cpu:.1f} s "
              f"({how}); load average {load0[0]:.1f} before, {os.getloadavg()[0]:.1f} after")
        cluster = stack.enter_context(LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                                   memory_limit="4GB", dashboard_address=":0", silence_logs=50))
        client = stack.enter_context(Client(cluster))
        # warm-up outside the clock: imports and FFT plans in every worker
        xtopo.twin(paths[:2 * workers]).topo.psd().compute()
        base = client.run(_worker_peak)
        load0 = os.getloadavg()
        t, cpu0 = time.perf_counter(), time.process_time()
        tree = xtopo.twin(paths)
        opened = time.perf_counter() - t
        graph = tree.topo.psd()
        built, cpu1 = time.perf_counter() - t, time.process_time()
        n_tasks = len(graph.__dask_graph__())
        result = graph.compute()
        wall, cpu2 = time.perf_counter() - t, time.process_time()
        load1 = os.getloadavg()
        peaks = client.run(_worker_peak)
    goal = 1.3 * serial / workers
    print(f"{n}-measurement twin, {workers} workers: {wall:.1f} s wall (twin opened {opened:.1f} s, graph of "
          f"{n_tasks} tasks built at {built:.1f} s, computed {wall - built:.1f} s); goal 1.3 × {serial:.1f} s / "
          f"{workers} = {goal:.1f} s; wall / goal = {wall / goal:.2f}")
    print(f"  load average {load0[0]:.1f} before, {load1[0]:.1f} after (1-min; {len(os.sched_getaffinity(0))} cores); "
          + _check_counts(result))
    worker_cpu = {w: peaks[w][2] - base[w][2] for w in peaks}
    print(f"  CPU time (load-independent): client opening + graph {cpu1 - cpu0:.1f} s, client and scheduler while "
          f"computing {cpu2 - cpu1:.1f} s, workers {' + '.join(f'{v:.1f}' for v in worker_cpu.values())} s "
          f"(serial analyses {serial_cpu:.1f} s). On free cores: about {cpu1 - cpu0:.1f} + "
          f"{max(worker_cpu.values()):.1f} = {cpu1 - cpu0 + max(worker_cpu.values()):.1f} s, "
          f"{(cpu1 - cpu0 + max(worker_cpu.values())) / (1.3 * serial_cpu / workers):.2f} × the goal in CPU terms")
    for w in sorted(peaks):
        print(f"  worker {w}: peak RSS {peaks[w][0] / 2**20:.0f} MiB (after warm-up {base[w][1] / 2**20:.0f} MiB, "
              f"now {peaks[w][1] / 2**20:.0f} MiB)")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--measurements", "--count", type=int, default=200, dest="count")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--dir", default=None, help="keep the measurement files here (default: a temporary folder)")
    p.add_argument("--serial-sample", type=int, default=None,
                   help="time the serial analyses on this many measurements and extrapolate (default: all)")
    p.add_argument("--skip-cluster", action="store_true")
    p.add_argument("--skip-cache", action="store_true")
    args = p.parse_args()
    if not args.skip_cache:
        bench_cache()
    if not args.skip_cluster:
        bench_cluster(args.count, args.workers, args.dir, args.serial_sample)


if __name__ == "__main__":
    main()
