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
