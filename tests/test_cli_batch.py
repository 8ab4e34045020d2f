"""CLI: info, contact, batch (local and against a separately started `dask scheduler`), convert."""

import json
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.cli import main
from xtopo.datasets import fractal_surface

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.fixture
def files(tmp_path):
    paths = []
    for i in range(3):
        p = tmp_path / f"surface{i}.nc"
        xtopo.to_netcdf(fractal_surface((32, 32), 1e-6, hurst=0.8, rms_slope=0.1, seed=i, periodic=True), p)
        paths.append(str(p))
    return paths


@pytest.mark.parametrize("command", [["info"], ["contact"], ["batch"], ["batch", "contact"], ["batch", "analyze"],
                                     ["convert"]])
def test_help_on_every_command(command, capsys):
    with pytest.raises(SystemExit) as e:
        main([*command, "--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert f"usage: xtopo {' '.join(command)}" in out and len(out) > 200


def test_console_script_batch_help():
    r = subprocess.run([sys.executable, "-m", "xtopo.cli", "batch", "contact", "--help"], capture_output=True,
                       text=True, cwd=REPO)
    assert r.returncode == 0 and "--scheduler" in r.stdout and "resume" in r.stdout


def test_info(files, capsys):
    assert main(["info", files[0]]) == 0
    out = capsys.readouterr().out
    assert "area scan" in out and "y=32 × x=32" in out and "periodic" in out


def test_info_errors(tmp_path, capsys):
    assert main(["info", str(tmp_path / "nope.nc")]) == 2
    assert "no such file" in capsys.readouterr().err
    bad = tmp_path / "bad.dat"
    bad.write_bytes(b"\x00garbage")
    assert main(["info", str(bad)]) == 2
    assert "bad.dat" in capsys.readouterr().err


def test_usage_errors_exit_2(capsys):
    with pytest.raises(SystemExit) as e:
        main(["batch", "contact", "x.nc", "-o", "s"])  # --loads missing
    assert e.value.code == 2
    assert main(["batch"]) == 2


def test_convert_roundtrip(files, tmp_path, capsys):
    out = tmp_path / "out.nc"
    assert main(["convert", files[0], "-o", str(out), "--units", "um"]) == 0
    a = xtopo.open_topography(files[0], units="um")
    b = xtopo.open_topography(out, units="um")
    np.testing.assert_allclose(b.height.values, a.height.values)
    assert b.height.attrs["units"] == "um"


def test_convert_surfacetopography_layout(files, tmp_path, capsys):
    out = tmp_path / "st.nc"
    rc = main(["convert", files[0], "-o", str(out), "--layout", "surfacetopography"])
    if getattr(xtopo.io, "to_surfacetopography_netcdf", None) is None:
        assert rc == 2 and "not available" in capsys.readouterr().err
        return
    assert rc == 0
    with xr.open_dataset(out) as ds:
        assert ds["heights"].size == 32 * 32


def test_batch_analyze_local_partial_failure_and_resume(files, tmp_path, capsys):
    bad = tmp_path / "corrupt.nc"
    bad.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 32)
    store = tmp_path / "store"
    argv = ["batch", "analyze", *files, str(bad), "--scheduler", "threads", "--workers", "2", "-q", "-o", str(store)]
    assert main(argv) == 1  # partial failure
    cap = capsys.readouterr()
    assert "corrupt.nc" in cap.err and "3/4 items done" in cap.out
    res = xr.open_dataset(store / "result.nc")
    assert res.sizes["measurement"] == 4 and np.isfinite(res.Sq.values[:3]).all()
    direct = xtopo.analysis.scalars.scalars(xtopo.open_topography(files[1]))
    np.testing.assert_allclose(res.Sq.sel(measurement="surface1.nc").item(), float(direct.Sq))
    res.close()
    assert main(argv) == 1
    assert "(1 chunks computed, 3 reused)" in capsys.readouterr().out
    assert main(["batch", "analyze", str(bad), "--scheduler", "sync", "-q", "-o", str(tmp_path / "s2")]) == 2


def test_batch_unreachable_scheduler(files, tmp_path, capsys):
    import dask

    port = _free_port()
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        rc = main(["batch", "analyze", files[0], "--scheduler", f"tcp://127.0.0.1:{port}", "-q",
                   "-o", str(tmp_path / "store")])
    assert rc == 2 and "cannot connect" in capsys.readouterr().err


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module")
def loopback_scheduler():
    """`dask scheduler` + `dask worker` (2 processes) on 127.0.0.1, started as separate programs."""
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": REPO + os.pathsep + os.environ.get("PYTHONPATH", "")}
    procs = []  # each in its own session, so that stopping it reaches its nannies and workers too
    try:
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                       "--port", str(port), "--no-dashboard"], env=env, start_new_session=True,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address, "--nworkers",
                                       "2", "--nthreads", "1", "--no-dashboard"], env=env, start_new_session=True,
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        with Client(address, timeout="30s") as c:
            c.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for p in reversed(procs):
            _signal_group(p, signal.SIGTERM)
        for p in reversed(procs):
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                _signal_group(p, signal.SIGKILL)
                p.wait(10)


