"""Twin averages, xtopo vs SurfaceTopography's container averages, side by side on the same data (issue 21).

Run: ``python benchmarks/bench_twin_vs_st.py [--seed 0] [--repeats 3]``.

The example twin (:func:`xtopo.datasets.example_twin`: 24 measurements, AFM maps, stylus profile sets,
nonuniform TEM profiles, missing data) is filled harmonically once; the same heights, sizes, tip radii and
resolutions go into an ``InMemorySurfaceContainer`` of SurfaceTopography (area scans and profile sets as
``Topography``, TEM contours as ``NonuniformLineScan``). Each repeat times, alternating which goes first,

* xtopo: ``twin_psd``, ``twin_acf``, ``twin_vbm`` (and ``twin_sdrp`` curvature, which ST's container lacks)
  on a fresh twin, computed;
* ST: ``container.power_spectrum / autocorrelation / variable_bandwidth(unit="m", nb_points_per_decade=10)``.

Prints min/median/max per side, the ratio of medians (xtopo / ST; the goal is <= 1) and the load average.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

import xtopo
from xtopo.preprocess import fill_missing
from xtopo.stitching import ANALYSES


def _st_info(ds) -> dict:
    params = {}
    for key in ("tip_radius", "resolution"):
        if ds.attrs.get(key) is not None:
            params[key] = {"value": float(ds.attrs[key]), "unit": ds.attrs.get(f"{key}_units", "m")}
    return {"instrument": {"parameters": params}} if params else {}


def st_container(measurements: dict):
    """The measurements as a SurfaceTopography ``InMemorySurfaceContainer`` (heights in m)."""
    from SurfaceTopography import NonuniformLineScan, Topography, UniformLineScan
    from SurfaceTopography.Container.SurfaceContainer import InMemorySurfaceContainer

    tops = []
    for ds in measurements.values():
        h = np.asarray(ds["height"].values, dtype=float)
        x = np.asarray(ds["x"].values, dtype=float)
        info = _st_info(ds)
        if ds.attrs.get("measurement_kind") == "nonuniform":
            tops.append(NonuniformLineScan(x, h, unit="m", info=info))
        elif h.ndim == 1:
            tops.append(UniformLineScan(h, x.size * (x[1] - x[0]), periodic=False, unit="m", info=info))
        else:
            y = np.asarray(ds["y"].values, dtype=float)
            size = (x.size * (x[1] - x[0]), y.size * (y[1] - y[0]))
            tops.append(Topography(h.T, size, periodic=False, unit="m", info=info))  # ST: (nx, ny)
    return InMemorySurfaceContainer(tops)


def run_xtopo(measurements: dict, names) -> dict:
    tree = xtopo.twin(measurements)
    return {n: ANALYSES[n](tree).compute() for n in names}


def run_st(container) -> dict:
    kw = dict(unit="m", nb_points_per_decade=10)
    return {"psd": container.power_spectrum(**kw), "acf": container.autocorrelation(**kw),
            "vbm": container.variable_bandwidth(**kw)}


def _decades(x) -> float:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x) & (x > 0)]
    return float(np.log10(x.max() / x.min()))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    tree = xtopo.datasets.example_twin(args.seed)
    ms = {n: fill_missing(node.to_dataset()).load() for n, node in tree.children.items()}
    container = st_container(ms)
    common = ("psd", "acf", "vbm")
    times = {"xtopo psd+acf+vbm": [], "ST psd+acf+vbm": [], "xtopo sdrp (curvature)": []}
    run_xtopo(ms, common), run_st(container)  # warm-up: imports, FFT plans, numba
    for r in range(args.repeats):
        order = ("x", "s") if r % 2 == 0 else ("s", "x")
        for who in order:
            t = time.perf_counter()
            if who == "x":
                ours = run_xtopo(ms, common)
                times["xtopo psd+acf+vbm"].append(time.perf_counter() - t)
            else:
                theirs = run_st(container)
                times["ST psd+acf+vbm"].append(time.perf_counter() - t)
        t = time.perf_counter()
        run_xtopo(ms, ("sdrp",))
        times["xtopo sdrp (curvature)"].append(time.perf_counter() - t)
    print(f"example_twin(seed={args.seed}): {len(ms)} measurements; load average {os.getloadavg()}")
    for label, ts in times.items():
        print(f"{label:24s} min {min(ts):7.2f} s  median {statistics.median(ts):7.2f} s  max {max(ts):7.2f} s")
    ratio = statistics.median(times["xtopo psd+acf+vbm"]) / statistics.median(times["ST psd+acf+vbm"])
    print(f"ratio of medians xtopo / ST (psd+acf+vbm): {ratio:.2f}")
    truth = xtopo.datasets.prescribed_psd(tree)
    refs = {"psd": truth.c1d, "acf": truth.acf}
    for name in common:  # what each covers, and how far from the ground truth, side by side
        avg = ours[name]
        coord = avg.average.dims[0]
        ok = avg["count"].values > 0
        x_ours, y_ours = avg[coord].values[ok], avg.average.values[ok]
        x_st = np.ma.filled(np.ma.asarray(theirs[name][0], dtype=float), np.nan)
        y_st = np.ma.filled(np.ma.asarray(theirs[name][1], dtype=float), np.nan)
        keep = np.isfinite(x_st) & np.isfinite(y_st) & (x_st > 0)
        x_st, y_st = x_st[keep], y_st[keep]
        line = (f"{name}: xtopo {x_ours.size} points over {_decades(x_ours):.2f} decades; "
                f"ST {x_st.size} points over {_decades(x_st):.2f} decades")
        if name in refs:
            for who, x, y in (("xtopo", x_ours, y_ours), ("ST", x_st, y_st)):
                dev = np.abs(y / refs[name](x) - 1)
                line += f"; {who} |avg/truth-1| median {np.median(dev):.3f} max {dev.max():.3f}"
        print(line)


if __name__ == "__main__":
    main()
