"""Twin averages of file-backed measurements on a distributed cluster (issue 27: a thousand measurements).

Each measurement's analysis runs as one task (:func:`xtopo._one_task.one_task`) that reads its
file in the worker; the average must equal the one computed in memory.
"""

from __future__ import annotations

import dask
import dask.array as dsa
import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo._one_task import one_task
from xtopo.datasets import fractal_surface

ANALYSES = {"psd": {}, "acf": {}, "vbm": {}, "sdrp": {"order": 2}}


def _files(tmp_path):
    """Maps and line scans of one surface (overlapping reliable ranges), one map with missing data."""
    paths = []
    for i, (shape, size) in enumerate([((64, 64), 1e-5), ((128, 128), 1e-5), (1024, 1e-3), ((96, 96), 1e-5),
                                       (2048, 1e-3)]):
        s = fractal_surface(shape, size, hurst=0.8, rms_height=1e-7 * (size / 1e-5) ** 0.8, periodic=False, seed=i)
        s.attrs.update(tip_radius=1e-8, tip_radius_units="m")
        if i == 3:
            s["height"][5:9, 10:20] = np.nan   # filled in the worker (preprocess.fill_missing)
        paths.append(xtopo.to_netcdf(s, tmp_path / f"m{i}.nc"))
    return paths


def _in_memory(tree):
    return xtopo.twin({k: v.to_dataset().load() for k, v in tree.children.items()})


def _count_covers_reliable_ranges(avg, coord):
    """count > 0 at every collocation point inside some measurement's reliable range."""
    x = avg[coord].values
    inside = np.zeros(x.shape, bool)
    for f in np.isfinite(avg["curves"].values):
        if f.any():
            inside |= (x >= x[f].min()) & (x <= x[f].max())
    assert inside.any() and (avg["count"].values[inside] > 0).all()


def test_one_measurement_one_task(tmp_path):
    """The per-measurement graph of a file-backed twin is one task per measurement (it was dozens, and the
    averaging step's rechunk grew with the square of the number of measurements)."""
    paths = _files(tmp_path)
    five, two = (len(dict(dask.optimize(xtopo.twin(p).topo.psd())[0].__dask_graph__())) for p in (paths, paths[:2]))
    # a handful of tasks per measurement: the one task, the collocation and the mask of points left out
    assert (five - two) / 3 < 16


def test_one_task_keeps_values_and_laziness():
    a = xr.DataArray(dsa.arange(6.0, chunks=2), dims="q", coords={"q": np.arange(6.0)}, name="c", attrs={"units": "m"})
    a = a.assign_coords(cut=xr.DataArray(dsa.from_array(np.float64(2.5)), attrs={"units": "m"}))
    out, none = one_task(a * 2, None)
    assert none is None and isinstance(out.data, dsa.Array) and isinstance(out["cut"].data, dsa.Array)
    with dask.config.set(scheduler="sync"):
        xr.testing.assert_identical(out.compute(), (a * 2).compute())
    plain = xr.DataArray(np.ones(3), dims="q")
    assert one_task(plain)[0] is plain


@pytest.mark.slow
def test_cluster_average_equals_in_memory_one(tmp_path):
    """All four twin averages of file-backed measurements, computed on a 2-worker LocalCluster (the files are
    read in the workers), equal those of the same measurements in memory; their counts cover every reliable
    range."""
    distributed = pytest.importorskip("distributed")
    tree = xtopo.twin(_files(tmp_path))
    eager = _in_memory(tree)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  silence_logs=50) as cl, distributed.Client(cl, set_as_default=False) as client:
        lazy = {name: getattr(tree.topo, name)(**kw) for name, kw in ANALYSES.items()}
        computed = dict(zip(lazy, client.compute(list(lazy.values()), sync=True)))
    for name, kw in ANALYSES.items():
        want = getattr(eager.topo, name)(**kw)
        got = computed[name]
        for var in ("average", "count", "curves", "uncertainty", "reliability_cutoff"):
            xr.testing.assert_allclose(got[var], want[var], rtol=1e-10)
        _count_covers_reliable_ranges(got, got["average"].dims[0])
