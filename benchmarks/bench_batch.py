"""Scaling of a 64-run batch on 1 and 2 Dask worker processes; per-task overhead vs. solve time.

Usage (from the repository root)::

    python benchmarks/bench_batch.py                    # FFT-bound stand-in workload
    python benchmarks/bench_batch.py --solver contact   # the real contact solver (xtopo.contact)

The batch is 16 measurements × 4 loads in chunks of one item (64 chunks), on a
``LocalCluster(n_workers=k, threads_per_worker=1, processes=True)`` with one FFT
thread per task, run twice in the same clusters, alternately: one chunk per task
(``XTOPO_BATCH_TASK_SECONDS=0``, as before issue 27) and packed (several chunks per
task, the default). Reported (medians over ``--repeat`` runs, min/median/max of the walls):

* ``serial``: the 64 items one after the other in this process (pure solve time), with
  the BLAS/OpenMP thread limits dask gives its workers (``OMP/OPENBLAS/MKL_NUM_THREADS=1``);
* ``1 worker`` / ``2 workers``: wall time of :func:`xtopo.batch.run` on the cluster
  (warm: the workers have imported everything before the clock starts);
* speedup = t(1 worker) / t(2 workers) (goal ≥ 1.7 on 2 free cores), next to the machine's
  ceiling at that moment: the same work in 1 vs 2 plain processes without Dask (on a shared
  machine the other core may simply not be free);
* per-item overhead = (t(1 worker) − the items' own compute time, ``func`` called directly) / 64,
  also as a fraction of an item, and (t(1 worker) − Σ in-task time from the task stream) / 64,
  the part outside the tasks (scheduling, transfers), which does not depend on the serial run
  being timed under the same machine load.
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

    # the items' own compute time: func called directly, one item after the other (no batch, no Dask)
    import xarray as xr

    items = [(ds if isinstance(ds, xr.Dataset) else xtopo.open_topography(ds), load)
             for ds in (ms.values() if isinstance(ms, dict) else ms) for load in loads]
    pure = []
    for _ in range(args.repeat):
        t = time.perf_counter()
        for ds, load in items:
            func(ds, [load])
        pure.append(time.perf_counter() - t)
    t_pure = statistics.median(pure)

    # one chunk per task (packing off, as before issue 27) and packed tasks, alternately in the same clusters
    modes = {"one chunk a task": "0", "packed": None}
    walls, in_task = {}, {}
    for n in (1, 2):
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                          silence_logs=50) as cluster, Client(cluster) as client:
            batch.run(func, dict(list(ms.items())[:n]) if isinstance(ms, dict) else ms[:n], loads[:1],
                      client=client, progress=False)  # warm-up: imports in every worker
            times, computes = {m: [] for m in modes}, {m: [] for m in modes}
            for r in range(args.repeat):
                from distributed import get_task_stream

                for mode, env in modes.items():
                    if env is None:
                        os.environ.pop("XTOPO_BATCH_TASK_SECONDS", None)
                    else:
                        os.environ["XTOPO_BATCH_TASK_SECONDS"] = env
                    with get_task_stream(client) as ts:
                        t = time.perf_counter()
                        res = batch.run(func, ms, loads, chunks=chunks, client=client, progress=False)
                        times[mode].append(time.perf_counter() - t)
                    computes[mode].append(sum(ss["stop"] - ss["start"] for rec in ts.data
                                              for ss in rec["startstops"] if ss["action"] == "compute"))
                    if res.attrs["n_failed"]:
                        raise SystemExit(f"failures: {res.attrs['failed_items']}")
            os.environ.pop("XTOPO_BATCH_TASK_SECONDS", None)
            for mode in modes:
                walls[n, mode] = (min(times[mode]), statistics.median(times[mode]), max(times[mode]))
                in_task[n, mode] = statistics.median(computes[mode])

    ceiling = _ceiling(func, ms, loads, chunks)
    per_task = t_serial / n_tasks
    print(f"workload: {args.solver}, {args.size}² grid, {n_tasks} items (16 measurements × {len(loads)} loads, "
          f"chunks of one item), {'files' if args.to_files else 'in-memory Datasets'}, "
          f"cpus={len(os.sched_getaffinity(0))}, load average {os.getloadavg()[0]:.1f}")
    print(f"items' own compute (func called directly): {t_pure:7.2f} s ({t_pure / n_tasks * 1e3:.1f} ms per item)")
    print(f"serial batch (sync scheduler):            {t_serial:7.2f} s   ({per_task * 1e3:.1f} ms per item)")
    for mode in modes:
        w1, w2 = walls[1, mode], walls[2, mode]
        print(f"{mode}: 1 worker {w1[0]:.2f}/{w1[1]:.2f}/{w1[2]:.2f} s, 2 workers {w2[0]:.2f}/{w2[1]:.2f}/{w2[2]:.2f} s"
              " (min/median/max)")
        overhead = (w1[1] - t_pure) / n_tasks
        print(f"  per-item overhead on 1 worker (wall - items' own compute) / items: {overhead * 1e3:.1f} ms = "
              f"{100 * overhead / (t_pure / n_tasks):.0f} % of an item; in-task time per item "
              f"{in_task[1, mode] / n_tasks * 1e3:.1f} ms; outside the tasks (wall - in-task) / items "
              f"{(w1[1] - in_task[1, mode]) / n_tasks * 1e3:.1f} ms")
        print(f"  speedup 1 → 2 workers: {w1[1] / w2[1]:.2f}×  (machine ceiling now {ceiling:.2f}×: the same work "
              "in 1 vs 2 plain processes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
