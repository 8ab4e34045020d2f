"""Batch engine: chunking, store/resume, bad inputs, worker faults, FFT threads, contact."""

import functools
import json
import os
import signal
import threading
import time

import dask
import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo import batch
from xtopo.datasets import fractal_surface
from xtopo.errors import XtopoError

from ._batch_work import Interrupt, fft_work

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _surfaces(n, size=32):
    return {f"s{i}": fractal_surface((size, size), 1e-6, hurst=0.8, seed=i) for i in range(n)}


def _files(tmp_path, n, size=32):
    paths = []
    for name, ds in _surfaces(n, size).items():
        p = tmp_path / f"{name}.nc"
        xtopo.to_netcdf(ds, p)
        paths.append(str(p))
    return paths


def _data(ds):
    """Results without bookkeeping attrs, for comparisons between runs."""
    return ds.drop_vars("source").drop_attrs()


@pytest.fixture
def counter(tmp_path, monkeypatch):
    path = tmp_path / "executions.log"
    monkeypatch.setenv("XTOPO_TEST_COUNTER", str(path))

    def count():
        return sum(1 for _ in open(path)) if path.exists() else 0

    return count


LOADS = [0.05, 0.1, 0.2]


def test_run_matches_direct_calls_and_has_dims(tmp_path):
    ms = _surfaces(3)
    res = batch.run(fft_work, ms, LOADS, chunks={"measurement": 2, "load": 2}, scheduler="sync", progress=False)
    assert dict(res.sizes) == {"measurement": 3, "load": 3}
    assert list(res.measurement.values) == ["s0", "s1", "s2"]
    np.testing.assert_array_equal(res["load"].values, LOADS)
    assert res.attrs["n_failed"] == 0 and res.attrs["chunks_computed"] == 4
    assert (res.error.values == "").all()
    for name, ds in ms.items():
        direct = fft_work(ds, LOADS)
        np.testing.assert_allclose(res.mean_gap.sel(measurement=name).values, direct.mean_gap.values, rtol=1e-12)
    assert res.mean_gap.attrs["units"] == "1" and "long_name" in res.mean_gap.attrs


def test_threads_scheduler_equals_sync_and_sets_fft_threads(tmp_path):
    ms = _surfaces(4)
    a = batch.run(fft_work, ms, LOADS, scheduler="sync", progress=False, fft_threads=1)
    b = batch.run(fft_work, ms, LOADS, scheduler="threads", workers=2, progress=False, fft_threads=1)
    xr.testing.assert_allclose(_data(a), _data(b))
    assert (b.fft_threads == 1).all()
    c = batch.run(fft_work, ms, LOADS[:1], scheduler="sync", progress=False, fft_threads=2)
    assert (c.fft_threads == 2).all()
    assert os.environ.get("XTOPO_FFT_THREADS") is None  # restored after the run


def test_resume_recomputes_only_missing_chunks(tmp_path, counter, monkeypatch):
    ms = _surfaces(6)
    store = tmp_path / "store"
    full = batch.run(fft_work, ms, LOADS, chunks={"measurement": 1, "load": 3}, scheduler="sync", progress=False)
    assert counter() == 6
    # interrupted after 3 completed chunks (the 4th execution raises, like Ctrl-C)
    monkeypatch.setenv("XTOPO_TEST_INTERRUPT_AFTER", "9")  # counter is at 6: executions 7, 8, 9 complete
    with pytest.raises(Interrupt):
        batch.run(fft_work, ms, LOADS, chunks={"measurement": 1, "load": 3}, scheduler="sync", store=store,
                  progress=False)
    assert len([f for f in os.listdir(store) if f.startswith("chunk-")]) == 3
    partial = batch.open_store(store)
    assert (partial.error.values == "not computed").sum() == 3 * 3
    monkeypatch.delenv("XTOPO_TEST_INTERRUPT_AFTER")
    before = counter()
    res = batch.run(fft_work, ms, LOADS, chunks={"measurement": 1, "load": 3}, scheduler="sync", store=store,
                    progress=False)
    assert counter() - before == 3  # only the missing chunks ran
    assert res.attrs["chunks_computed"] == 3 and res.attrs["chunks_reused"] == 3
    xr.testing.assert_identical(_data(res), _data(full))
    # a third run computes nothing; the store alone gives the same result
    again = batch.run(fft_work, ms, LOADS, chunks={"measurement": 1, "load": 3}, scheduler="sync", store=store,
                      progress=False)
    assert counter() - before == 3 and again.attrs["chunks_reused"] == 6
    xr.testing.assert_identical(_data(batch.open_store(store)), _data(full))
    manifest = json.load(open(store / "manifest.json"))
    assert manifest["status"] == "complete"


def test_changed_input_or_params_invalidate_chunks(tmp_path, counter):
    paths = _files(tmp_path, 2)
    store = tmp_path / "store"
    batch.run(fft_work, paths, LOADS, scheduler="sync", store=store, progress=False)
    assert counter() == 2
    xtopo.to_netcdf(fractal_surface((32, 32), 1e-6, hurst=0.5, seed=9), paths[0])  # file changed
    os.utime(paths[0], ns=(1, 1))  # a different mtime even on coarse file systems
    res = batch.run(fft_work, paths, LOADS, scheduler="sync", store=store, progress=False)
    assert counter() == 3 and res.attrs["chunks_reused"] == 1
    res = batch.run(functools.partial(fft_work, iterations=5), paths, LOADS, scheduler="sync", store=store,
                    progress=False)
    assert counter() == 5 and res.attrs["chunks_reused"] == 0


def test_bad_inputs_keep_good_results(tmp_path):
    paths = _files(tmp_path, 3)
    bad = tmp_path / "broken.nc"
    bad.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 64)  # an HDF5 signature with nothing behind it
    missing = str(tmp_path / "missing.nc")
    store = tmp_path / "store"
    items = [paths[0], str(bad), paths[1], missing, paths[2]]
    res = batch.run(fft_work, items, LOADS, chunks=2, scheduler="threads", store=store, progress=False)
    assert res.attrs["n_failed"] == 2 * len(LOADS)
    failed = json.loads(res.attrs["failed_items"])
    assert any("broken.nc" in f for f in failed) and any("missing.nc" in f for f in failed)
    assert "broken.nc" in res.error.sel(measurement="broken.nc", load=0.1).item()
    assert np.isnan(res.mean_gap.sel(measurement="missing.nc")).all()
    good = batch.run(fft_work, paths, LOADS, scheduler="sync", progress=False)
    xr.testing.assert_identical(_data(res.sel(measurement=good.measurement)), _data(good))
    assert json.load(open(store / "manifest.json"))["status"] == "partial"
    import dask

    assert dask.config.get("scheduler", None) is None  # the store's write-time setting did not leak
    # failed chunks are retried on the next run, good ones reused
    res2 = batch.run(fft_work, items, LOADS, chunks=2, scheduler="threads", store=store, progress=False)
    assert res2.attrs["chunks_computed"] == 2 and res2.attrs["chunks_reused"] == 1


