"""The convolution's halves (forward / Parseval energy / inverse) and the solver built on them."""

import os

import numpy as np
import xarray as xr
import pytest

from xtopo._kernels import compiled, convolution as conv_mod
from xtopo._kernels.convolution import Convolution
from xtopo._kernels.fft import choose_backend
from xtopo._kernels.pk_solver import polonsky_keer
from xtopo.errors import XtopoError

SHAPES = [(6, 5), (8, 8), (7,), (12,)]


@pytest.mark.parametrize("backend", ["scipy", "pyfftw"])
@pytest.mark.parametrize("periodic", [True, False])
@pytest.mark.parametrize("shape", SHAPES)
def test_energy_is_parseval_of_the_convolution(shape, periodic, backend):
    rng = np.random.default_rng(3)
    c = Convolution(shape, (0.4, 0.9)[: len(shape)], 1.7, periodic=periodic, backend=backend)
    p = rng.standard_normal(shape)
    u = c(p).copy()
    c.input[...] = p
    energy = c.energy(c.forward())
    np.testing.assert_allclose(energy, float(np.sum(p * u)), rtol=1e-12)
    # the inverse of the buffered spectrum is the same convolution
    c.input[...] = p
    np.testing.assert_allclose(c.inverse(c.forward()), u, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("backend", ["scipy", "pyfftw"])
@pytest.mark.parametrize("periodic", [True, False])
def test_sparse_writes_through_buffer_layout(periodic, backend):
    """Writing a few pixels by flat index leaves the zero padding intact: same as a full call."""
    shape = (5, 7)
    c = Convolution(shape, (1.0, 1.0), periodic=periodic, backend=backend)
    c.input_flat.fill(0)
    idx = np.array([0, 8, 34])
    c.input_flat[compiled.slots(idx, *c.buffer_layout)] = [1.0, 2.0, -0.5]
    p = np.zeros(shape)
    p.flat[idx] = [1.0, 2.0, -0.5]
    got = np.array(c.inverse(c.forward()))
    c.input_flat.fill(0)
    np.testing.assert_allclose(got, Convolution(shape, (1.0, 1.0), periodic=periodic, backend="scipy")(p),
                               rtol=1e-12, atol=1e-15)


def test_backend_choice():
    assert choose_backend((256, 256), "auto", planned=True) == "pyfftw"    # plans reused: FFTW from small grids on
    assert choose_backend((256, 256), "auto") == "scipy"                  # one-shot transforms: pocketfft below 2048²
    assert choose_backend((2048, 2048), "auto") == "pyfftw"
    assert choose_backend((256, 256), "scipy", planned=True) == "scipy"
    assert Convolution((8, 8), (1.0, 1.0), periodic=True).backend == "pyfftw"
    with pytest.raises(ValueError, match="unknown FFT backend"):
        choose_backend((8, 8), "cufft")


def test_measured_plans_are_remembered(tmp_path, monkeypatch):
    """FFTW wisdom of a measured plan lands in the cache directory and is read back."""
    monkeypatch.setenv("XTOPO_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("XTOPO_FFTW_PLANNER", "measure")
    monkeypatch.setitem(conv_mod._WISDOM, "loaded", False)
    c = Convolution((6, 10), (1.0, 1.0), periodic=True, backend="pyfftw")
    c.input  # builds the plans
    path = tmp_path / "fftw-wisdom.npz"
    assert path.stat().st_size > 0
    import pyfftw

    with np.load(path) as stored:
        assert stored["arr_0"].tobytes() == pyfftw.export_wisdom()[0]


def test_wisdom_of_processes_saving_meanwhile_is_kept(tmp_path, monkeypatch):
    """A process that stores its wisdom keeps what another process stored since it read the file (parallel
    solves, other sessions): before, the last writer's wisdom replaced the file and the others' plans were
    measured again."""
    import subprocess
    import sys

    import pyfftw

    monkeypatch.setenv("XTOPO_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("XTOPO_FFTW_PLANNER", "measure")
    monkeypatch.setitem(conv_mod._WISDOM, "loaded", False)
    pyfftw.forget_wisdom()
    Convolution((6, 10), (1.0, 1.0), periodic=True, backend="pyfftw").input   # reads the file, stores its plans
    other = ("from xtopo._kernels.convolution import Convolution; "
             "Convolution((14, 18), (1.0, 1.0), periodic=True, backend='pyfftw').input")
    subprocess.run([sys.executable, "-c", other], check=True, env=dict(os.environ))
    Convolution((6, 12), (1.0, 1.0), periodic=True, backend="pyfftw").input   # stores again
    pyfftw.forget_wisdom()
    monkeypatch.setenv("XTOPO_FFTW_PLANNER", "")
    monkeypatch.setitem(conv_mod._WISDOM, "loaded", False)
    monkeypatch.setattr(conv_mod, "_MEASURE_FROM", 1)
    for shape in ((6, 10), (14, 18), (6, 12)):
        c = Convolution(shape, (1.0, 1.0), periodic=True, backend="pyfftw")
        c.input
        assert c._planned == "FFTW_MEASURE", shape   # measured plans known from the file


@pytest.mark.parametrize(("name", "value"), [("XTOPO_FFTW_PLANNER", "patiant"), ("XTOPO_FFT_THREADS", "two"),
                                           ("XTOPO_FFT_THREADS", "0")])
def test_a_misspelt_fft_setting_is_refused(monkeypatch, name, value):
    """An FFT setting in the environment that names no choice is refused, naming the variable and what to set;
    before, a misspelt planner planned by default and a non-number of threads raised a bare ValueError."""
    monkeypatch.setenv(name, value)
    with pytest.raises(XtopoError, match=f"{name}=.*(use estimate, measure or patient|a whole number of threads)"):
        Convolution((512, 512), (1.0, 1.0), periodic=True, backend="pyfftw").input


def test_plans_estimated_until_the_operator_proves_its_use(tmp_path, monkeypatch):
    """A grid the wisdom does not know is planned by estimate (measuring costs more than a solve); the
    operator's third solve measures its plans and stores them, and a new operator finds them known."""
    import pyfftw

    from xtopo import datasets
    from xtopo.contact import Scene

    monkeypatch.setenv("XTOPO_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("XTOPO_FFTW_PLANNER", raising=False)
    monkeypatch.setitem(conv_mod._WISDOM, "loaded", True)        # nothing read from disk
    monkeypatch.setattr(conv_mod, "_MEASURE_FROM", 1)
    pyfftw.forget_wisdom()
    ds = datasets.fractal_surface((24, 40), 1.0, hurst=0.8, rms_slope=0.1, seed=4, periodic=True, units="um")
    scene = Scene(ds, backend="pyfftw")
    results = [scene.solve(mean_pressure=0.02, tol=1e-8) for _ in range(conv_mod._MEASURE_AFTER)]
    assert len(_ops(scene)) == 3 and {op._planned for op in _ops(scene)} == {"FFTW_MEASURE"}
    assert (tmp_path / "fftw-wisdom.npz").stat().st_size > 0
    _agree(results)
    fresh = Scene(ds, backend="pyfftw")
    fresh.solve(mean_pressure=0.02, tol=1e-8)
    assert {op._planned for op in _ops(fresh)} == {"FFTW_MEASURE"}
    import pickle   # a copy sent elsewhere (a batch worker) plans from that machine's wisdom and counts anew

    copy = pickle.loads(pickle.dumps(scene.convolution))
    assert (copy._planned, copy._wanted, copy._solves) == (None, None, 0)


def test_patient_plans_are_asked_for_and_then_found(tmp_path, monkeypatch):
    """``XTOPO_FFTW_PLANNER=patient`` plans the columns of 2-D grids patiently (same results) and stores them; a
    later default operator starts from them; a line grid has no columns to plan patiently (one the wisdom does
    not know is estimated)."""
    import pyfftw

    from xtopo import datasets
    from xtopo.contact import Scene

    monkeypatch.setenv("XTOPO_CACHE_DIR", str(tmp_path))
    monkeypatch.setitem(conv_mod._WISDOM, "loaded", True)
    monkeypatch.setattr(conv_mod, "_MEASURE_FROM", 1)
    pyfftw.forget_wisdom()
    ds = datasets.fractal_surface((24, 40), 1.0, hurst=0.8, rms_slope=0.1, seed=4, periodic=True, units="um")
    measured = Scene(ds, backend="pyfftw").solve(mean_pressure=0.02, tol=1e-8)   # estimated plans: a new grid
    monkeypatch.setenv("XTOPO_FFTW_PLANNER", "patient")
    scene = Scene(ds, backend="pyfftw")
    _agree([measured, scene.solve(mean_pressure=0.02, tol=1e-8)])
    assert {op._planned for op in _ops(scene)} == {"FFTW_PATIENT"}
    monkeypatch.delenv("XTOPO_FFTW_PLANNER")
    later = Scene(ds, backend="pyfftw")
    later.solve(mean_pressure=0.02, tol=1e-8)
    assert {op._planned for op in _ops(later)} == {"FFTW_PATIENT"}
    line = Convolution((70000,), (1.0,), periodic=True, backend="pyfftw")
    line.input
    assert line._planned == "FFTW_ESTIMATE"   # no wisdom for it: estimated, never patient


def _ops(scene):
    return [scene.convolution, *scene.convolution._workspaces.values()]


def _agree(results):
    """The plans change the float32 rounding, not the solution."""
    for r in results[1:]:
        for name in ("pressure", "gap", "displacement"):
            np.testing.assert_allclose(r[name], results[0][name], rtol=0, atol=1e-7 * float(abs(results[0][name]).max()))
        assert float(r.residual) <= 1e-8


@pytest.mark.parametrize("backend", ["scipy", "pyfftw"])
@pytest.mark.parametrize("periodic", [True, False])
def test_solver_satisfies_complementarity(periodic, backend):
    """p ≥ 0, g ≥ 0 and p·g = 0 within tol; the load is carried; backends agree."""
    rng = np.random.default_rng(5)
    n = 24
    h = np.cumsum(np.cumsum(rng.standard_normal((n, n)), 0), 1) * 1e-3
    w = h - h.max()
    c = Convolution((n, n), (1 / n, 1 / n), periodic=periodic, backend=backend)
    load = 2e-3
    r = polonsky_keer(c, w, pixel_area=1 / n**2, load=load, tol=1e-10, maxiter=2000)
    assert r.converged and r.iterations > 1
    assert np.all(r.pressure >= 0)
    np.testing.assert_allclose(r.load, load, rtol=1e-12)
    ptv = -w.min()
    # the returned displacements are the exact convolution of the returned pressures
    np.testing.assert_allclose(r.displacement, c(r.pressure), rtol=0, atol=1e-12 * ptv)
    gap = r.displacement - w - r.penetration
    assert gap.min() > -1e-9 * ptv
    np.testing.assert_allclose(gap[r.pressure > 0], 0, atol=1e-9 * ptv)
    # per iteration one float32 forward transform of the direction and one float32 convolution of the
    # pressure increment; working-precision convolutions only at the start, every 3 decades of the
    # residual (0.5 → 1e-10 here) and to confirm convergence
    assert r.transforms == 3 * r.iterations + 2 * r.exact_convolutions
    assert r.exact_convolutions <= 6
    other = polonsky_keer(Convolution((n, n), (1 / n, 1 / n), periodic=periodic,
                                      backend="scipy" if backend == "pyfftw" else "pyfftw"),
                          w, pixel_area=1 / n**2, load=load, tol=1e-10, maxiter=2000)
    np.testing.assert_allclose(other.pressure, r.pressure, rtol=1e-6, atol=1e-9 * r.pressure.max())


def test_solve_reports_progress_through_callback():
    from xtopo import datasets
    from xtopo.contact import Scene

    seen = []
    ds = datasets.fractal_surface((32, 32), 1.0, hurst=0.8, rms_slope=0.1, seed=2, periodic=True, units="um")
    r = Scene(ds).solve(mean_pressure=0.01, tol=1e-8, callback=lambda it, res: seen.append((it, res)))
    assert [it for it, _ in seen] == list(range(len(seen)))
    assert len(seen) == int(r.iterations) + 1
    assert seen[-1][1] <= 1e-8 < seen[0][1]


@pytest.mark.parametrize("periodic", [True, False])
@pytest.mark.parametrize("shape", [(32, 48), (33,)])
def test_self_stiffness_is_the_displacement_under_a_unit_impulse(periodic, shape):
    conv = Convolution(shape, (0.5, 0.7)[: len(shape)], 2.0, periodic=periodic)
    centre = tuple(n // 2 for n in shape)
    p = np.zeros(shape)
    p[centre] = 1.0
    np.testing.assert_allclose(conv.self_stiffness, conv(p)[centre], rtol=1e-12)


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("backend", ["scipy", "pyfftw"])
def test_repeated_solves_on_one_scene_plan_nothing_and_agree(monkeypatch, dtype, backend):
    """The solver's work operators are built once per scene; reusing their buffers leaves no trace."""
    from xtopo import datasets
    from xtopo.contact import Scene

    ds = datasets.fractal_surface((32, 32), 1.0, hurst=0.8, rms_slope=0.1, seed=4, periodic=False, units="um")
    scene = Scene(ds, dtype=dtype, backend=backend)
    first = scene.solve(mean_pressure=0.02, tol=1e-6)
    other = scene.solve(mean_pressure=0.005, tol=1e-6)     # different sets and pressures in the buffers
    built = []
    for name in ("_build_pyfftw", "_build_scipy"):
        original = getattr(Convolution, name)
        monkeypatch.setattr(Convolution, name, lambda self, _f=original: (built.append(self), _f(self))[1])
    again = scene.solve(mean_pressure=0.02, tol=1e-6)
    assert built == []
    assert int(other.iterations) > 0 and float(other.area_fraction) < float(first.area_fraction)
    xr.testing.assert_identical(again.drop_attrs(), first.drop_attrs())


def test_inverse_refuses_a_strided_spectrum():
    """The Green's function multiplies the spectrum in place: a strided one (a copy would be lost) is refused."""
    c = Convolution((8, 8), (1.0, 1.0), periodic=True, backend="scipy")
    c.input[...] = np.arange(64.0).reshape(8, 8)
    spectrum = np.repeat(c.forward(), 2, axis=0)[::2]   # same values, every other row of a larger array
    with pytest.raises(ValueError, match="C-contiguous"):
        c.inverse(spectrum)
    np.testing.assert_allclose(c.inverse(np.ascontiguousarray(spectrum)), c(c.input.copy()), rtol=1e-12)
