import subprocess
import sys

import numpy as np
import pytest

import xtopo
from xtopo.cli import main


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
    assert set(tree.children) == {"psd", "acf", "vbm", "sdrp"}
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
         "unknown analysis 'bogus'"),
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


def test_analyze_says_how_many_measurements_each_average_holds(tmp_path, capsys):
    """The line under the table gave the largest per-point count ('psd average over 1 measurements')
    for a twin whose measurements do not overlap in scale, as if the others had been dropped;
    it now counts the measurements in the average and names those that add no reliable point."""
    fine = tmp_path / "fine.nc"
    coarse = tmp_path / "coarse.nc"
    blurred = tmp_path / "blurred.nc"
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((64, 64), 1e-6, hurst=0.8, seed=1), fine)
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((64, 64), 1e-2, hurst=0.8, seed=2), coarse)
    # a resolution as large as the scan: nothing of it is reliable
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((64, 64), 1e-4, hurst=0.8, seed=3)
                    .assign_attrs(resolution=1e-4, resolution_units="m"), blurred)
    assert main(["analyze", str(fine), str(coarse), str(blurred), "-o", str(tmp_path / "out.nc")]) == 0
    lines = capsys.readouterr().out.splitlines()
    vbm = lines.index(next(ln for ln in lines if ln.startswith("vbm ")))
    assert lines[vbm].startswith("vbm   average of 2 of 3 measurements at ")
    assert "no reliable point from blurred.nc" in lines[vbm + 1]
