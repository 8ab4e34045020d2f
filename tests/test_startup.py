"""``import xtopo`` and ``xtopo --version``/``--help`` load no heavy dependency (issue 26; times in
benchmarks/bench_startup.py — no wall-time assertion here)."""

import os
import pathlib
import subprocess
import sys

REPO = pathlib.Path(__file__).resolve().parents[1]
HEAVY = ["dask", "distributed", "holoviews", "bokeh", "numba", "netCDF4", "h5netcdf", "scipy", "matplotlib",
         "pint", "tqdm"]


def _loaded(code, *args):
    out = subprocess.run([sys.executable, *args, "-c", code + "\nimport sys, json; print(json.dumps(sorted(sys.modules)))"],
                         capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(REPO)}, check=True)
    return set(__import__("json").loads(out.stdout.splitlines()[-1]))


def test_import_xtopo_loads_no_heavy_dependency():
    loaded = _loaded("import xtopo")
    assert not [m for m in HEAVY if m in loaded]  # imported by the first function that needs them


def test_the_command_line_answers_version_and_help_without_numpy():
    for flag in ("--version", "--help"):  # as the xtopo script runs it (argv[0] is the script)
        loaded = _loaded(f"import sys; sys.argv = ['/usr/bin/xtopo', {flag!r}]\nfrom xtopo.cli import main\ntry:\n"
                         "    main()\nexcept SystemExit:\n    pass")
        assert "numpy" not in loaded and "xarray" not in loaded, flag


def test_accessors_are_registered_whichever_is_imported_first():
    for code in ("import xtopo, xarray as xr", "import xarray as xr, xtopo", "import xtopo\nxtopo.datasets"):
        out = subprocess.run([sys.executable, "-c", code + "\nimport xarray as xr\nprint(hasattr(xr.Dataset, 'topo'),"
                              " hasattr(xr.DataArray, 'topo'), hasattr(xr.DataTree, 'topo'))"],
                             capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(REPO)})
        assert out.stdout.split() == ["True", "True", "True"], (code, out.stderr)
