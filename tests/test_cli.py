import subprocess
import sys

import numpy as np
import pytest

import xtopo
from xtopo.cli import main
from xtopo.stitching import ANALYSES


def test_analyze_example_twin_prints_table_and_writes_netcdf(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["analyze"]) == 0
    out = capsys.readouterr().out
    assert "example twin" in out and "afm-5um" in out and "Sq/Rq" in out and "psd   average" in out
    import xarray as xr

    ds = xr.open_dataset(tmp_path / "xtopo-analysis.nc")
    assert ds.sizes["measurement"] >= 6
    assert ds.rms_height.attrs["units"] == "m"
    assert np.all(np.isfinite(ds.rms_slope.values))
    ds.close()
    tree = xr.open_datatree(tmp_path / "xtopo-analysis.nc")
    assert set(tree.children) == set(ANALYSES)  # one group per declared twin analysis
    assert tree["psd"]["average"].attrs["units"] == "m3"
    assert int(tree["psd"]["count"].max()) >= 2


def test_analyze_files_reports_bad_file_and_keeps_good(tmp_path, capsys):
    good = tmp_path / "good.nc"
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((32, 32), 1e-6, hurst=0.7), good)
    bad = tmp_path / "bad.xyz"
    bad.write_bytes(b"\x00\x01garbage")
    rc = main(["analyze", str(good), str(bad), "-o", str(tmp_path / "out.nc")])
    captured = capsys.readouterr()
    assert rc == 1  # partial failure
    assert "bad.xyz" in captured.err
    assert "good.nc" in captured.out
    assert (tmp_path / "out.nc").exists()


def _container_twin(seed):
    area = xtopo.datasets.fractal_surface((32, 48), (1e-6, 1.5e-6), hurst=0.8, rms_height=1e-8, periodic=False,
                                          seed=seed).assign_attrs(tip_radius=2e-8, tip_radius_units="m")
    line = xtopo.datasets.fractal_surface(400, 2e-5, hurst=0.8, rms_height=5e-8, periodic=False, seed=seed + 1)
    return xtopo.twin({"afm": area, "stylus": line}, name=f"sample {seed}")


