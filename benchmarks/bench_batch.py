"""Scaling of a 64-run batch on 1 and 2 Dask worker processes; per-task overhead vs. solve time.

Usage (from the repository root)::

    python benchmarks/bench_batch.py                    # FFT-bound stand-in workload
    python benchmarks/bench_batch.py --solver contact   # the real contact solver (xtopo.contact)

The batch is 16 measurements × 4 loads, one item per task (64 tasks), on a
``LocalCluster(n_workers=k, threads_per_worker=1, processes=True)`` with one FFT
thread per task. Reported (medians over ``--repeat`` runs):

* ``serial``: the 64 items one after the other in this process (pure solve time), with
  the BLAS/OpenMP thread limits dask gives its workers (``OMP/OPENBLAS/MKL_NUM_THREADS=1``);
* ``1 worker`` / ``2 workers``: wall time of :func:`xtopo.batch.run` on the cluster
  (warm: the workers have imported everything before the clock starts);
* speedup = t(1 worker) / t(2 workers) (goal ≥ 1.7 on 2 free cores), next to the machine's
  ceiling at that moment: the same work in 1 vs 2 plain processes without Dask (on a shared
  machine the other core may simply not be free);
* per-task overhead = (t(1 worker) − serial) / 64, also as a fraction of the mean solve time,
  and (t(1 worker) − Σ in-worker compute time from the task stream) / 64, which does not
  depend on the serial run being timed under the same machine load.
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import sys
import tempfile
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, REPO)
# Same thread settings in this process (the serial reference) as dask's nanny gives its workers:
# threaded BLAS inside np.dot of a solver loop made the serial contact run ~10x slower on a busy machine.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import xtopo  # noqa: E402
from xtopo import batch  # noqa: E402
from xtopo.datasets import fractal_surface  # noqa: E402


def _workload(args):
    loads = [0.05, 0.1, 0.2, 0.4]
    if args.solver == "contact":
        from xtopo.batch import _contact_item

        loads = [l * 0.02 for l in loads]  # mean pressures 1e-3 … 8e-3 E* (unit area): a few % in contact
        return functools.partial(_contact_item, control="load", scene={"modulus": 1.0}, solve={}, maps=False), loads
    from tests._batch_work import fft_work

    return functools.partial(fft_work, iterations=args.iterations), loads


def _plain(func, ms, loads, chunks):
    """The batch (or a part of it) run serially in a fresh process: for the machine's ceiling."""
    t = time.perf_counter()
    batch.run(func, ms, loads, chunks=chunks, scheduler="sync", progress=False)
    return time.perf_counter() - t


def _ceiling(func, ms, loads, chunks):
    """What 2 processes can gain on this machine now, without Dask: t(1 process, all) / t(2 processes, halves)."""
    from concurrent.futures import ProcessPoolExecutor

    items = list(ms.items()) if isinstance(ms, dict) else list(ms)
    halves = [dict(items[:len(items) // 2]), dict(items[len(items) // 2:])] if isinstance(ms, dict) else \
        [items[:len(items) // 2], items[len(items) // 2:]]
    with ProcessPoolExecutor(2) as pool:
        pool.submit(_plain, func, halves[0], loads[:1], chunks).result()  # warm-up
        t = time.perf_counter()
        pool.submit(_plain, func, ms, loads, chunks).result()
        one = time.perf_counter() - t
        t = time.perf_counter()
        list(pool.map(_plain, [func, func], halves, [loads, loads], [chunks, chunks]))
        two = time.perf_counter() - t
    return one / two


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--solver", choices=("fft", "contact"), default="fft")
    ap.add_argument("--size", type=int, default=128, help="grid points per side (default %(default)s)")
    ap.add_argument("--iterations", type=int, default=60, help="FFT pairs per load in the stand-in workload")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--to-files", action="store_true", help="pass file paths (read in the workers)")
    args = ap.parse_args(argv)

    from distributed import Client, LocalCluster

    func, loads = _workload(args)
    ms = {f"s{i}": fractal_surface((args.size, args.size), 1.0, hurst=0.8, rms_slope=0.1, seed=i, periodic=True)
          for i in range(16)}
    tmp = tempfile.mkdtemp(prefix="xtopo-bench-batch-")
    if args.to_files:
        paths = []
        for name, ds in ms.items():
            paths.append(os.path.join(tmp, name + ".nc"))
            xtopo.to_netcdf(ds, paths[-1])
        ms = paths
    n_tasks = 16 * len(loads)
    chunks = {"measurement": 1, "load": 1}

    os.environ["XTOPO_FFT_THREADS"] = "1"
    serial = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        batch.run(func, ms, loads, chunks=chunks, scheduler="sync", progress=False)
        serial.append(time.perf_counter() - t)
    t_serial = statistics.median(serial)

    walls, in_task = {}, {}
    for n in (1, 2):
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                          silence_logs=50) as cluster, Client(cluster) as client:
            batch.run(func, dict(list(ms.items())[:n]) if isinstance(ms, dict) else ms[:n], loads[:1],
                      client=client, progress=False)  # warm-up: imports in every worker
            times, computes = [], []
            for r in range(args.repeat):
                from distributed import get_task_stream

                with get_task_stream(client) as ts:
                    t = time.perf_counter()
                    res = batch.run(func, ms, loads, chunks=chunks, client=client, progress=False)
                    times.append(time.perf_counter() - t)
                computes.append(sum(ss["stop"] - ss["start"] for rec in ts.data for ss in rec["startstops"]
                                    if ss["action"] == "compute"))
                if res.attrs["n_failed"]:
                    raise SystemExit(f"failures: {res.attrs['failed_items']}")
            walls[n] = statistics.median(times)
            in_task[n] = statistics.median(computes)

    ceiling = _ceiling(func, ms, loads, chunks)
    per_task = t_serial / n_tasks
    overhead = (walls[1] - t_serial) / n_tasks
    solve_1 = in_task[1] / n_tasks
    overhead_1 = (walls[1] - in_task[1]) / n_tasks
    print(f"workload: {args.solver}, {args.size}² grid, {n_tasks} tasks (16 measurements × {len(loads)} loads), "
          f"{'files' if args.to_files else 'in-memory Datasets'}, cpus={len(os.sched_getaffinity(0))}, "
          f"load average {os.getloadavg()[0]:.1f}")
    print(f"serial (in process):  {t_serial:7.2f} s   ({per_task * 1e3:.1f} ms per task)")
    print(f"1 worker process:     {walls[1]:7.2f} s")
    print(f"2 worker processes:   {walls[2]:7.2f} s")
    print(f"in-worker solve time per task: {in_task[1] / n_tasks * 1e3:.1f} ms (1 worker), "
          f"{in_task[2] / n_tasks * 1e3:.1f} ms (2 workers; longer = the workers did not get a free core each)")
    print(f"speedup 1 → 2 workers: {walls[1] / walls[2]:.2f}×  (goal ≥ 1.7× on 2 free cores)")
    print(f"machine ceiling now:   {ceiling:.2f}×  (the same work in 1 vs 2 plain processes, no Dask); "
          f"parallel efficiency of the batch relative to it: {100 * walls[1] / walls[2] / ceiling:.0f} %")
    print(f"per-task overhead vs serial run:      {overhead * 1e3:.1f} ms = {100 * overhead / per_task:.1f} % "
          "of the serial solve time")
    print(f"per-task overhead vs in-worker solve: {overhead_1 * 1e3:.1f} ms = {100 * overhead_1 / solve_1:.1f} % "
          f"of the in-worker solve time ({solve_1 * 1e3:.1f} ms, 1 worker; task stream)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
