"""The extras of pyproject.toml mean something: the core install reads, analyses and writes; a feature whose
extra is missing says which one to install. Missing packages are simulated (``sys.modules[name] = None``),
nothing is uninstalled."""

import os
import pathlib
import subprocess
import sys
import tomllib

import numpy as np
import pytest

import xtopo
from xtopo._optional import EXTRAS, require

REPO = pathlib.Path(__file__).resolve().parents[1]
PROJECT = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def _names(requirements) -> set[str]:
    return {r.split(";")[0].split("[")[0].split(">")[0].split("=")[0].split("<")[0].strip().lower()
            for r in requirements}


def test_optional_packages_are_in_their_extra_and_not_in_the_core():
    extras = PROJECT["optional-dependencies"]
    core = _names(PROJECT["dependencies"])
    for module, extra in EXTRAS.items():
        assert module.lower() not in core, module
        assert module.lower() in _names(extras[extra]), (module, extra)
    assert "numba" in core  # the kernels are compiled: not optional
    assert set(extras["all"][0].split("[")[1].rstrip("]").split(",")) == {"dask", "io", "plot", "fftw"}
    assert "xtopo[all]" in extras["test"]  # README's test command installs every feature


@pytest.fixture
def ds():
    return xtopo.datasets.fractal_surface((32, 32), 1e-6, hurst=0.8, rms_slope=0.1, seed=1)


@pytest.mark.parametrize("missing,extra,call", [
    ("holoviews", "plot", lambda ds: xtopo.plot.plot(ds)),
    ("bokeh", "plot", lambda ds: xtopo.report.report(ds, maps=False)),
    ("dask", "dask", lambda ds: xtopo.batch.analyze({"a": ds}, ["scalars"], scheduler="sync", progress=False)),
    ("dask", "dask", lambda ds: xtopo.cache.Cache(memory_bytes=0)(xtopo.analysis.scalars.scalars, ds)),
])
def test_a_missing_extra_is_named(monkeypatch, ds, missing, extra, call):
    for name in [m for m in sys.modules if m == missing or m.startswith(missing + ".")]:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setitem(sys.modules, missing, None)
    with pytest.raises(xtopo.XtopoError, match=rf'needs {missing}, which is not installed: pip install "xtopo\[{extra}\]"'):
        call(ds)


def test_a_module_missing_inside_an_installed_package_is_not_blamed_on_an_extra():
    with pytest.raises(ModuleNotFoundError):
        require("numpy.no_such_module", "this test")


def test_the_core_install_reads_analyses_and_writes(tmp_path):
    """Without any extra (dask, distributed, holoviews, bokeh, matplotlib, pyFFTW, netCDF4, zstandard
    blocked): a file read into a twin, every twin analysis and the summary, the results written."""
    src = tmp_path / "scan.nc"
    xtopo.to_netcdf(xtopo.datasets.fractal_surface((64, 64), 1e-6, hurst=0.8, rms_slope=0.1, seed=2), src)
    out = tmp_path / "out.nc"
    code = (f"import sys\nfor m in {sorted(EXTRAS)!r}:\n    sys.modules[m] = None\n"
            "from xtopo.cli import main\n"
            f"rc = main(['analyze', {str(src)!r}, '-o', {str(out)!r}])\n"
            f"print('loaded', sorted(m for m in {sorted(EXTRAS)!r} if sys.modules.get(m) is not None))\n"
            "sys.exit(rc)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(REPO)})
    assert r.returncode == 0, r.stderr
    assert "loaded []" in r.stdout and out.stat().st_size > 0
    with xtopo.io.netcdf.read_netcdf(out) as res:  # the summary at the root
        assert np.isfinite(res["rms_height"].values).all()