def _signal_group(proc, sig):
    """Signal the session of a process this test started (it and its own children only)."""
    try:
        os.killpg(proc.pid, sig)
    except ProcessLookupError:
        pass


def test_batch_against_separate_dask_scheduler(files, tmp_path, capsys, loopback_scheduler):
    store = tmp_path / "store"
    rc = main(["batch", "analyze", *files, "--scheduler", loopback_scheduler, "-q", "-o", str(store)])
    assert rc == 0, capsys.readouterr().err
    assert "3/3 items done (3 chunks computed, 0 reused)" in capsys.readouterr().out
    with xr.open_dataset(store / "result.nc") as res:
        for i, f in enumerate(files):
            direct = xtopo.analysis.scalars.scalars(xtopo.open_topography(f))
            np.testing.assert_allclose(res.Rq.sel(measurement=os.path.basename(f)).values, direct.Rq.values)
    assert json.load(open(store / "manifest.json"))["status"] == "complete"


def _need_contact():
    try:
        from xtopo.contact import Scene  # noqa: F401
    except ImportError as exc:
        pytest.skip(f"xtopo.contact (issue 5) not available: {exc}")


def test_contact_command(files, tmp_path, capsys):
    _need_contact()
    out = tmp_path / "c.nc"
    assert main(["contact", files[0], "--loads", "1e-14", "2e-14", "--maps", "-o", str(out)]) == 0
    with xr.open_dataset(out) as ds:
        assert ds.sizes["load"] == 2 and "pressure" in ds
        assert ds["pressure"].encoding.get("zlib")  # maps compressed
    assert main(["contact", files[0], "--loads", "1e-14", "2e-14", "-o", str(out)]) == 0
    with xtopo.open_contact(out) as ds:  # scalars by default (issue 26: 33 MB of maps nobody asked for)
        assert ds.sizes["load"] == 2 and "pressure" not in ds and "area_fraction" in ds


def test_contact_command_keeps_the_input_history(files, tmp_path, capsys):
    """The output had only the last load's solve line as history (none with different histories per load):
    the measurement's processing and the contact computation were lost."""
    _need_contact()
    out = tmp_path / "c.nc"
    assert main(["contact", files[0], "--loads", "1e-14", "2e-14", "--hardness", "0.5", "-o", str(out)]) == 0
    before = xtopo.open_topography(files[0]).attrs["history"].split("\n")
    with xr.open_dataset(out) as ds:
        lines = ds.attrs["history"].split("\n")
    assert lines[:len(before)] == before
    contact_lines = [line for line in lines if line.startswith("xtopo contact")]
    assert len(contact_lines) == 1 and "(E* m2)" in contact_lines[0] and "hardness=0.5" in contact_lines[0]


