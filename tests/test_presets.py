"""Speed/accuracy presets (issue 9): the table, the resolver, and the contact API that uses them."""

import pathlib
import warnings

import numpy as np
import pytest

from xtopo import datasets, presets
from xtopo.contact import Scene, contact
from xtopo.contact.solve import default_tol, solver_settings
from xtopo.errors import ConvergenceWarning, XtopoError

from .test_tradeoffs import load_tradeoffs

REPO = pathlib.Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def tradeoffs():
    return load_tradeoffs()


def test_each_preset_maps_to_the_documented_knobs():
    table = presets.PRESETS["contact"]
    assert tuple(table) == presets.NAMES == ("fast", "default", "accurate")
    assert dict(table["fast"]) == {"dtype": "float32", "tol": 1e-4, "maxiter": 500}
    assert dict(table["default"]) == {"dtype": "float64", "tol": None, "maxiter": 1000}
    assert dict(table["accurate"]) == {"dtype": "float64", "tol": 1e-8, "maxiter": 10000}
    # the docs page states the same numbers
    doc = (REPO / "docs" / "tradeoffs.md").read_text()
    for name, knobs in table.items():
        assert f"`{name}`" in doc
        assert f"{knobs['maxiter']}" in doc


def test_fast_is_not_slower_by_construction():
    fast, default, accurate = (presets.resolve("contact", n) for n in presets.NAMES)
    surf = datasets.fractal_surface((16, 16), 1.0, hurst=0.8, rms_slope=0.1, units="um")
    tols = [solver_settings(Scene(surf, preset=n), preset=n)[0] for n in presets.NAMES]
    assert tols[0] >= tols[1] >= tols[2] and tols[0] > tols[2]
    assert fast["maxiter"] <= default["maxiter"] <= accurate["maxiter"]
    assert np.dtype(fast["dtype"]).itemsize <= np.dtype(default["dtype"]).itemsize


def test_resolver_explicit_keywords_win():
    assert presets.resolve("contact", None) == presets.resolve("contact", "default")
    assert presets.resolve("contact", "fast", tol=1e-7)["tol"] == 1e-7
    assert presets.resolve("contact", "fast", maxiter=None)["maxiter"] == 500
    surf = datasets.fractal_surface((16, 16), 1.0, hurst=0.8, rms_slope=0.1, units="um")
    assert Scene(surf, preset="fast").dtype == np.float32
    assert Scene(surf, preset="fast", dtype="float64").dtype == np.float64
    assert Scene(surf).dtype == np.float64 and Scene(surf).preset is None
    # no preset: the old defaults (tol by dtype, 1000 iterations)
    assert solver_settings(Scene(surf)) == (default_tol("float64"), 1000)
    assert solver_settings(Scene(surf, dtype="float32")) == (default_tol("float32"), 1000)
    # the scene's preset is the default of its solves; a solve's own preset or keywords win
    fast = Scene(surf, preset="fast")
    assert solver_settings(fast) == (1e-4, 500)
    assert solver_settings(fast, preset="default") == (default_tol("float32"), 1000)
    assert solver_settings(fast, tol=1e-3, maxiter=7) == (1e-3, 7)
    # float32 cannot resolve the accurate tolerance: floored
    assert solver_settings(Scene(surf, dtype="float32"), preset="accurate")[0] == 1e-6
    r = Scene(surf, preset="accurate").solve(mean_pressure=0.02)
    assert r.attrs["tolerance"] == 1e-8 and r.attrs["dtype"] == "float64"
    c = contact(surf, mean_pressure=[0.01, 0.02], preset="fast")
    assert c.attrs["tolerance"] == 1e-4 and c.pressure.dtype == np.float32
    with pytest.raises(XtopoError, match="preset must be one of"):
        Scene(surf, preset="quick")
    with pytest.raises(XtopoError, match="preset must be one of"):
        Scene(surf).solve(mean_pressure=0.01, preset="best")
    with pytest.raises(XtopoError, match="no knob"):
        presets.resolve("contact", "fast", window="hann")
    assert "preset 'fast'" in repr(fast)


def test_accurate_beats_fast_on_westergaard(tradeoffs):
    """Line contact of a sinusoid (analytic pressure): the solver error shows above the grid error."""
    w = tradeoffs.Westergaard(512)  # 512 px across the contact: discretisation error ≈ 5e-4
    errors = {}
    for name in presets.NAMES:
        res = Scene(w.ds, preset=name).solve(mean_pressure=w.mean_pressure)
        assert bool(res.converged)
        errors[name] = tradeoffs.rel_l2(res.pressure.values, w.exact)
    assert errors["accurate"] < 0.5 * errors["fast"]
    assert errors["default"] < 0.5 * errors["fast"]
    assert errors["accurate"] < 1e-3


def test_accurate_beats_fast_on_hertz(tradeoffs):
    h = tradeoffs.Hertz(32)  # 96² free boundary, a = 32 px
    errors, iterations = {}, {}
    for name in presets.NAMES:
        res = h.scene(preset=name).solve(load=h.load)
        errors[name], iterations[name] = h.error(res), int(res.iterations)
    assert errors["accurate"] < errors["fast"] < 0.01
    assert iterations["fast"] < iterations["default"] < iterations["accurate"]


def test_fast_preset_maxiter_is_a_cap():
    surf = datasets.fractal_surface((32, 32), 1.0, hurst=0.8, rms_slope=0.1, units="um")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        r = Scene(surf, preset="fast").solve(mean_pressure=0.02, maxiter=3)
    assert int(r.iterations) == 3 and not bool(r.converged)


@pytest.mark.parametrize("family,preset", [(["contact"], None), ({}, None), ("contact", ["fast"]), ("contact", {})])
def test_resolver_refuses_unhashable_names(family, preset):
    # a list or dict raised TypeError: unhashable type
    with pytest.raises(XtopoError, match="no presets for|preset must be one of"):
        presets.resolve(family, preset)
