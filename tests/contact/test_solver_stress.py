"""Random contact problems: every solve converges to pressures that satisfy the contact conditions.

The conditions are checked against an independent float64 convolution of the returned
pressures, so the float32 work inside the solver cannot hide behind its own bookkeeping.
"""

import warnings

import numpy as np
import pytest

from xtopo import datasets
from xtopo.contact import Scene
from xtopo.errors import ContactError


def random_case(rng):
    n = int(rng.choice([32, 48, 64, 96]))
    periodic = bool(rng.integers(2))
    hardness = [None, 0.02, 0.05][int(rng.integers(3))]
    slope = float(rng.uniform(0.02, 0.5))
    ds = datasets.fractal_surface((n, n), 1.0, hurst=float(rng.uniform(0.3, 0.95)), rms_slope=slope,
                                  short_cutoff=float(rng.uniform(2, 8)) / n, seed=int(rng.integers(1_000_000)),
                                  periodic=periodic, units="um")
    if rng.integers(3) == 0:
        ptv = float(ds.height.max() - ds.height.min())
        control = {"penetration": float(10 ** rng.uniform(-3, 0)) * ptv}
    else:
        control = {"mean_pressure": float(10 ** rng.uniform(-4, 0)) * slope}
        if hardness is not None:
            control["mean_pressure"] = min(control["mean_pressure"], 0.5 * hardness)
    tol = float(rng.choice([1e-4, 1e-6, 1e-8]))
    return ds, hardness, control, tol


@pytest.mark.parametrize("seed", range(4))
def test_random_problems_satisfy_the_contact_conditions(seed):
    rng = np.random.default_rng(seed)
    checked = 0
    for _ in range(8):
        ds, hardness, control, tol = random_case(rng)
        scene = Scene(ds, hardness=hardness)
        with warnings.catch_warnings():
            warnings.simplefilter("error")                      # a ConvergenceWarning fails the test
            try:
                r = scene.solve(tol=tol, maxiter=5000, **control)
            except ContactError:                                # periodic penetration past the mean plane
                assert scene.periodic and hardness is None and "penetration" in control
                continue
        checked += 1
        assert bool(r.converged) and float(r.residual) <= tol
        p = r.pressure.values
        w = scene.w.astype(np.float64)
        ptv = -float(w.min())
        u = scene.convolution(p.astype(np.float64))              # independent float64 convolution
        np.testing.assert_allclose(r.displacement.values, u, rtol=0, atol=1e-10 * ptv)
        gap = u - w - float(r.penetration)
        slack = 1.001 * tol * ptv + 1e-12 * ptv
        assert p.min() >= 0
        free = p == 0
        assert gap[free].min(initial=np.inf) >= -slack
        if hardness is None:
            elastic = p > 0
        else:
            assert p.max() <= hardness
            plastic = p >= hardness
            assert gap[plastic].max(initial=-np.inf) <= slack
            elastic = (p > 0) & ~plastic
        assert np.abs(gap[elastic]).max(initial=0.0) <= slack
        if "mean_pressure" in control:
            np.testing.assert_allclose(float(r.mean_pressure), control["mean_pressure"], rtol=max(tol, 1e-9))
    assert checked >= 4
