"""ISO 16610 filters and the ISO 21920-2 profile set: xtopo vs surfalize, side by side in one process.

Usage::

    PYTHONPATH=. python benchmarks/bench_iso_profile.py                     # defaults below, 5 repeats
    PYTHONPATH=. python benchmarks/bench_iso_profile.py --points 100000 --map 2048 --lines 2048 --repeats 7

Cases (the same data for both packages):

* ``profile filter``: roughness of one profile of ``--points`` points (Δx = 0.5 µm, λc = 0.8 mm:
  a 3201-point kernel). xtopo: ``filter(lambda_s=None, lambda_c=..., form=None)`` (end
  correction, full length); surfalize: ``GaussianFilter(λc, "highpass")`` (``scipy.ndimage``,
  reflected ends, truncated at 4σ).
* ``areal filter``: the same on a ``--map``² map (Δ = 1 µm, λc = 0.25 mm), areal Gaussian.
* ``profile set``: one profile of ``--points`` points; the parameters both packages have (Ra Rq
  Rp Rv Rz Rt Rsk Rku Rdq Rk Rpk Rvk Rmr1 Rmr2 Rmr(c)); xtopo computes RSm as well. No filter.
* ``set per line``: the same for ``--lines`` lines of a map (xtopo: one vectorised call along
  ``x``; surfalize: one ``Profile`` per line, its documented way).

Each case: one warm-up call of each, then ``--repeats`` calls alternating between the two
(surfalize gets a fresh object each time: it caches results on the object). The table gives
min/median/max in seconds and the ratio of the medians (xtopo/surfalize; < 1: xtopo faster),
with the load average before and after.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

import xtopo  # noqa: F401
from xtopo.conventions import make_measurement


def _surfalize_set(z, step):
    import surfalize

    p = surfalize.Profile(z, step)
    return [p.Ra(), p.Rq(), p.Rp(), p.Rv(), p.Rz(), p.Rt(), p.Rsk(), p.Rku(), p.Rdq(), p.Rk(), p.Rpk(), p.Rvk(),
            p.Rmr1(), p.Rmr2(), p.Rmr(0.0)]


def _cases(points: int, side: int, lines: int):
    import surfalize
    from surfalize.filter import GaussianFilter

    rng = np.random.default_rng(0)
    dx = 0.5  # µm
    z = np.cumsum(rng.normal(size=points)) * 0.01 + rng.normal(size=points) * 0.05
    line = make_measurement(z, spacing=dx, units="um")
    zmap = rng.normal(size=(side, side)).cumsum(1) * 0.01
    area = make_measurement(zmap, spacing=1.0, units="um")
    rows = zmap[:lines]
    rows_ds = make_measurement(rows, spacing=1.0, units="um")
    hp_line, hp_area = GaussianFilter(800.0, "highpass"), GaussianFilter(250.0, "highpass")
    return [
        (f"profile filter ({points} pts, λc 0.8 mm)",
         lambda: line.topo.filter(lambda_s=None, lambda_c=800.0, form=None).height.values,
         lambda: hp_line(surfalize.Profile(z, dx)).data),
        (f"areal filter ({side}², λc 0.25 mm)",
         lambda: area.topo.filter(lambda_s=None, lambda_c=250.0, form=None).height.values,
         lambda: hp_area(surfalize.Surface(zmap, 1.0, 1.0)).data),
        (f"profile set ({points} pts)",
         lambda: line.topo.iso21920(form=None).compute(),
         lambda: _surfalize_set(z, dx)),
        (f"set per line ({lines} × {side})",
         lambda: rows_ds.topo.iso21920(form=None).compute(),
         lambda: [_surfalize_set(r, 1.0) for r in rows]),
    ]


def _stats(times):
    return min(times), statistics.median(times), max(times)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--points", type=int, default=100_000)
    ap.add_argument("--map", type=int, default=2048)
    ap.add_argument("--lines", type=int, default=64,
                    help="lines of the map for the per-line set (surfalize takes ~0.2 s per 512-point line)")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    load0 = os.getloadavg()
    print(f"load average before: {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f} ({os.cpu_count()} CPUs)")
    print(f"{'case':38s} {'xtopo min/med/max s':>26s} {'surfalize min/med/max s':>26s} {'ratio':>7s}")
    for name, ours, theirs in _cases(args.points, args.map, args.lines):
        ours(), theirs()  # warm-up: imports, FFT plans
        t_ours, t_theirs = [], []
        for i in range(args.repeats):
            for fn, times in ((ours, t_ours), (theirs, t_theirs)) if i % 2 == 0 else ((theirs, t_theirs),
                                                                                   (ours, t_ours)):
                t0 = time.perf_counter()
                fn()
                times.append(time.perf_counter() - t0)
        a, b = _stats(t_ours), _stats(t_theirs)
        print(f"{name:38s} {a[0]:8.3f} {a[1]:8.3f} {a[2]:8.3f} {b[0]:8.3f} {b[1]:8.3f} {b[2]:8.3f} "
              f"{a[1] / b[1]:7.2f}")
    load1 = os.getloadavg()
    print(f"load average after: {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")


if __name__ == "__main__":
    main()