def test_contact_commands_take_mean_pressures(files, tmp_path, capsys):
    """Only --loads (E*·m² for files read in metres) existed: a mean pressure had to be multiplied by the
    scan's area by hand, and `--loads 0.01` on a 1 µm scan meant 1e10 E*."""
    _need_contact()
    by_load, by_pressure = tmp_path / "l.nc", tmp_path / "p.nc"
    assert main(["contact", files[0], "--loads", "1e-14", "2e-14", "-o", str(by_load)]) == 0
    assert main(["contact", files[0], "--mean-pressures", "0.01", "0.02", "-o", str(by_pressure)]) == 0
    assert "mean_pressure [E*]  load [E* m2]  area_fraction" in capsys.readouterr().out
    with xr.open_dataset(by_load) as lo, xr.open_dataset(by_pressure) as pr:
        assert pr["mean_pressure"].attrs["units"] == "E*" and pr["load"].attrs["units"] == "E* m2"
        # the scan is 1 µm × 1 µm: mean pressure 0.01 E* is a load of 1e-14 E*·m²
        np.testing.assert_allclose(pr["load"].values, [1e-14, 2e-14], rtol=1e-12)
        np.testing.assert_array_equal(pr.area_fraction.values, lo.area_fraction.values)
    store = tmp_path / "store"
    assert main(["batch", "contact", *files[:2], "--mean-pressures", "0.01", "--scheduler", "sync", "-q",
                 "-o", str(store)]) == 0
    with xr.open_dataset(store / "result.nc") as res:
        assert dict(res.sizes) == {"measurement": 2, "mean_pressure": 1}
        np.testing.assert_allclose(res["load"].values, 1e-14, rtol=1e-12)
    for command in (["contact", files[0]], ["batch", "contact", files[0], "-o", str(store)]):
        for extra in ([], ["--loads", "1e-14", "--mean-pressures", "0.01"]):
            with pytest.raises(SystemExit) as e:
                main(command + extra)
            assert e.value.code == 2 and "--loads" in capsys.readouterr().err


@pytest.mark.parametrize("command", [["contact"], ["batch", "contact"]])
@pytest.mark.parametrize("given,message", [
    (["--loads", "nan"], "--loads value must be a finite scalar, got nan"),
    (["--loads", "1e-14", "-1"], "--loads value must be ≥ 0 (adhesion is not modelled), got -1.0"),
    (["--mean-pressures", "-0.1"], "--mean-pressures value must be ≥ 0"),
    (["--mean-pressures", "0.01", "2", "--hardness", "1"], "--mean-pressures value 2 reaches the hardness (1)"),
])
def test_contact_commands_name_the_option_in_control_errors(files, tmp_path, capsys, command, given, message):
    """The messages spoke of Python: 'load must be a finite scalar, got nan (use Scene.curve for sequences)', and
    `xtopo contact --mean-pressures 2 --hardness 1` said 'load 2e-12 exceeds hardness × nominal area'."""
    _need_contact()
    out = ["-o", str(tmp_path / ("c.nc" if command == ["contact"] else "store"))]
    assert main([*command, files[0], *given, *out] + (["-q"] if len(command) == 2 else [])) == 2
    err = capsys.readouterr().err
    assert message in err and "Scene.curve" not in err and "exceeds hardness" not in err, err
    assert not (tmp_path / "c.nc").exists() and not (tmp_path / "store").exists()   # checked before any work


def test_contact_command_says_which_mean_pressures_did_not_converge(files, tmp_path, capsys):
    """'some loads did not converge' was printed for --mean-pressures too."""
    _need_contact()
    assert main(["contact", files[0], "--mean-pressures", "0.01", "0.02", "--maxiter", "1",
                 "-o", str(tmp_path / "c.nc")]) == 1
    err = capsys.readouterr().err
    assert "xtopo: warning: contact solve did not converge" in err  # the text, not a path into xtopo (issue 26)
    assert "the solves at --mean-pressures 0.01 0.02 did not converge" in err and "loads" not in err, err