def _fails_at_big_load(ds, loads):
    if any(load > 1 for load in loads):
        raise XtopoError("load too large for this test")
    return fft_work(ds, loads, iterations=2)


def test_failing_parameter_value_is_isolated():
    res = batch.run(_fails_at_big_load, _surfaces(2), [0.1, 5.0, 0.2], scheduler="sync", progress=False)
    assert res.attrs["n_failed"] == 2
    assert (res.error.sel(load=5.0) == "XtopoError: load too large for this test").all()
    assert np.isfinite(res.mean_gap.sel(load=[0.1, 0.2])).all()


def test_analyze_matches_scalars(tmp_path):
    ms = _surfaces(3)
    res = batch.analyze(ms, ["scalars"], scheduler="threads", progress=False)
    for name, ds in ms.items():
        direct = xtopo.analysis.scalars.scalars(ds)
        xr.testing.assert_allclose(res.drop_vars(["error", "source"]).sel(measurement=name, drop=True).drop_attrs(),
                                   direct.drop_attrs())
    assert res.Sq.attrs["units"] == "m"
    both = batch.analyze(ms, ["scalars", xtopo.analysis.scalars.scalars], scheduler="sync", progress=False)
    assert "scalars_Sq" in both and both.attrs["n_failed"] == 0


def test_input_errors():
    ms = _surfaces(1)
    with pytest.raises(XtopoError, match="unknown analysis 'nope'"):
        batch.analyze(ms, ["nope"])
    with pytest.raises(XtopoError, match="chunk size"):
        batch.run(fft_work, ms, LOADS, chunks={"load": 0}, scheduler="sync")
    with pytest.raises(XtopoError, match="unknown dims"):
        batch.run(fft_work, ms, LOADS, chunks={"time": 1}, scheduler="sync")
    with pytest.raises(XtopoError, match="unknown scheduler"):
        batch.run(fft_work, ms, LOADS, scheduler="gpu")
    with pytest.raises(XtopoError, match="at least one measurement"):
        batch.run(fft_work, [], LOADS)
    with pytest.raises(XtopoError, match="exactly one"):
        batch.contact(ms, loads=[1], penetrations=[1])


def test_progress_bar_local(capsys):
    batch.run(fft_work, _surfaces(2), LOADS[:1], scheduler="sync", progress=True)
    assert "100% Completed" in capsys.readouterr().out
    batch.run(fft_work, _surfaces(2), LOADS[:1], scheduler="sync", progress=False)
    assert "Completed" not in capsys.readouterr().out


# --------------------------------------------------------------------------- distributed


