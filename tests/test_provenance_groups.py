"""Provenance of `xtopo analyze` output (issue 26): each step once in the history, measurement names in
every group of the file."""

import os
import pathlib
import subprocess
import sys

import xarray as xr

import xtopo

REPO = pathlib.Path(__file__).resolve().parents[1]


def test_analyze_history_and_group_labels(tmp_path, tilted_with_hole):
    path, _ = tilted_with_hole
    other = tmp_path / "other.nc"
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((32, 32), 1e-6, hurst=0.8, rms_height=1e-9, seed=3), other)
    out = tmp_path / "a.nc"
    run = subprocess.run([sys.executable, "-m", "xtopo", "analyze", str(path), str(other), "--detrend", "plane",
                          "--fill-missing", "-o", str(out)], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(REPO)})
    assert run.returncode == 0, run.stderr
    for group in ("psd", "acf", "vbm", "sdrp"):
        with xr.open_dataset(out, group=group) as ds:  # a group opened on its own is labelled
            assert ds["measurement"].values.tolist() == ["tilted.nc", "other.nc"]
            for line in ds["history"].values:  # each measurement's preprocessing, each step once
                assert line.count("fill_missing") == 1 and line.count("detrend") == 1, line
    with xr.open_datatree(out) as tree:  # and the tree reads back with the names inherited
        assert tree["psd"]["measurement"].values.tolist() == ["tilted.nc", "other.nc"]

