import multiprocessing as mp
import os

import numpy as np
import pytest
import xarray as xr

from xtopo.analysis.scalars import scalars
from xtopo.cache import Cache, checksum
from xtopo.datasets import fractal_surface


def test_hit_returns_identical_result_and_skips_compute(tmp_path):
    calls = []

    def counted(ds, **kw):
        calls.append(kw)
        return scalars(ds)

    ds = fractal_surface((64, 64), 1.0, hurst=0.7, seed=1)
    cache = Cache(tmp_path)
    first = cache(counted, ds)
    second = cache(counted, ds)
    assert len(calls) == 1 and cache.hits == 1 and cache.misses == 1
    xr.testing.assert_identical(second, first)


def test_changed_data_or_parameters_recompute(tmp_path):
    cache = Cache(tmp_path)
    ds = fractal_surface((64, 64), 1.0, hurst=0.7, seed=1)
    from xtopo.analysis.distribution import distribution

    a = cache(distribution, ds, kind="height", bins=10)
    b = cache(distribution, ds, kind="height", bins=12)
    assert cache.misses == 2 and a.sizes["bin"] == 10 and b.sizes["bin"] == 12
    changed = ds.copy(deep=True)
    changed["height"][0, 0] += 1e-12
    assert checksum(changed) != checksum(ds)
    cache(distribution, changed, kind="height", bins=10)
    assert cache.misses == 3
    tipped = ds.assign_attrs(tip_radius=1e-3)
    assert checksum(tipped) != checksum(ds)
    cache(distribution, ds, kind="height", bins=10)
    assert cache.hits == 1


def _worker(directory, seed, q):
    ds = fractal_surface((128, 128), 1.0, hurst=0.7, seed=seed)
    out = Cache(directory)(scalars, ds)
    q.put(float(out.Sq))


def test_concurrent_writers_same_key(tmp_path):
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    procs = [ctx.Process(target=_worker, args=(str(tmp_path), 3, q)) for _ in range(4)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
    values = [q.get(timeout=5) for _ in procs]
    assert all(p.exitcode == 0 for p in procs)
    assert len(set(values)) == 1
    files = os.listdir(tmp_path)
    assert len(files) == 1 and files[0].endswith(".nc")  # one entry, no temp files left
    again = Cache(tmp_path)
    res = again(scalars, fractal_surface((128, 128), 1.0, hurst=0.7, seed=3))
    assert again.hits == 1 and float(res.Sq) == values[0]


def test_damaged_entry_is_recomputed(tmp_path):
    cache = Cache(tmp_path)
    ds = fractal_surface((32, 32), 1.0, hurst=0.7)
    cache(scalars, ds)
    with open(cache.path(scalars, ds), "wb") as f:
        f.write(b"garbage")
    res = cache(scalars, ds)
    assert cache.misses == 2 and np.isfinite(float(res.Sq))