@pytest.fixture(scope="module")
def cluster():
    """A 2-worker LocalCluster and a client to it that is not the process's default one: as the default it made
    every test of this module that ran after the first distributed one (in random order) compute on it."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  silence_logs=50) as cl, distributed.Client(cl, set_as_default=False) as client:
        yield cl, client


def test_distributed_worker_killed_mid_run(tmp_path, cluster):
    """64 tasks on 2 worker processes; one worker is SIGKILLed mid-run; all results equal the serial run."""
    _, client = cluster
    ms = _surfaces(16, size=64)
    work = functools.partial(fft_work, iterations=60)
    loads = [0.05, 0.1, 0.2, 0.4]
    store = tmp_path / "store"
    out = {}

    def go():
        out["res"] = batch.run(work, ms, loads, chunks={"measurement": 1, "load": 1}, client=client, store=store,
                               progress=False)

    t = threading.Thread(target=go)
    t.start()
    deadline = time.time() + 60
    while t.is_alive() and time.time() < deadline and (not store.exists() or
                                      len([f for f in os.listdir(store) if f.startswith("chunk-")]) < 6):
        time.sleep(0.02)
    done_at_kill = len([f for f in os.listdir(store) if f.startswith("chunk-")])
    pids = client.run(os.getpid)
    victim = sorted(pids)[0]
    os.kill(pids[victim], signal.SIGKILL)
    t.join(120)
    assert not t.is_alive()
    assert done_at_kill < 64  # the kill happened while work remained
    res = out["res"]
    assert res.attrs["chunks_computed"] == 64
    assert res.attrs["n_failed"] == 0, res.attrs["failed_items"]
    serial = batch.run(work, ms, loads, scheduler="sync", progress=False)
    xr.testing.assert_allclose(_data(res), _data(serial), rtol=1e-12)
    assert (res.fft_threads == 1).all()  # workers ran FFTs single-threaded


@pytest.mark.parametrize("stored", [False, True])
def test_distributed_lost_result_is_resubmitted(tmp_path, cluster, monkeypatch, stored):
    """A task whose finished result is lost (the worker holding it was killed: distributed's client marks the
    future "lost") runs again; its chunk's file, written before the task returned, is read back. It used to
    end the chunk as "XtopoError: None"."""
    distributed = pytest.importorskip("distributed")
    _, client = cluster
    lost = []

    class LosingFirst(distributed.as_completed):  # what the client does on the scheduler's "lost-data"
        def __next__(self):
            fut = super().__next__()
            if not lost:
                lost.append(fut.key)
                fut._state.lose()
            return fut

    monkeypatch.setattr(distributed, "as_completed", LosingFirst)
    ms = _surfaces(2)
    store = tmp_path / "store" if stored else None
    res = batch.run(fft_work, ms, LOADS, client=client, store=store, progress=False)
    assert lost and res.attrs["n_failed"] == 0, res.attrs["failed_items"]
    xr.testing.assert_allclose(_data(res), _data(batch.run(fft_work, ms, LOADS, scheduler="sync", progress=False)),
                               rtol=1e-12)


def test_distributed_active_client_and_resume(tmp_path, cluster):
    _, client = cluster
    ms = _surfaces(4)
    store = tmp_path / "store"
    with client.as_current():  # the active client is found without passing it
        a = batch.run(fft_work, ms, LOADS, store=store, progress=False)
        b = batch.run(fft_work, ms, LOADS, store=store, progress=False)
    assert a.attrs["chunks_computed"] == 4 and b.attrs["chunks_reused"] == 4
    xr.testing.assert_identical(_data(a), _data(b))


def test_distributed_progress_bar(cluster, capsys):
    _, client = cluster
    batch.run(fft_work, _surfaces(2), LOADS[:1], client=client, progress=True)
    assert "100% Completed" in capsys.readouterr().out
    batch.run(fft_work, _surfaces(2), LOADS[:1], client=client, progress=False)
    assert "Completed" not in capsys.readouterr().out


# --------------------------------------------------------------------------- contact (needs issue 5)


def _scene():
    try:
        from xtopo.contact import Scene
    except ImportError as exc:
        pytest.skip(f"xtopo.contact (issue 5) not available: {exc}")
    return Scene


def test_batch_contact_equals_direct_solves(tmp_path):
    Scene = _scene()
    ms = {f"s{i}": fractal_surface((32, 32), 1e-6, hurst=0.8, rms_slope=0.1, seed=i, periodic=True)
          for i in range(2)}
    loads = [1e-14, 2e-14]
    res = batch.contact(ms, loads, scheduler="sync", progress=False)
    assert set(res.dims) == {"measurement", "load"}
    assert res.attrs["n_failed"] == 0, res.attrs["failed_items"]
    for name, ds in ms.items():
        for load in loads:
            direct = Scene(ds, modulus=1.0).solve(load=load)
            np.testing.assert_allclose(res.area_fraction.sel(measurement=name, load=load).item(),
                                       float(direct.area_fraction), rtol=1e-10)
    with_maps = batch.contact(ms, loads[:1], scheduler="sync", progress=False, maps=True)
    assert "pressure" in with_maps and {"x", "y"} <= set(with_maps.pressure.dims)


def test_read_options_open_generic_files_and_key_the_store(tmp_path, counter):
    """Text matrices store no size or unit: read_options supply them in the workers, and enter the store keys."""
    surfaces = _surfaces(2, size=16)
    paths = []
    for name, ds in surfaces.items():
        p = tmp_path / f"{name}.txt"
        np.savetxt(p, ds.height.values * 1e6)                          # in um
        paths.append(str(p))
    store = tmp_path / "store"
    bare = batch.run(fft_work, paths, LOADS, scheduler="sync", progress=False)
    assert all("file_units" in e for e in bare.error.values.ravel())  # no unit: every item fails, and says why
    opts = {"file_units": "um", "physical_size": (1.0, 1.0)}
    res = batch.run(fft_work, paths, LOADS, scheduler="sync", store=store, progress=False, read_options=opts)
    assert res.attrs["n_failed"] == 0 and counter() == 2
    direct = batch.run(fft_work, [xtopo.io.open_topography(p, **opts) for p in paths], LOADS, scheduler="sync",
                       progress=False)
    xr.testing.assert_allclose(_data(res), _data(direct).assign_coords(measurement=res.measurement.values))
    before = counter()
    again = batch.run(fft_work, paths, LOADS, scheduler="sync", store=store, progress=False, read_options=dict(opts))
    assert counter() == before and again.attrs["chunks_reused"] == 2  # same options: reused
    other = batch.run(fft_work, paths, LOADS, scheduler="sync", store=store, progress=False,
                      read_options={**opts, "physical_size": (2.0, 2.0)})
    assert counter() == before + 2 and other.attrs["chunks_reused"] == 0   # other options: recomputed
    with pytest.raises(XtopoError, match=r"read_options has no option 'file_unit'"):
        batch.run(fft_work, paths, LOADS, scheduler="sync", progress=False, read_options={"file_unit": "um"})


def test_contact_batch_checks_shared_parameters_before_dispatch():
    """A bad scene or solver parameter fails the call at once (it was recorded as N identical item errors); the
    declared ones are covered by tests/test_parameters.py, tol ≥ 1 says why."""
    with pytest.raises(XtopoError, match="tol must be below 1"):
        batch.contact(_surfaces(2, size=16), [1e-3], scheduler="sync", progress=False, tol=1)


def test_contact_batch_solves_every_measurement_in_one_length_unit():
    """A copy in nm was loaded with 0.01 E*·nm² (not the 0.01 E*·µm² the `load` coordinate said); its contact
    area and penetration lost their units, and its maps joined the µm ones on a 31×31 union grid."""
    _scene()
    s = fractal_surface((16, 16), 1.0, hurst=0.8, rms_slope=0.1, seed=0, periodic=True, units="um")
    ms = {"um": s, "nm": s.topo.to_units("nm")}
    res = batch.contact(ms, [0.01], scheduler="sync", progress=False, maps=True)
    assert res.attrs["n_failed"] == 0, res.attrs["failed_items"]
    assert res["load"].attrs["units"] == "E* um2"
    # 0.01 E*·µm² on a 1 µm × 1 µm surface: mean pressure 0.01 E* for both copies
    np.testing.assert_allclose(res.mean_pressure.values, 0.01, rtol=1e-12)
    um, nm = res.sel(measurement="um"), res.sel(measurement="nm")
    assert um.area_fraction.item() == nm.area_fraction.item() > 0
    for name, units in (("contact_area", "um2"), ("penetration", "um")):
        assert res[name].attrs["units"] == units
        np.testing.assert_allclose(nm[name].values, um[name].values, rtol=1e-6)
    assert dict(res.pressure.sizes) == {"measurement": 2, "load": 1, "y": 16, "x": 16}
    xr.testing.assert_allclose(res.x.reset_coords(drop=True), s.x.reset_coords(drop=True))
    xr.testing.assert_allclose(nm.pressure.drop_vars(["measurement", "source", "history"]),
                               um.pressure.drop_vars(["measurement", "source", "history"]), rtol=1e-6, atol=1e-8)
    # asked in nm: the same physical load is 1e4 E*·nm²
    in_nm = batch.contact(ms, [1e4], scheduler="sync", progress=False, units="nm")
    assert in_nm["load"].attrs["units"] == "E* nm2" and in_nm.penetration.attrs["units"] == "nm"
    np.testing.assert_array_equal(in_nm.area_fraction.values, res.area_fraction.values)
    # data without a unit cannot join a batch in µm: that item fails and says why
    bare = s.copy()
    for v in ("height", "x", "y"):
        bare[v].attrs.pop("units")
    mixed = batch.contact({"um": s, "bare": bare}, [0.01], scheduler="sync", progress=False)
    assert mixed.error.sel(measurement="um").item() == "" and "no length unit" in mixed.error.sel(measurement="bare").item()


@pytest.mark.parametrize("control,units", [("mean_pressures", "E*"), ("penetrations", "m")])
def test_contact_batch_coordinate_has_units_when_every_item_failed(tmp_path, control, units):
    """The mean_pressure/penetration coordinate took its units from the results: with none, it had none."""
    res = batch.contact([str(tmp_path / "missing.nc")], scheduler="sync", progress=False, **{control: [0.01]})
    assert res.attrs["n_failed"] == 1
    assert res[control[:-1]].attrs["units"] == units and "long_name" in res[control[:-1]].attrs


def test_contact_batch_keeps_each_measurements_history(tmp_path):
    """The solves' history lines differ by load, so the batch dropped history altogether: neither the
    input's processing nor the contact computation was recorded."""
    _scene()
    ms = {f"s{i}": fractal_surface((16, 16), 1.0, hurst=0.8, rms_slope=0.1, seed=i, periodic=True, units="um")
          for i in range(2)}
    ms["s1"] = xtopo.preprocess.detrend(ms["s1"])
    kw = dict(scheduler="sync", progress=False, chunks={"load": 1}, hardness=0.5, store=tmp_path / "store")
    res = batch.contact({**ms, "missing": str(tmp_path / "missing.nc")}, [0.01, 0.02], **kw)
    for name, ds in ms.items():
        lines = res.history.sel(measurement=name).item().split("\n")
        assert lines[:-1] == ds.attrs["history"].split("\n")       # the input's history, then one line
        assert "load" in lines[-1] and "E* um2" in lines[-1] and "hardness=0.5" in lines[-1]
        boundary = "periodic" if xtopo.conventions.is_periodic(ds) else "free"  # detrending a tilt: free
        assert "no counter surface" in lines[-1] and f"boundary {boundary}" in lines[-1]
    assert res.history.sel(measurement="missing").item() == ""
    assert res.history.sel(measurement="s0").item() != res.history.sel(measurement="s1").item()
    again = batch.contact({**ms, "missing": str(tmp_path / "missing.nc")}, [0.01, 0.02], **kw)
    assert again.attrs["chunks_reused"] == 4
    xr.testing.assert_identical(again.history, res.history)