def test_analyze_a_contact_engineering_download(tmp_path, capsys):
    """`xtopo analyze download.zip` read the ZIP as one (unreadable) file; now it is the twin open_twin gives, with
    the same outputs as for files, and --surface picks one surface of a container holding several."""
    import xarray as xr

    one = xtopo.to_container(_container_twin(0), tmp_path / "one.zip")
    out = tmp_path / "one.nc"
    assert main(["analyze", str(one), "-o", str(out), "-q"]) == 0
    printed = capsys.readouterr().out
    assert "2 measurements" in printed and "afm" in printed and "stylus" in printed
    tree = xr.open_datatree(out)
    assert set(tree.children) == set(ANALYSES) and list(tree["psd"]["measurement"].values) == [
        "afm", "stylus"]
    expected = xtopo.open_twin(one).topo.psd()
    np.testing.assert_allclose(tree["psd"]["average"].values, expected.average.values, rtol=1e-12)
    tree.close()

    two = xtopo.to_container({"first": _container_twin(0), "second": _container_twin(1)}, tmp_path / "two.zip")
    assert main(["analyze", str(two), "-o", str(tmp_path / "two.nc"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "--surface" in err and "'first', 'second'" in err  # names the option and the surfaces to choose from
    for choice in ("second", "1"):
        assert main(["analyze", str(two), "--surface", choice, "-o", str(tmp_path / "two.nc"), "-q"]) == 0
        capsys.readouterr()
        with xr.open_datatree(tmp_path / "two.nc") as got:
            want = xtopo.open_twin(two, surface="second").topo.vbm()
            np.testing.assert_allclose(got["vbm"]["average"].values, want.average.values, rtol=1e-12)
    html = tmp_path / "two.html"
    assert main(["report", str(two), "--surface", "first", "-o", str(html), "--analyses", "psd", "-q"]) == 0
    assert html.stat().st_size > 0


def test_console_script_help():
    r = subprocess.run([sys.executable, "-m", "xtopo.cli", "analyze", "--help"], capture_output=True, text=True)
    assert r.returncode == 0 and "example twin" in r.stdout


def test_bad_arguments_give_one_clear_error_line(tmp_path, capsys):
    """`info DIR` said 'no such file'; `convert -o` into a missing directory named the temporary file
    ('.x.nc.abc123.tmp'); `report --analyses bogus` wrote a page and exited 0."""
    good = tmp_path / "m.nc"
    xtopo.to_netcdf(xtopo.datasets.measure(xtopo.datasets.fractal_surface((16, 16), (1e-6, 1e-6), hurst=0.8)), good)
    cases = [
        (["info", str(tmp_path)], f"{tmp_path}: is a directory"),
        (["convert", str(good), "-o", str(tmp_path / "missing" / "x.nc")],
         f"cannot write {tmp_path / 'missing' / 'x.nc'}: No such file or directory"),
        (["convert", str(good), "-o", str(tmp_path)], f"cannot write {tmp_path}: "),
        (["report", str(good), "--analyses", "psd,bogus", "-o", str(tmp_path / "r.html")],
         "--analyses: analyses must be a name or a sequence of names from ('psd', "),
    ]
    for argv, message in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("xtopo: error: ") and message in err[0], (argv, err)
    assert not (tmp_path / "r.html").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.nc"]  # no temporary file left behind


def test_generic_files_need_their_size_and_unit_on_the_command_line(tmp_path, capsys):
    """A plain text matrix stores neither size nor unit: the CLI takes them as options (it could not read one)."""
    heights = np.random.default_rng(0).standard_normal((12, 20))
    src = tmp_path / "matrix.txt"
    np.savetxt(src, heights)
    assert main(["info", str(src)]) == 2
    assert "command line: --file-units" in capsys.readouterr().err
    assert main(["info", str(src), "--file-units", "um"]) == 2
    assert "--physical-size Ly Lx" in capsys.readouterr().err
    out = tmp_path / "matrix.nc"
    assert main(["convert", str(src), "-o", str(out), "--file-units", "um", "--physical-size", "3", "5",
                 "--units", "um"]) == 0
    ds = xtopo.io.open_topography(out, units="um")
    np.testing.assert_allclose(ds.height.values, heights, rtol=1e-12)
    assert float(ds.x[1] - ds.x[0]) == pytest.approx(5 / 20) and float(ds.y[1] - ds.y[0]) == pytest.approx(3 / 12)
    capsys.readouterr()
    assert main(["analyze", str(src), "--file-units", "um", "--physical-size", "3", "5",
                 "-o", str(tmp_path / "a.nc")]) == 0
    assert main(["info", str(src), "--file-units", "um", "--physical-size", "1", "2", "3"]) == 2
    assert "does not match a 2D measurement" in capsys.readouterr().err


def test_python_dash_m_runs_the_command_line():
    out = subprocess.run([sys.executable, "-m", "xtopo", "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.startswith("xtopo ")


def test_a_closed_stdout_does_not_stop_the_command(tmp_path):
    """`xtopo contact FILE ... | head -1`: the reader leaving early used to abort the command before it wrote its
    output file ("xtopo: error: [Errno 32] Broken pipe", exit code 2) when stdout is unbuffered."""
    import os
    import pathlib

    src = xtopo.to_netcdf(xtopo.datasets.fractal_surface((32, 32), 1e-6, hurst=0.8, rms_height=1e-8),
                          tmp_path / "small.nc")
    repo = str(pathlib.Path(__file__).resolve().parents[1])
    env = dict(os.environ, PYTHONUNBUFFERED="1",
               PYTHONPATH=os.pathsep.join(p for p in (repo, os.environ.get("PYTHONPATH")) if p))
    p = subprocess.Popen([sys.executable, "-m", "xtopo", "contact", src, "--mean-pressures", "0.01", "-o",
                          str(tmp_path / "out.nc")], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    p.stdout.close()  # the reader is gone before the command prints anything
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 0, err
    assert "Broken pipe" not in err and "BrokenPipeError" not in err
    import xarray as xr

    with xr.open_dataset(tmp_path / "out.nc") as res:
        assert res["mean_pressure"].values.ravel().tolist() == pytest.approx([0.01])


def test_analyze_says_how_many_measurements_each_average_holds(tmp_path, capsys):
    """The line under the table gave the largest per-point count ('psd average over 1 measurements')
    for a twin whose measurements do not overlap in scale, as if the others had been dropped;
    it now counts the measurements in the average and names those that add no reliable point."""
    fine = tmp_path / "fine.nc"
    coarse = tmp_path / "coarse.nc"
    blurred = tmp_path / "blurred.nc"
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((64, 64), 1e-6, hurst=0.8, seed=1), fine)
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((64, 64), 1e-2, hurst=0.8, seed=2), coarse)
    # a resolution larger than the scan: nothing of it is reliable
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((64, 64), 1e-4, hurst=0.8, seed=3)
                    .assign_attrs(resolution=2e-4, resolution_units="m"), blurred)
    assert main(["analyze", str(fine), str(coarse), str(blurred), "-o", str(tmp_path / "out.nc")]) == 0
    lines = capsys.readouterr().out.splitlines()
    vbm = lines.index(next(ln for ln in lines if ln.startswith("vbm ")))
    assert lines[vbm].startswith("vbm   average of 2 of 3 measurements at ")
    assert "no reliable point from blurred.nc" in lines[vbm + 1]


def test_analyze_and_convert_detrend_and_fill_on_request(tmp_path, capsys, tilted_with_hole):
    """The command line could not detrend or fill: real (tilted) files were analysed as read, and
    their Sq was that of the sample tilt. --detrend/--fill-missing run the library's steps."""
    path, ds = tilted_with_hole
    want = xtopo.preprocess.fill_missing(xtopo.preprocess.detrend(ds, "plane"))
    assert main(["analyze", str(path), "--detrend", "plane", "--fill-missing", "-o", str(tmp_path / "a.nc")]) == 0
    import xarray as xr

    with xr.open_dataset(tmp_path / "a.nc") as table:
        np.testing.assert_allclose(table.rms_height.values, [float(want.topo.scalars().Sq)], rtol=1e-12)
        assert table.missing_percent.values[0] == 0
    assert main(["convert", str(path), "--detrend", "plane", "--fill-missing", "-o", str(tmp_path / "c.nc")]) == 0
    back = xtopo.open_topography(tmp_path / "c.nc")
    xr.testing.assert_allclose(back.height, want.height)
    assert "detrend(mode='plane'" in back.attrs["history"] and "fill_missing" in back.attrs["history"]


def test_contact_names_the_option_for_missing_data(tmp_path, capsys, tilted_with_hole):
    """On a file with missing data `xtopo contact` said 'fill them first (e.g. xtopo.preprocess.fill_missing)',
    a Python function the command line had no way to call; it names --fill-missing, which works."""
    path, _ = tilted_with_hole
    out = tmp_path / "c.nc"
    assert main(["contact", str(path), "--mean-pressures", "0.01", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "40 points have no height" in err and "--fill-missing" in err and not out.exists()
    assert main(["contact", str(path), "--mean-pressures", "0.01", "--detrend", "plane", "--fill-missing",
                 "-o", str(out)]) == 0
    import xarray as xr

    with xr.open_dataset(out) as res:
        assert bool(res["converged"].all()) and "fill_missing" in res.attrs["history"]


def test_a_few_missing_points_are_not_printed_as_none(tmp_path, capsys):
    """`xtopo info` and the `analyze` table printed 'missing 0.0 %' for opd-1.opd (116 undefined pixels),
    which `xtopo contact` then refused; info gives the count, the table '<0.1 %'."""
    ds = xtopo.datasets.fractal_surface((64, 64), 1e-6, hurst=0.8, periodic=False)
    ds["mask"] = (ds.height.dims, np.zeros(ds.height.shape, bool))
    ds["mask"][3, 5] = True
    path = tmp_path / "one_hole.nc"
    xtopo.to_netcdf(ds, path)
    assert main(["info", str(path)]) == 0
    assert "missing 1 points (<0.1 %)" in capsys.readouterr().out
    assert main(["analyze", str(path), "-o", str(tmp_path / "a.nc")]) == 0
    row = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("one_hole.nc"))
    assert "<0.1 %" in row
    assert main(["analyze", str(path), "--fill-missing", "-o", str(tmp_path / "b.nc")]) == 0
    row = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("one_hole.nc"))
    assert " 0.0 % " in row
