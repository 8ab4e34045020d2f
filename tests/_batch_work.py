"""A deterministic FFT-bound stand-in for a contact solve, for batch tests and the batch benchmark.

Projected-gradient iterations of the periodic elastic contact problem (Green's function
``2/(E*|q|)``): the same kind of work per item as the real solver (FFT pairs in a loop),
without depending on it. Counting/interrupting hooks for the resume tests are driven by
environment variables so that they work in worker processes too.
"""

from __future__ import annotations

import os

import numpy as np
import xarray as xr

from xtopo._kernels import fft as _fft


class Interrupt(BaseException):
    """Stands for Ctrl-C / a killed client in the resume test."""


def _count() -> int:
    path = os.environ.get("XTOPO_TEST_COUNTER")
    if not path:
        return 0
    with open(path, "a") as f:
        f.write("x\n")
    with open(path) as f:
        return sum(1 for _ in f)


def fft_work(ds, loads, *, iterations: int = 30):
    """Mean gap and contact fraction of ``ds`` pressed by a rigid flat at each load (arbitrary units)."""
    n = _count()
    limit = os.environ.get("XTOPO_TEST_INTERRUPT_AFTER")
    if limit and n > int(limit):
        raise Interrupt(f"interrupted at execution {n}")
    h = np.asarray(ds["height"].values, dtype=float)
    h = (h - h.max()) / (np.ptp(h) or 1.0)
    ny, nx = h.shape
    qy = np.fft.fftfreq(ny)[:, None]
    qx = np.fft.rfftfreq(nx)[None, :]
    q = np.hypot(qy, qx)
    green = np.where(q > 0, 1.0 / np.where(q > 0, q, 1.0), 0.0)
    gaps, fractions = [], []
    for load in loads:
        p = np.full(h.shape, float(load))
        for _ in range(iterations):
            u = _fft.irfftn(_fft.rfftn(p) * green, s=h.shape)
            g = u - h - float(load)
            p = np.maximum(p - 0.1 * g, 0.0)
            p *= float(load) / max(p.mean(), 1e-300)
        gaps.append(float(np.mean(np.maximum(u - h, 0.0))))
        fractions.append(float(np.mean(p > 0)))
    return xr.Dataset({
        "mean_gap": ("load", gaps, {"units": "1", "long_name": "mean gap (normalised)"}),
        "area_fraction": ("load", fractions, {"units": "1", "long_name": "fraction of the area in contact"}),
        "fft_threads": ((), _fft.workers(), {"units": "1", "long_name": "FFT threads used by the task"}),
    })


def probe_attrs(ds):
    """The tip radius a measurement was read with (a batch function of tests/test_cli_units.py)."""
    import xarray as xr

    return xr.Dataset({"tip_radius": ((), float(ds.attrs.get("tip_radius", float("nan"))), {"units": "m"})})