@pytest.mark.parametrize("kwargs,match", [
    (dict(loads=[0.1, -1]), "load must be ≥ 0"), (dict(loads=[1, "a"]), "load must be a finite scalar"),
    (dict(loads=[np.nan]), "finite scalar"), (dict(loads=[True]), "finite scalar"),
    (dict(mean_pressures=[-0.1]), "mean_pressure must be ≥ 0"),
    (dict(mean_pressures=[0.5], hardness=0.1), "reaches the hardness"),
    (dict(penetrations=[np.inf]), "penetration must be a finite scalar"),
    (dict(loads=[[1, 2], [3]]), "load values must be a number or a 1D sequence"),
])
def test_contact_batch_checks_control_values_before_dispatch(kwargs, match, monkeypatch):
    """loads=[-1] gave one identical item error per measurement instead of failing the call at once."""
    def no_task(*args, **kw):
        raise AssertionError("a task was dispatched")

    monkeypatch.setattr(batch._dispatch, "run_chunk", no_task)
    with pytest.raises(XtopoError, match=match):
        batch.contact(_surfaces(2, size=16), scheduler="sync", progress=False, **kwargs)


def _line_and_area(tmp_path):
    s = fractal_surface((32, 32), 1.0, hurst=0.8, units="um", seed=1)
    line = fractal_surface((64,), 1.0, hurst=0.8, units="um", seed=2)
    paths = {"area.nc": s, "line.nc": line}
    for name, ds in paths.items():
        xtopo.to_netcdf(ds, tmp_path / name)
    return s, line, {k: str(tmp_path / k) for k in paths}


def test_contact_batch_refuses_loads_for_a_mix_of_line_and_area_scans(tmp_path, monkeypatch):
    """A load is E*·µm² on an area scan but E*·µm (per unit length) on a line scan: a mixed batch labelled the
    `load` coordinate with the first item's units, wrong for the others, and dropped contact_area's units."""
    _scene()
    s, line, files = _line_and_area(tmp_path)
    kw = dict(scheduler="sync", progress=False, read_options={"units": "um"})
    run_chunk = batch._dispatch.run_chunk

    def no_task(*args, **k):
        raise AssertionError("a task was dispatched")

    monkeypatch.setattr(batch._dispatch, "run_chunk", no_task)
    with pytest.raises(XtopoError, match=r"loads= for a mix of line and area scans: measurement 'area' is an area "
                                         r"scan, 'line' a line scan: a load is a force on an area scan \(a pressure "):
        batch.contact({"area": s, "line": line}, [0.01], **kw)
    monkeypatch.setattr(batch._dispatch, "run_chunk", run_chunk)
    # a file is known only once read: one of the other kind fails as an item, the others keep their labels
    res = batch.contact({"area": s, "line": files["line.nc"]}, [0.01], **kw)
    assert res.error.sel(measurement="area").item() == ""
    assert "this measurement is a line scan, but the loads of this batch are for area scans" in \
        res.error.sel(measurement="line").item()
    assert res["load"].attrs == {"units": "E* um2", "long_name": "normal load"} and res.attrs["n_failed"] == 1
    assert res.contact_area.attrs == {"units": "um2", "long_name": "contact area"}
    assert np.isnan(res.contact_area.sel(measurement="line").item())
    # files only: the first one solved sets the kind
    res = batch.contact({"line": files["line.nc"], "area": files["area.nc"]}, [0.01], **kw)
    assert res.error.sel(measurement="line").item() == "" and res.attrs["n_failed"] == 1
    assert "this measurement is an area scan" in res.error.sel(measurement="area").item()
    assert res["load"].attrs == {"units": "E* um", "long_name": "normal load per unit length"}
    assert res.contact_area.attrs == {"units": "um", "long_name": "contact length"}
    assert res.history.sel(measurement="area").item() == ""
    assert np.isnan(res.area_fraction.sel(measurement="area").item())
    # a physical modulus: loads in Pa·length, as each item's scene labels them (were relabelled E*)
    res = batch.contact({"line": files["line.nc"], "area": files["area.nc"]}, [0.01], modulus=2e9, **kw)
    assert res["load"].attrs["units"] == "Pa um" and res["mean_pressure"].attrs["units"] == "Pa"