def test_batch_contact_against_separate_dask_scheduler(files, tmp_path, capsys, loopback_scheduler):
    _need_contact()
    store = tmp_path / "store"
    rc = main(["batch", "contact", *files, "--loads", "1e-14", "2e-14", "--scheduler", loopback_scheduler, "-q",
               "-o", str(store)])
    assert rc == 0, capsys.readouterr().err
    with xr.open_dataset(store / "result.nc") as res:
        assert dict(res.sizes) == {"measurement": 3, "load": 2}
        assert np.isfinite(res.area_fraction.values).all()


def test_bad_worker_count_is_a_usage_error(files, tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["batch", "analyze", files[0], "--workers", "0", "-o", str(tmp_path / "s")])
    assert e.value.code == 2 and "at least 1" in capsys.readouterr().err


@pytest.mark.parametrize("command", [["contact"], ["batch", "contact"]])
@pytest.mark.parametrize("option,value", [("--hardness", "-1"), ("--modulus", "0"), ("--tol", "nan"),
                                          ("--maxiter", "0"), ("--hardness", "x")])
def test_contact_scene_options_are_checked_by_the_parser(files, capsys, command, option, value):
    """--hardness -1 reached the library and came back as 'hardness (or None for elastic) must be ...';
    --maxiter 0 and --tol nan likewise spoke Python. The parser names the option (exit code 2)."""
    with pytest.raises(SystemExit) as e:
        main(command + [files[0], "--mean-pressures", "0.01", option, value])
    err = capsys.readouterr().err
    assert e.value.code == 2 and f"argument {option}" in err and "None" not in err, err


def test_batch_commands_detrend_and_fill_on_request(tilted_with_hole, tmp_path, capsys):
    """`xtopo batch analyze|contact` had no --detrend/--fill-missing: a tilted file's scalars were those of its
    tilt, and a file with missing points could not be solved by `batch contact` at all."""
    path, ds = tilted_with_hole
    store = tmp_path / "store"
    flags = ["--detrend", "plane", "--fill-missing"]
    argv = ["batch", "analyze", str(path), "--scheduler", "sync", "-q", "-o", str(store)]
    assert main(argv + flags) == 0, capsys.readouterr().err
    assert "(1 chunks computed, 0 reused)" in capsys.readouterr().out
    want = xtopo.analysis.scalars.scalars(xtopo.preprocess.fill_missing(xtopo.preprocess.detrend(ds, "plane")))
    with xr.open_dataset(store / "result.nc") as res:
        xr.testing.assert_allclose(res[list(want.data_vars)].squeeze("measurement", drop=True), want, rtol=1e-12)
        assert "detrend(mode='plane'" in str(res.history.item()) and "fill_missing" in str(res.history.item())
    assert main(argv + flags) == 0 and "(0 chunks computed, 1 reused)" in capsys.readouterr().out
    assert main(argv) == 0 and "(1 chunks computed, 0 reused)" in capsys.readouterr().out  # as read: another key
    with xr.open_dataset(store / "result.nc") as res:
        np.testing.assert_allclose(res.Sq.values, float(xtopo.analysis.scalars.scalars(ds).Sq), rtol=1e-12)

    _need_contact()
    argv = ["batch", "contact", str(path), "--mean-pressures", "0.01", "--scheduler", "sync", "-q",
            "-o", str(tmp_path / "contact")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "40 points have no height" in err and "--fill-missing" in err, err
    assert main(argv + flags) == 0, capsys.readouterr().err
    with xr.open_dataset(tmp_path / "contact" / "result.nc") as res:
        assert bool(res.converged.all()) and "fill_missing" in str(res.history.item())


@pytest.mark.parametrize("command,extra", [("analyze", []), ("contact", ["--mean-pressures", "0.01"])])
def test_batch_detrend_mode_is_checked_by_the_parser(files, tmp_path, capsys, command, extra):
    with pytest.raises(SystemExit) as e:
        main(["batch", command, files[0], *extra, "--detrend", "tilt", "-o", str(tmp_path / "s")])
    assert e.value.code == 2 and "argument --detrend: invalid choice: 'tilt'" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()
