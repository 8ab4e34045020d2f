"""Capped (plastic) contact under load control converges within the default ``maxiter`` (issue 26).

The penetration search of a capped load-controlled solve starts at the elastic solution's
penetration (a lower bound), grows its bracket by the secant, and warm-starts each solve
from pressures interpolated between the bracket ends, keeping the free and plastic points of the nearer end;
the solves far from the root are coarse (inner tolerance 1e-3), only those near it meet ``tol``
(:mod:`xtopo._kernels.pk_solver`). hfm-1.hfm (a 4.8 mm line scan, plane strain, 99 % in contact) needed
1505 iterations (313 elastic + 6 inner solves of 230-333 at full tolerance); now 889.
"""

import importlib.util
import pathlib
import warnings

import numpy as np
import pytest

import xtopo
from xtopo.contact import Scene
from xtopo.errors import ConvergenceWarning, XtopoError

REAL_DATA = pathlib.Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"

#: the issue's scene: E* = 2 GPa, hardness 100 MPa, mean pressure half the hardness
MODULUS, HARDNESS, PRESSURE = 2e9, 1e8, 5e7


def _real_files():
    if not REAL_DATA.is_dir():
        return []
    return sorted(p.name for p in REAL_DATA.iterdir() if p.is_file() and p.suffix != ".md")


def test_capped_solve_where_the_elastic_deflection_dominates():
    """H/E* = 0.05 at p = H/2: the penetration is many times the roughness; the search starts at the elastic
    penetration instead of the rigid-plastic one (464 iterations before issue 26, 229 with it, 151 with coarse
    solves far from the root)."""
    ds = xtopo.datasets.fractal_surface((128, 128), 1e-5, hurst=0.8, rms_height=1e-8, periodic=False, seed=4)
    r = Scene(ds, modulus=MODULUS, hardness=HARDNESS).solve(mean_pressure=PRESSURE)
    assert bool(r.converged)
    assert int(r.iterations) <= 300
    assert float(r.mean_pressure) == pytest.approx(PRESSURE, rel=1e-5)
    assert float(r.pressure.max()) <= HARDNESS


def test_capped_solve_on_a_long_line_scan_in_full_contact():
    """A 4.8 mm line scan of 8192 points (plane strain, like hfm-1.hfm) pressed into full contact with 13 %
    plastic: every warm-started solve costs ~100 iterations a decade of the residual, so the penetration search
    solves coarsely far from the root (1250 iterations before, past the default maxiter; 676 now)."""
    ds = xtopo.datasets.fractal_surface((8192,), 4.8e-3, hurst=0.8, rms_height=5e-7, periodic=False, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConvergenceWarning)
        r = Scene(ds, modulus=MODULUS, hardness=HARDNESS).solve(mean_pressure=PRESSURE)
    assert bool(r.converged) and float(r.residual) <= float(r.attrs["tolerance"])
    assert float(r.mean_pressure) == pytest.approx(PRESSURE, rel=1e-5)
    assert float(r.area_fraction) == 1 and 0 < float(r.plastic.mean()) < 0.5
    assert float(r.pressure.max()) <= HARDNESS


@pytest.mark.slow
@pytest.mark.parametrize("name", _real_files() or ["(no real data)"])
def test_capped_contact_on_real_files_converges(name):
    """Every shared real file without missing data, and opd-1.opd with its holes filled, converges at the
    issue's settings within the default maxiter (1000)."""
    path = REAL_DATA / name
    if not path.is_file():
        pytest.skip(f"real data {REAL_DATA} not present")
    try:
        ds = xtopo.open_topography(path)
    except XtopoError as exc:  # reading is tested elsewhere
        pytest.skip(f"{name} is not read: {exc}")
    missing = int((~np.isfinite(ds["height"].values)).sum())
    if missing and name != "opd-1.opd":
        pytest.skip(f"{name} has {missing} missing points")
    if missing:
        ds = ds.topo.fill_missing()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConvergenceWarning)
        r = Scene(ds, modulus=MODULUS, hardness=HARDNESS).solve(mean_pressure=PRESSURE)
    assert bool(r.converged), (int(r.iterations), float(r.residual))
    assert float(r.mean_pressure) == pytest.approx(PRESSURE, rel=1e-4)


def _unconverged(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    found = [w for w in caught if issubclass(w.category, ConvergenceWarning)]
    assert found
    return found


@pytest.mark.parametrize("how", ["solve", "curve", "contact"])
def test_convergence_warning_points_at_the_callers_line(how):
    """The warning names the user's file and line, not xtopo's internals (issue 26)."""
    ds = xtopo.datasets.fractal_surface((32, 32), 1e-5, hurst=0.8, rms_height=1e-8, periodic=False, seed=1)
    sc = Scene(ds, modulus=MODULUS, hardness=HARDNESS)
    calls = {"solve": lambda: sc.solve(mean_pressure=PRESSURE, maxiter=2),
             "curve": lambda: sc.curve(mean_pressures=[PRESSURE], maxiter=2),
             "contact": lambda: xtopo.contact.contact(ds, mean_pressure=PRESSURE, modulus=MODULUS, maxiter=2)}
    for w in _unconverged(calls[how]):
        assert pathlib.Path(w.filename).resolve() == pathlib.Path(__file__).resolve()


def test_convergence_warning_on_the_command_line(tmp_path):
    """The command prints the warning's text without a path into the library."""
    import subprocess
    import sys

    ds = xtopo.datasets.fractal_surface((32, 32), 1e-5, hurst=0.8, rms_height=1e-8, periodic=False, seed=1)
    src = tmp_path / "s.nc"
    xtopo.to_netcdf(ds, src)
    root = pathlib.Path(__file__).resolve().parents[2]
    out = subprocess.run([sys.executable, "-m", "xtopo", "contact", str(src), "--modulus", "2e9", "--hardness",
                          "1e8", "--mean-pressures", "5e7", "--maxiter", "2", "-o", str(tmp_path / "c.nc")],
                         capture_output=True, text=True, cwd=root, env={**__import__("os").environ,
                                                                         "PYTHONPATH": str(root)})
    assert "xtopo: warning: contact solve did not converge" in out.stderr
    assert ".py:" not in out.stderr


def test_physical_modulus_gives_physical_units_and_a_mean_pressure_curve():
    """A modulus in Pa labels pressures in Pa (not E*); a curve given mean pressures runs along mean_pressure."""
    ds = xtopo.datasets.fractal_surface((32, 32), 1e-5, hurst=0.8, rms_height=1e-8, periodic=False, seed=1)
    cur = Scene(ds, modulus=MODULUS).curve(mean_pressures=[1e6, 2e6])
    assert cur["area_fraction"].dims == ("mean_pressure",)
    assert cur["mean_pressure"].attrs["units"] == "Pa" and cur["load"].attrs["units"] == "Pa m2"
    assert cur.attrs["modulus_units"] == "Pa"
    cur.area_fraction.plot(x="mean_pressure")  # the call
    if importlib.util.find_spec("holoviews") is not None:  # the figure's axis: Pa, not p/E*
        axis = xtopo.plot.contact_area(cur).Curve.I.kdims[0]
        assert axis.unit == "Pa" and "E*" not in axis.label
    assert Scene(ds).solve(mean_pressure=1e-3)["pressure"].attrs["units"] == "E*"  # the default modulus 1
