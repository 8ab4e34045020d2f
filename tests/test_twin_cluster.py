"""Twin averages of file-backed measurements on a distributed cluster (issue 27: a thousand measurements).

Each measurement's analysis runs as one task (:func:`xtopo._one_task.one_task`) that reads its
file in the worker, with the coordinates of a lazy graph built once per shape; the average must
equal the one computed in memory.
"""

from __future__ import annotations

import dask
import dask.array as dsa
import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo._one_task import one_task, template
from xtopo.datasets import fractal_surface

ANALYSES = {"psd": {}, "acf": {}, "vbm": {}, "sdrp": {"order": 2}}


def _files(tmp_path):
    """Maps and line scans of one surface (overlapping reliable ranges), one map with missing data, two
    replicates (the same shape: one lazy graph gives the coordinates of both)."""
    paths = []
    for i, (shape, size) in enumerate([((64, 64), 1e-5), ((128, 128), 1e-5), (1024, 1e-3), ((96, 96), 1e-5),
                                       (2048, 1e-3), ((128, 128), 1e-5)]):
        s = fractal_surface(shape, size, hurst=0.8, rms_height=1e-7 * (size / 1e-5) ** 0.8, periodic=False, seed=i)
        s.attrs.update(tip_radius=1e-8, tip_radius_units="m")
        if i == 3:
            s["height"][5:9, 10:20] = np.nan   # filled in the worker (preprocess.fill_missing)
        paths.append(xtopo.to_netcdf(s, tmp_path / f"m{i}.nc"))
    return paths


def _in_memory(tree):
    # .compute(), not .load(): load() would read the lazy twin's own variables into memory in place
    return xtopo.twin({k: v.to_dataset().compute() for k, v in tree.children.items()})


def _count_covers_reliable_ranges(avg, coord):
    """count > 0 at every collocation point inside some measurement's reliable range."""
    x = avg[coord].values
    inside = np.zeros(x.shape, bool)
    for f in np.isfinite(avg["curves"].values):
        if f.any():
            inside |= (x >= x[f].min()) & (x <= x[f].max())
    assert inside.any() and (avg["count"].values[inside] > 0).all()


def test_one_measurement_one_task(tmp_path):
    """The per-measurement graph of a file-backed twin is a few tasks per measurement (it was dozens, and the
    averaging step's rechunk grew with the square of the number of measurements)."""
    paths = _files(tmp_path)
    six, two = (len(dict(dask.optimize(xtopo.twin(p).topo.psd())[0].__dask_graph__())) for p in (paths, paths[:2]))
    # the one task, its three outputs (curve, cutoff, criterion) and the collocation (values, errors, reach) in one step
    assert (six - two) / 4 <= 7


def test_lazy_replicates_equal_in_memory_ones(tmp_path):
    """Lazy measurements of the same shape share the coordinates of one lazy graph; each keeps its own values,
    cutoff and (pooled) errors: the lazy averages equal the in-memory ones."""
    tree = xtopo.twin(_files(tmp_path))
    eager = _in_memory(tree)
    for name, kw in ANALYSES.items():
        lazy = getattr(tree.topo, name)(**kw)
        assert isinstance(lazy["average"].data, dsa.Array)
        with dask.config.set(scheduler="sync"):
            got, want = lazy.compute(), getattr(eager.topo, name)(**kw)
        for var in ("average", "count", "uncertainty", "curves", "curve_error", "left_out", "reliability_cutoff"):
            xr.testing.assert_equal(got[var], want[var])


def test_one_task_checks_the_coordinates():
    """A measurement whose analysis gives other coordinates than its template's is refused, not mislabelled."""
    ds = xr.Dataset({"height": ("x", dsa.arange(6.0, chunks=3))}, coords={"x": np.arange(6.0)})
    like = (ds["height"].cumsum("x"), None)
    out, none = one_task(lambda d: (d["height"].cumsum("x"), None), ds, template(like))
    assert none is None and isinstance(out.data, dsa.Array)
    with dask.config.set(scheduler="sync"):
        xr.testing.assert_identical(out.compute(), like[0].compute())
        with pytest.raises(xtopo.XtopoError, match="other coordinates"):
            one_task(lambda d: (d["height"].cumsum("x").assign_coords(x=np.arange(6.0) + 1), None),
                     ds, template(like))[0].compute()



@pytest.mark.parametrize("cluster", [False, True])
def test_lazy_averages_computed_at_once_equal_in_memory_ones(tmp_path, cluster):
    """``dask.compute(psd, acf)`` and ``client.compute(psd)`` of lazy averages lost a key in dask's graph
    optimisation ("Missing dependency", "lost dependencies"; pydata/xarray#11329, many variables derived by
    separate dask ops from one source): the statistics are one task per block of the grid now."""
    tree = xtopo.twin(_files(tmp_path))
    eager, lazy = _in_memory(tree), (tree.topo.psd(), tree.topo.acf())
    assert all(len(avg.chunks["measurement"]) == 1 for avg in lazy)  # Dataset.chunks: one chunking per dim
    if cluster:
        distributed = pytest.importorskip("distributed")
        with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0",
                                      silence_logs=50) as cl, distributed.Client(cl, set_as_default=False) as client:
            got = [client.compute(avg).result() for avg in lazy]
    else:
        got = dask.compute(*lazy)
    for avg, want in zip(got, (eager.topo.psd(), eager.topo.acf())):
        for var in ("average", "uncertainty", "relative_error", "count", "curves", "curve_error", "left_out",
                    "reliability_criterion"):  # which criterion set a spectrum's cutoff: data, known at compute
            xr.testing.assert_identical(avg[var], want[var])


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
        computed = client.gather(client.compute(lazy))  # all at once (pydata/xarray#11329 lost keys here)
    for name, kw in ANALYSES.items():
        want = getattr(eager.topo, name)(**kw)
        got = computed[name]
        for var in ("average", "count", "curves", "uncertainty", "reliability_cutoff"):
            xr.testing.assert_allclose(got[var], want[var], rtol=1e-10)
        _count_covers_reliable_ranges(got, got["average"].dims[0])