def test_mixed_files_batch_records_its_refused_items_in_the_store(tmp_path):
    """In a loads= batch of files mixing line and area scans, the items of the other kind were marked failed only
    in the returned result, after the run: the store's manifest said 'complete' with no failed item, and
    open_store showed those items solved. Each item now carries its kind (``scan``) and the store records how the
    result is settled: a rerun and open_store give the same result, and the manifest lists the refused items."""
    _scene()
    _, _, files = _line_and_area(tmp_path)
    store = tmp_path / "store"
    ms = {"line": files["line.nc"], "area": files["area.nc"]}
    kw = dict(scheduler="sync", progress=False, read_options={"units": "um"}, store=store)
    res = batch.contact(ms, [0.01, 0.02], **kw)
    assert res.scan.dims == ("measurement", "load") and "long_name" in res.scan.attrs
    assert list(res.scan.sel(measurement="line").values) == ["line", "line"]
    assert list(res.scan.sel(measurement="area").values) == ["", ""]   # refused: no result, as any failed item
    assert res.attrs["n_failed"] == 2
    assert all("this measurement is an area scan" in e for e in res.error.sel(measurement="area").values)
    manifest = json.load(open(store / "manifest.json"))
    assert manifest["status"] == "partial" and manifest["failed"] == json.loads(res.attrs["failed_items"])
    again = batch.contact(ms, [0.01, 0.02], **kw)
    assert again.attrs["chunks_reused"] == 2 and again.attrs["chunks_computed"] == 0
    xr.testing.assert_identical(again, res.assign_attrs(chunks_computed=0, chunks_reused=2))
    xr.testing.assert_identical(batch.open_store(store), res.drop_attrs(deep=False).assign_attrs(
        {k: v for k, v in res.attrs.items() if k not in ("title", "n_failed", "failed_items", "chunks_computed",
                                                         "chunks_reused", "store")}))
    assert json.load(open(store / "manifest.json"))["failed"] == manifest["failed"]


def test_open_store_names_the_store_whose_manifest_has_an_unknown_finishing_step(tmp_path):
    store = tmp_path / "store"
    batch.run(fft_work, _surfaces(1), LOADS, scheduler="sync", store=store, progress=False)
    manifest = json.load(open(store / "manifest.json"))
    (store / "manifest.json").write_text(json.dumps({**manifest, "finish": {"name": "rm -rf", "kwargs": {}}}))
    with pytest.raises(XtopoError, match=r"batch store .*store \(manifest.json\): unknown finishing step .*rm -rf"):
        batch.open_store(store)


@pytest.mark.parametrize("manifest", ['{"dim": "load"}', "[1, 2]", '{"dim": "load", "params": null, '
                                      '"measurements": ["a"], "sources": [""], "chunks": 5}'])
def test_open_store_of_a_damaged_manifest_names_the_store(tmp_path, manifest):
    """A manifest without 'params' raised a bare KeyError, a JSON list or chunks=5 a TypeError."""
    (tmp_path / "manifest.json").write_text(manifest)
    with pytest.raises(XtopoError, match=r"batch store .* \(manifest.json\) is damaged or not a batch manifest"):
        batch.open_store(tmp_path)


def test_open_store_does_not_create_a_missing_store(tmp_path):
    """open_store of a mistyped directory created it (and then said it had no manifest)."""
    with pytest.raises(XtopoError, match="no batch store at .*typo: not a directory"):
        batch.open_store(tmp_path / "typo")
    assert not (tmp_path / "typo").exists()


