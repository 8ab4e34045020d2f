"""Properties of the contact solution (issue 9): periodic translation and the scalings
(h, E*, p) → (αh, E*, αp) and (h, E*, p) → (h, αE*, αp) leave the contact area unchanged."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import assume
from hypothesis import strategies as st

import xtopo
from xtopo.contact import Scene

from .strategies import heights, property_tests

pytestmark = [pytest.mark.timeout(120), pytest.mark.filterwarnings("error::RuntimeWarning")]

TOL = 1e-10
PRESSURES = st.sampled_from([1e-3, 0.05, 0.5, 5.0])  # in E*, on slopes of order one: up to full contact


def _unit_slopes(h):
    """``h`` scaled to a peak-to-valley of 1 (slopes of order one on 1 m pixels).

    The solver's residual is relative to the peak-to-valley height; far beyond full contact of
    a nearly flat surface (displacements ≫ roughness / (eps · tol)) it cannot be met in floating
    point (the solver then flags converged=False, as test_extremes checks for float32).
    """
    ptp = float(np.ptp(h))
    return h / ptp if ptp > 0 else h


def _solve(h, *, modulus=1.0, mean_pressure, periodic=True):
    ds = xtopo.make_measurement(h, spacing=1.0, periodic=periodic)
    with warnings.catch_warnings():
        warnings.simplefilter("error", xtopo.ConvergenceWarning)
        r = Scene(ds, modulus=modulus).solve(mean_pressure=mean_pressure, tol=TOL, maxiter=2000)
    assert bool(r["converged"])
    return r


def _same_contact(a, b, pressure_factor=1.0):
    """Same contact set and pressures up to the points whose pressure is at round-off level."""
    pa, pb = a["pressure"].values * pressure_factor, b["pressure"].values
    pmax = max(float(pa.max()), float(pb.max()))
    sure = (pa > 1e-6 * pmax) | (pb > 1e-6 * pmax)
    marginal = ~sure & ((pa > 0) | (pb > 0))
    np.testing.assert_array_equal(pa[sure] > 0, pb[sure] > 0)
    n = pa.size
    assert abs(float(a["area_fraction"]) - float(b["area_fraction"])) <= marginal.sum() / n + 1e-12
    np.testing.assert_allclose(pb, pa, rtol=0, atol=1e-5 * pmax)


def check_translation(h, shifts, mean_pressure):
    h = _unit_slopes(h)
    r = _solve(h, mean_pressure=mean_pressure)
    moved = _solve(np.roll(h, shifts[-h.ndim:], axis=tuple(range(h.ndim))), mean_pressure=mean_pressure)
    back = moved.copy()
    back["pressure"] = moved["pressure"].copy(data=np.roll(moved["pressure"].values, [-s for s in shifts[-h.ndim:]],
                                                           axis=tuple(range(h.ndim))))
    _same_contact(r, back)


test_contact_translation, test_contact_translation_nightly = property_tests(
    h=heights(min_side=2, max_side=10), shifts=st.tuples(st.integers(-9, 9), st.integers(-9, 9)),
    mean_pressure=PRESSURES)(check_translation)


def check_height_scaling(h, alpha, mean_pressure, periodic):
    h = _unit_slopes(h)
    r = _solve(h, mean_pressure=mean_pressure, periodic=periodic)
    s = _solve(alpha * h, mean_pressure=alpha * mean_pressure, periodic=periodic)
    _same_contact(r, s, pressure_factor=alpha)


test_contact_height_scaling, test_contact_height_scaling_nightly = property_tests(
    h=heights(min_side=2, max_side=10), alpha=st.sampled_from([1e-9, 1e-3, 7.0, 1e4]), mean_pressure=PRESSURES,
    periodic=st.booleans())(check_height_scaling)


def check_modulus_scaling(h, alpha, mean_pressure, periodic):
    h = _unit_slopes(h)
    r = _solve(h, mean_pressure=mean_pressure, periodic=periodic)
    s = _solve(h, modulus=alpha, mean_pressure=alpha * mean_pressure, periodic=periodic)
    _same_contact(r, s, pressure_factor=alpha)


test_contact_modulus_scaling, test_contact_modulus_scaling_nightly = property_tests(
    h=heights(min_side=2, max_side=10), alpha=st.sampled_from([1e-9, 1e-3, 7.0, 1e9]), mean_pressure=PRESSURES,
    periodic=st.booleans())(check_modulus_scaling)
