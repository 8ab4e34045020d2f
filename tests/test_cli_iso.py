"""ISO parameters and filtration through the real command line and in batches (issue 22)."""

import os
import subprocess
import sys

import numpy as np
import pytest
import xarray as xr

import xtopo
from xtopo.conventions import make_measurement
from xtopo.stitching import ANALYSES

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
A, LAM = 1e-6, 100e-6  # m: amplitude 1 µm, wavelength 0.1 mm


def _xtopo(*args, cwd=None):
    env = {**os.environ, "PYTHONPATH": REPO + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run([sys.executable, "-m", "xtopo", *map(str, args)], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=300)


@pytest.fixture
def cosine_file(tmp_path):
    """A 6 mm cosine profile (λ = 0.1 mm, A = 1 µm) on 2 µm spacing, written as xtopo NetCDF."""
    dx = 2e-6
    x = np.arange(3000) * dx
    path = tmp_path / "cosine.nc"
    xtopo.to_netcdf(make_measurement(A * np.cos(2 * np.pi * x / LAM), spacing=dx, units="m", name="cosine"), path)
    return path


def test_analyze_iso_prints_and_stores_the_profile_set(cosine_file, tmp_path):
    out = tmp_path / "a.nc"
    r = _xtopo("analyze", cosine_file, "--iso", "--lambda-c", "1.2 mm", "--lambda-s", "auto", "-o", out)
    assert r.returncode == 0, r.stderr
    assert "ISO parameters (lambda_s=auto, lambda_c=1.2 mm)" in r.stdout
    assert "3.75 µm   1.2 mm" in r.stdout  # the cut-offs used: λs by the ISO 3274 ratio (1.2 mm/320)
    line = [ln for ln in r.stdout.splitlines() if ln.startswith("cosine")][-1]  # the ISO table, after the summary
    assert "637 nm" in line  # Ra = 2A/π (the table's row), λs = 1.2 mm / 320 = 3.75 µm passes λ = 0.1 mm
    assert f"groups: summary at the root, {', '.join(ANALYSES)}, iso" in r.stdout
    iso = xr.open_datatree(out)["iso"].to_dataset()  # the measurement coordinate is inherited from the root
    assert float(iso.Ra.sel(measurement="cosine.nc")) == pytest.approx(2 * A / np.pi, rel=2e-3)
    assert float(iso.Rz.sel(measurement="cosine.nc")) == pytest.approx(2 * A, rel=2e-3)
    assert iso.Ra.attrs["units"] == "m" and iso.Rmr1.attrs["units"] == "%"


def test_iso_failure_is_reported_and_is_a_partial_failure(cosine_file, tmp_path):
    r = _xtopo("analyze", cosine_file, "--iso", "--lambda-c", "8 mm", "-o", tmp_path / "a.nc")
    assert r.returncode == 1
    assert "ISO parameters of cosine.nc: lambda_c=0.008 m is longer than the measurement" in r.stderr


def test_info_shows_the_iso_values(cosine_file, capsys):
    from xtopo.cli import main

    r = _xtopo("info", cosine_file, "--iso")
    assert r.returncode == 0, r.stderr
    assert "ISO parameters (lambda_s=none, lambda_c=none)" in r.stdout and "Rk" in r.stdout
    assert main(["info", str(cosine_file)]) == 0
    assert "ISO parameters" not in capsys.readouterr().out


@pytest.mark.slow  # bokeh in a fresh interpreter: 4-15 s on 2 shared cores
def test_report_has_an_iso_table(cosine_file, tmp_path):
    page = tmp_path / "r.html"
    r = _xtopo("report", cosine_file, "--iso", "--lambda-c", "0.8 mm", "--analyses", "none", "-o", page)
    assert r.returncode == 0, r.stderr
    text = page.read_text()
    assert "<h2>ISO parameters</h2>" in text and "lambda_c = 0.8 mm" in text and "<th>Rpk</th>" in text


def test_batch_analyze_runs_the_profile_set(cosine_file, tmp_path):
    store = tmp_path / "store"
    r = _xtopo("batch", "analyze", cosine_file, cosine_file, "--analyses", "iso21920", "scalars", "-o", store,
               "--scheduler", "sync", "-q")
    assert r.returncode == 0, r.stderr
    res = xr.open_dataset(store / "result.nc")
    np.testing.assert_allclose(res.iso21920_Ra, 2 * A / np.pi, rtol=2e-3)
    assert res.iso21920_Ra.attrs["units"] == "m"


def test_batch_preprocess_filter_step_then_profile_set(cosine_file):
    """A batch filters (``preprocess={"filter": ...}``, recorded in history) before the analyses."""
    from xtopo.batch import analyze

    base = xtopo.open_topography(cosine_file)
    wavy = base.assign(height=base.height + 5e-6 * np.sin(2 * np.pi * base.x / 3e-3))  # λ = 3 mm waviness
    res = analyze({"wavy": wavy}, analyses="iso21920", scheduler="sync", progress=False,
                  preprocess={"filter": {"lambda_s": None, "lambda_c": "0.5 mm", "form": "line"}})
    assert float(res.Ra.sel(measurement="wavy")) == pytest.approx(2 * A / np.pi, rel=1e-2)  # waviness filtered out


def test_iso_table_keeps_every_measurement_and_says_what_failed():
    from xtopo.analysis._iso_sets import format_iso_table, iso_table

    area = xtopo.datasets.fractal_surface((32, 64), (32e-6, 64e-6), hurst=0.8, rms_height=1e-8, seed=1)
    x = np.arange(6000) * 1e-6
    line = make_measurement(A * np.cos(2 * np.pi * x / LAM), spacing=1e-6, units="m")
    table, errors = iso_table({"area": area, "line": line}, lambda_c=1e-3)  # λc = 10 λ: transmission ≈ 1
    assert list(errors) == ["area"] and "longer than the measurement" in errors["area"]
    assert np.isnan(float(table.Ra.sel(measurement="area")))
    assert float(table.Ra.sel(measurement="line")) == pytest.approx(2 * A / np.pi, rel=2e-3)
    header, rows = format_iso_table(table)
    assert header[:5] == ["measurement", "lambda_s", "lambda_c", "Ra", "Rq"]
    assert rows[0][3] == "-" and rows[1][3] in ("636 nm", "637 nm") and rows[1][2] == "1 mm"
    assert np.isnan(float(table.lambda_s.sel(measurement="line")))  # no S-filter asked for
    every_line, _ = iso_table({"area": area})
    assert "mean over the profiles" in every_line.Ra.attrs["long_name"]