@pytest.mark.parametrize("store", ["", b""])
def test_an_empty_store_path_is_refused(tmp_path, monkeypatch, store):
    """store='' wrote the chunk files, manifest.json (and, on the command line, result.nc) into the working
    directory."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(XtopoError, match="store must be a directory path, got an empty string"):
        batch.run(fft_work, _surfaces(1), LOADS, scheduler="sync", store=store, progress=False)
    assert os.listdir(tmp_path) == []


def test_measurements_that_are_no_collection_are_refused():
    """None or a number raised a bare TypeError "'int' object is not iterable"."""
    for measurements in [None, 3, 2.5, True, object()]:
        with pytest.raises(XtopoError, match="measurements must be a Dataset, a file path, or a mapping"):
            batch.run(fft_work, measurements, LOADS, scheduler="sync")
        with pytest.raises(XtopoError, match="measurements must be a Dataset, a file path, or a mapping"):
            batch.analyze(measurements, scheduler="sync")


def test_run_refuses_a_func_that_is_not_callable():
    """A func that is no function ran the batch and reported every item as failed ("'int' object is not
    callable") instead of failing at once."""
    for func in [None, 5, "fft_work"]:
        with pytest.raises(XtopoError, match="func must be a function"):
            batch.run(func, _surfaces(2), LOADS, scheduler="sync", progress=False)


def test_run_refuses_a_client_that_is_no_distributed_client():
    """client=5 raised "'int' object has no attribute 'submit'"."""
    for client in [5, "tcp://localhost:8786", object()]:
        with pytest.raises(XtopoError, match="client must be a distributed.Client"):
            batch.run(fft_work, _surfaces(1), LOADS, client=client, progress=False)


@pytest.mark.parametrize("scheduler", ["tcp://", "tcp://:"])
def test_a_scheduler_address_without_host_or_port_is_refused(scheduler):
    """distributed's ValueError ('missing port number in address') escaped; the half-built Client then stayed the
    process's default client, so every later dask compute (and xarray's NetCDF write lock) asked the dead scheduler:
    79 tests after this one failed in a full run."""
    dask = pytest.importorskip("dask")
    distributed = pytest.importorskip("distributed")
    before = dask.config.get("scheduler", None), distributed.client._get_global_client()
    with pytest.raises(XtopoError, match="give it as 'tcp://host:port'"):
        batch.run(fft_work, _surfaces(1), LOADS, scheduler=scheduler, progress=False)
    assert (dask.config.get("scheduler", None), distributed.client._get_global_client()) == before


def test_read_option_values_are_checked_before_any_task(tmp_path):
    """Bad read_options values were only found in the workers, as one identical error per file."""
    for read_options, match in [
        ({"units": 5}, "read_options: units=5 is not a length unit"),
        ({"file_units": "s"}, "read_options: file_units='s' is not a length unit"),
        ({"height_units": "abc"}, "read_options: height_units='abc' is not a length unit"),
        ({"physical_size": -1}, "read_options: physical_size must be positive finite lengths"),
        ({"periodic": "yes"}, "read_options: periodic must be True or False"),
        ({"tip_radius": 0}, "read_options: tip_radius must be a positive finite number"),
        ({"format": "nope"}, "unknown format 'nope'"),
    ]:
        paths = _files(tmp_path, 2, size=16)
        with pytest.raises(XtopoError, match=match):
            batch.analyze(paths, scheduler="sync", read_options=read_options, progress=False)


def test_analyze_refuses_analyses_that_are_no_sequence():
    """analyses=None or a number raised a bare TypeError "'int' object is not iterable"."""
    for analyses in [None, 5, 2.5]:
        with pytest.raises(XtopoError, match="analyses must be a name, a function or a sequence"):
            batch.analyze(_surfaces(1), analyses, scheduler="sync")


def test_analyze_takes_one_analysis_name():
    """analyses='scalars' was split into its letters ("unknown analysis 's'")."""
    xr.testing.assert_identical(batch.analyze(_surfaces(1), "scalars", scheduler="sync", progress=False),
                                batch.analyze(_surfaces(1), ["scalars"], scheduler="sync", progress=False))


def test_unknown_analysis_lists_only_what_analyze_can_run():
    """'reliability' (a module without a function of its name) was refused as unknown and listed as available."""
    with pytest.raises(XtopoError, match="unknown analysis 'reliability'") as info:
        batch.analyze(_surfaces(1), ["reliability"], scheduler="sync")
    available = str(info.value).split("available: ")[1]
    assert "reliability" not in available and "scalars" in available


@pytest.mark.parametrize("control", ["loads", "mean_pressures"])
def test_mixed_files_batch_does_not_read_the_history_wording(tmp_path, monkeypatch, control):
    """The kind of each file's scan was recovered from the wording of its contact history line: reworded, a
    loads= batch let line and area scans share one load coordinate, and a mean_pressures= batch kept load and
    contact_area, whose units differ between the two kinds."""
    _scene()
    _, _, files = _line_and_area(tmp_path)
    monkeypatch.setattr(batch._contact, "_contact_line", lambda *args: "solved by xtopo")
    res = batch.contact({"line": files["line.nc"], "area": files["area.nc"]}, **{control: [0.01]},
                        scheduler="sync", progress=False, read_options={"units": "um"})
    assert res.history.sel(measurement="line").item().endswith("\nsolved by xtopo")   # the wording changed
    if control == "loads":
        assert "this measurement is an area scan" in res.error.sel(measurement="area").item()
        assert res["load"].attrs["units"] == "E* um" and res.contact_area.attrs["units"] == "um"
    else:
        assert "load" not in res.data_vars and "contact_area" not in res.data_vars
        assert res.attrs["n_failed"] == 0 and list(res.scan.values[:, 0]) == ["line", "area"]


@pytest.mark.parametrize("control", ["mean_pressures", "penetrations"])
def test_contact_batch_of_line_and_area_scans_leaves_out_load_and_contact_area(tmp_path, control):
    """A mean pressure or a penetration means the same on a line and an area scan, but the results' load (force
    per length / force) and contact_area (length / area) do not: they were kept with their units dropped."""
    _scene()
    s, line, files = _line_and_area(tmp_path)
    kw = dict(scheduler="sync", progress=False, read_options={"units": "um"}, **{control: [0.01]})
    for ms in ({"area": s, "line": line}, {"line": files["line.nc"], "area": files["area.nc"]}):
        res = batch.contact(ms, **kw)
        assert res.attrs["n_failed"] == 0, res.attrs["failed_items"]
        assert "load" not in res.data_vars and "contact_area" not in res.data_vars
        assert "left out" in res.attrs["comment"]
        for name in ("mean_pressure", "area_fraction", "penetration"):
            assert res[name].attrs["units"] in ("E*", "1", "um"), name
        direct = batch.contact({"line": line}, **kw)
        xr.testing.assert_allclose(res.area_fraction.sel(measurement="line").reset_coords(drop=True),
                                   direct.area_fraction.sel(measurement="line").reset_coords(drop=True))
    alone = batch.contact({"area": s}, **kw)   # one kind: kept
    assert alone.contact_area.attrs["units"] == "um2" and alone["load"].attrs["units"] == "E* um2"


def _weighted_std(ds, *, weights):
    return xr.Dataset({"s": ((), float(ds["height"].std()) * float(np.sum(weights)), {"units": "m", "long_name": "s"})})


def test_store_key_holds_function_arguments_by_content(tmp_path):
    """Chunk keys held repr() of a partial's arguments: arrays differing beyond numpy's abbreviated
    repr reused the stale chunk, and a function argument (``analyze(ms, [callable])``) put its memory
    address into the key, so a new process never reused the store."""
    ms = _surfaces(2)
    store = tmp_path / "store"
    ones = np.ones(5000)
    other = ones.copy()
    other[2500] = 6.0  # same repr as ``ones``
    a = batch.run(functools.partial(_weighted_std, weights=ones), ms, scheduler="sync", store=store, progress=False)
    b = batch.run(functools.partial(_weighted_std, weights=other), ms, scheduler="sync", store=store, progress=False)
    assert b.attrs["chunks_reused"] == 0
    np.testing.assert_allclose(b.s.values, a.s.values * 5005 / 5000)
    func = functools.partial(batch._analyze_item, analyses=(xtopo.analysis.scalars.scalars,))
    here = batch.chunk_key(func, "load", ["a"], ["p"], None)
    import subprocess
    import sys

    code = ("import functools, xtopo; from xtopo import batch; print(batch.chunk_key(functools.partial("
            "batch._analyze_item, analyses=(xtopo.analysis.scalars.scalars,)), 'load', ['a'], ['p'], None))")
    there = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=REPO)
    assert there.stdout.strip() == here


def test_store_key_follows_an_edited_module_function(tmp_path, monkeypatch):
    """A module-level function entered the chunk key by name only: after its body was edited, a
    new run reused the chunks of the old code."""
    import importlib
    import sys

    module = tmp_path / "xtopo_store_probe.py"
    module.write_text("def stat(ds):\n    return ds.height.std()\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "xtopo_store_probe", raising=False)
    probe = importlib.import_module("xtopo_store_probe")
    before = batch.chunk_key(functools.partial(probe.stat), "load", ["a"], ["p"], None)
    assert batch.chunk_key(functools.partial(probe.stat), "load", ["a"], ["p"], None) == before
    module.write_text("def stat(ds):\n    return ds.height.mean()  # edited\n")
    probe = importlib.reload(probe)
    assert batch.chunk_key(functools.partial(probe.stat), "load", ["a"], ["p"], None) != before
    sys.modules.pop("xtopo_store_probe", None)


def test_run_options_are_checked_before_any_task():
    """These raised bare TypeError/ValueError (fft_threads='x', workers='two', dim=3, 2D loads,
    read_options=[...], store=3 or an uncreatable store), some only after the tasks ran;
    chunks=True ran one measurement per chunk, progress='no' showed the bar."""
    for kwargs, match in [
        ({"chunks": True}, "chunks must be an int"),
        ({"chunks": {"measurement": True}}, "chunk size along 'measurement'.*got True"),
        ({"dim": 3}, "dim must be a name"),
        ({"dim": "measurement"}, "dim must be a name.*got 'measurement'"),
        ({"params": [[0.1, 0.2], [0.3, 0.4]]}, r"load values must be a number or a 1D sequence, got shape \(2, 2\)"),
        ({"read_options": ["units"]}, "read_options must be a dict"),
        ({"store": 3}, "store must be a directory path.*int"),
        ({"store": "/proc/no-such-dir/store"}, "cannot create the batch store /proc/no-such-dir/store"),
    ]:
        kwargs = {"params": LOADS, "scheduler": "sync", **kwargs}
        with pytest.raises(XtopoError, match=match):
            batch.run(fft_work, _surfaces(2), **kwargs)


def _with_attrs(ds, loads):
    out = fft_work(ds, loads, iterations=2)
    out["mean_gap"].attrs["normalised"] = True
    return out.assign_attrs(settings={"iterations": 2}, converged=True)


def test_computed_and_reused_chunks_are_identical(tmp_path):
    """A chunk computed in the run kept bool/dict attrs, one read back from the store had
    their stored form (1, JSON): the same batch gave different results on a rerun."""
    store = tmp_path / "store"
    fresh = batch.run(_with_attrs, _surfaces(2), LOADS, scheduler="sync", store=store, progress=False)
    reused = batch.run(_with_attrs, _surfaces(2), LOADS, scheduler="sync", store=store, progress=False)
    assert reused.attrs["chunks_reused"] == 2
    for key in ("settings", "converged"):
        assert fresh.attrs[key] == reused.attrs[key]
    xr.testing.assert_identical(fresh.drop_attrs(deep=False), reused.drop_attrs(deep=False))


# --------------------------------------------------------------------------- preprocessing in the worker

PREPROCESS = {"detrend": "plane", "fill_missing": True}
_BOOKKEEPING = ["error", "source", "history"]


def _preprocessed(ds):
    """What PREPROCESS asks for, step by step."""
    return xtopo.preprocess.fill_missing(xtopo.preprocess.detrend(ds, "plane"))


@pytest.mark.parametrize("scheduler", ["sync", "threads"])
def test_analyze_preprocesses_files_and_datasets_in_the_worker(tilted_with_hole, scheduler):
    """A batch used the heights as read: the scalars of a tilted file were those of its tilt, and the
    command line's --detrend/--fill-missing had no batch counterpart."""
    path, ds = tilted_with_hole
    raw = batch.analyze({"file": path}, scheduler=scheduler, progress=False)
    res = batch.analyze({"file": path, "memory": ds}, scheduler=scheduler, workers=2, progress=False,
                        preprocess=PREPROCESS)
    assert res.attrs["n_failed"] == 0, res.attrs["failed_items"]
    want = xtopo.analysis.scalars.scalars(_preprocessed(ds))
    for name in ("file", "memory"):
        got = res.drop_vars(_BOOKKEEPING).sel(measurement=name, drop=True)
        xr.testing.assert_allclose(got, want, rtol=1e-12)
        history = str(res.history.sel(measurement=name).item())
        assert "detrend(mode='plane', per_line=False)" in history and "fill_missing(harmonic)" in history
    unprocessed = xtopo.analysis.scalars.scalars(ds)
    xr.testing.assert_allclose(raw.drop_vars(_BOOKKEEPING).sel(measurement="file", drop=True), unprocessed)
    assert float(raw.Sq.item()) > 10 * float(want.Sq)  # the tilt, which the preprocessing removes


def test_contact_batch_fills_and_detrends_on_request(tilted_with_hole):
    """A file with missing points could not be solved in a batch at all."""
    Scene = _scene()
    path, ds = tilted_with_hole
    without = batch.contact([path], mean_pressures=[0.01], scheduler="sync", progress=False)
    error = str(without.error.item())  # it named xtopo.preprocess.fill_missing, which a batch could not call
    assert "tilted.nc: 40 points have no height" in error and "preprocess={'fill_missing': True}" in error
    res = batch.contact([path, ds], mean_pressures=[0.01, 0.02], scheduler="sync", progress=False,
                        preprocess=[("detrend", {"mode": "plane"}), "fill_missing"])
    assert res.attrs["n_failed"] == 0, res.attrs["failed_items"]
    direct = Scene(_preprocessed(ds), modulus=1.0).curve(mean_pressures=[0.01, 0.02])
    for name in res.measurement.values:
        np.testing.assert_allclose(res.area_fraction.sel(measurement=name).values, direct.area_fraction.values,
                                   rtol=1e-6)
        history = str(res.history.sel(measurement=name).item()).split("\n")
        steps = [i for i, line in enumerate(history) if line.startswith(("detrend(", "fill_missing("))]
        contact_line = next(i for i, line in enumerate(history) if line.startswith("xtopo contact"))
        assert len(steps) == 2 and steps[-1] < contact_line  # preprocessed, then solved


def test_store_keys_hold_the_preprocessing(tmp_path, counter, tilted_with_hole):
    """The steps enter each chunk's key: the same steps (in any form) reuse a chunk, other steps recompute it;
    a function whose result has no history gets the preprocessed measurement's."""
    path, ds = tilted_with_hole
    store = tmp_path / "store"
    kw = dict(scheduler="sync", store=store, progress=False)
    first = batch.run(fft_work, [path], LOADS, preprocess=PREPROCESS, **kw)
    assert counter() == 1 and first.attrs["chunks_computed"] == 1
    assert "fill_missing(harmonic)" in str(first.history.item())
    same = batch.run(fft_work, [path], LOADS, preprocess=[("detrend", {"mode": "plane", "per_line": False}),
                                                           ("fill_missing", True)], **kw)
    assert counter() == 1 and same.attrs["chunks_reused"] == 1
    xr.testing.assert_identical(_data(same), _data(first))
    other = batch.run(fft_work, [path], LOADS, preprocess={"detrend": "curvature", "fill_missing": True}, **kw)
    assert counter() == 2 and other.attrs["chunks_computed"] == 1
    assert "detrend(mode='curvature'" in str(other.history.item())
    assert not np.allclose(other.mean_gap.values, first.mean_gap.values)
    manifest = json.load(open(store / "manifest.json"))
    assert manifest["preprocess"] == [["detrend", {"mode": "curvature", "per_line": False}], ["fill_missing", {}]]
    batch.run(fft_work, [path], LOADS, **kw)  # none: the file as read
    assert counter() == 3
    direct = fft_work(_preprocessed(ds), LOADS)[["mean_gap", "area_fraction"]]
    xr.testing.assert_allclose(first[["mean_gap", "area_fraction"]].squeeze("measurement", drop=True)
                               .drop_vars("load"), direct)


def test_bad_preprocessing_is_refused_before_dispatch(monkeypatch):
    for preprocess, match in [
        ({"detrnd": "plane"}, "preprocess: unknown preprocessing step 'detrnd'; the steps: detrend, fill_missing"),
        ({"detrend": "tilt"}, "preprocess: step 'detrend': mode must be one of .*got 'tilt'"),
        ({"detrend": {"order": 1}}, "preprocess: step 'detrend' has no option 'order'; its options: mode, per_line"),
        ({"detrend": {"per_line": "yes"}}, "preprocess: step 'detrend': per_line must be True or False"),
        ({"fill_missing": "harmonic"}, "preprocess: step 'fill_missing' takes no options"),
        ([("detrend",)], r"a step is a name or a \(name, options\) pair"),
        (3, "preprocess must be a step name, a dict"),
    ]:
        for call in ["run", "analyze", "contact"]:
            def no_task(*args, **kw):
                raise AssertionError("a task was dispatched")

            if call == "contact":
                _scene()
            monkeypatch.setattr(batch._dispatch, "run_chunk", no_task)
            args = {"run": (fft_work, _surfaces(1, size=16), LOADS), "analyze": (_surfaces(1, size=16),),
                    "contact": (_surfaces(1, size=16), [1e-14])}[call]
            with pytest.raises(XtopoError, match=match):
                getattr(batch, call)(*args, scheduler="sync", progress=False, preprocess=preprocess)


def test_distributed_batch_preprocesses_in_the_workers(tilted_with_hole, cluster):
    _, client = cluster
    path, ds = tilted_with_hole
    res = batch.analyze([str(path), ds], client=client, progress=False, preprocess=PREPROCESS)
    assert res.attrs["n_failed"] == 0, res.attrs["failed_items"]
    want = xtopo.analysis.scalars.scalars(_preprocessed(ds))
    for name in res.measurement.values:
        xr.testing.assert_allclose(res.drop_vars(_BOOKKEEPING).sel(measurement=name, drop=True), want, rtol=1e-12)


def test_small_chunks_are_packed_into_few_tasks(tmp_path, cluster, monkeypatch):
    """Chunks far shorter than a task's overhead run several to a task (timed on one chunk per worker first);
    the store still holds one file per chunk and the results equal the serial run's."""
    from distributed import get_task_stream

    # a task target far above any chunk's time, however loaded the machine: the packing is then set by the
    # four-tasks-a-worker bound alone, not by how long the timed chunks happened to take
    monkeypatch.setenv("XTOPO_BATCH_TASK_SECONDS", "60")
    _, client = cluster
    ms = _surfaces(8, size=32)
    work = functools.partial(fft_work, iterations=2)
    batch.run(work, ms, LOADS[:1], client=client, progress=False)  # imports in the workers
    with get_task_stream(client) as ts:
        res = batch.run(work, ms, LOADS, chunks={"measurement": 1, "load": 1}, client=client,
                        store=tmp_path / "store", progress=False)
    tasks = {rec["key"] for rec in ts.data if str(rec["key"]).startswith("xtopo-batch-")}
    n_chunks = 8 * len(LOADS)
    assert res.attrs["chunks_computed"] == n_chunks and res.attrs["n_failed"] == 0
    assert len(tasks) < n_chunks / 2
    assert len([f for f in os.listdir(tmp_path / "store") if f.startswith("chunk-")]) == n_chunks
    serial = batch.run(work, ms, LOADS, chunks={"measurement": 1, "load": 1}, scheduler="sync", progress=False)
    xr.testing.assert_allclose(_data(res), _data(serial), rtol=1e-12)


def test_group_size_from_chunk_cost(monkeypatch):
    from xtopo.batch._dispatch import _group_size

    assert _group_size(0.001, 1000, 2) == 125   # 0.25 s of work a task, at most 1000 / (4 × 2)
    assert _group_size(0.001, 20, 2) == 3       # at least four tasks a worker
    assert _group_size(1.0, 1000, 2) == 1       # long chunks: one a task
    monkeypatch.setenv("XTOPO_BATCH_TASK_SECONDS", "0")
    assert _group_size(0.001, 1000, 2) == 1     # packing off
