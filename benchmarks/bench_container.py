"""Twin averages of a contact.engineering container: xtopo vs SurfaceTopography, side by side in one run.

Usage::

    PYTHONPATH=. python benchmarks/bench_container.py                 # both built-in containers
    PYTHONPATH=. python benchmarks/bench_container.py --which real    # real files only
    PYTHONPATH=. python benchmarks/bench_container.py --container download.zip   # any CE download
    PYTHONPATH=. python benchmarks/bench_container.py --repeats 5

Containers:

* ``real``: the CE layout of a contact.engineering download built from the shared real files
  (``../shared/data/real``, or ``--real-data DIR``): AFM map ``di-3.di`` (tip radius 10 nm),
  optical map ``plu-1.plu`` (resolution 2 µm) and stylus profile ``dektak-1.csv`` (tip radius
  2.5 µm), original files with ``meta.yml`` (tilt/curvature detrending), as contact.engineering
  writes them;
* ``example``: xtopo's example twin (``xtopo.datasets.example_twin(seed=7)``, 24 measurements from
  TEM contours to stylus profiles) written with :func:`xtopo.to_container`.

SurfaceTopography reads the container with ``read_container`` and averages it with
``container.power_spectrum / autocorrelation / variable_bandwidth(unit="m",
nb_points_per_decade=10)``; xtopo opens it with :func:`xtopo.open_twin` and averages with
``twin.topo.psd() / acf() / vbm()``. Printed per analysis: the decades of the abscissa each
covers (the union of its points' collocation cells, ±1/20 decade around each finite point), the
fraction of SurfaceTopography's decades that xtopo covers (acceptance ≥ 90 %), the median relative
deviation of xtopo's average from SurfaceTopography's on common points (xtopo's average
interpolated log-log onto SurfaceTopography's points inside xtopo's covered cells; acceptance
≤ 25 %), and the median time of each (``--repeats``, after one warm-up) with the ratio
xtopo/SurfaceTopography (< 1: xtopo faster).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
import warnings

import numpy as np

import xtopo

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

REAL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "data", "real")
#: cells per decade for measuring coverage; a finite point covers ±HALF decades around it
CELLS = 1000
HALF = 0.05
#: (label, SurfaceTopography container method, twin accessor method, its keyword arguments). VBM twice: the
#: paper's areal squares with the mean of their RMS heights (xtopo's default), and SurfaceTopography's own
#: definition (segments of the profiles along x, RMS over all segments: ``kind="1d", average="rms"``)
ANALYSES = (("PSD", "power_spectrum", "psd", {}), ("ACF", "autocorrelation", "acf", {}),
            ("VBM", "variable_bandwidth", "vbm", {}),
            ("VBM1", "variable_bandwidth", "vbm", {"kind": "1d", "average": "rms"}))


def real_container(directory: str, real: str) -> str:
    """A contact.engineering download (CE layout, meta.yml) of three real measurements."""
    import zipfile

    meta = """\
surfaces:
- name: three instruments
  description: AFM, optical and stylus measurements (shared real files; not one physical surface)
  topographies:
  - name: afm
    datafile: {original: di-3.di}
    data_source: 0
    detrend_mode: height
    is_periodic: false
    instrument: {name: Dimension Icon, type: contact-based, parameters: {tip_radius: {value: 10, unit: nm}}}
  - name: optical
    datafile: {original: plu-1.plu}
    data_source: 0
    detrend_mode: height
    fill_undefined_data_mode: harmonic
    is_periodic: false
    instrument: {name: Sensofar, type: microscope-based, parameters: {resolution: {value: 2, unit: µm}}}
  - name: stylus
    datafile: {original: dektak-1.csv}
    data_source: 0
    detrend_mode: curvature
    is_periodic: false
    instrument: {name: Dektak, type: contact-based, parameters: {tip_radius: {value: 2.5, unit: µm}}}
versions: {topobank: 1.0.0}
"""
    path = os.path.join(directory, "real.zip")
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("meta.yml", meta)
        for name in ("di-3.di", "plu-1.plu", "dektak-1.csv"):
            zf.write(os.path.join(real, name), name)
    return path


def example_container(directory: str, seed: int = 7) -> str:
    return xtopo.to_container(xtopo.datasets.example_twin(seed=seed), os.path.join(directory, "example.zip"))


def _cells(x) -> set:
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x) & (x > 0)]
    out = set()
    for v in np.log10(x):
        out.update(range(int(np.floor((v - HALF) * CELLS)), int(np.ceil((v + HALF) * CELLS))))
    return out


def _xtopo_curve(result):
    """(abscissa, average) of a twin-average Dataset (finite points only)."""
    name = "average" if "average" in result else next(v for v in result.data_vars if result[v].ndim == 1)
    avg = result[name]
    dim, = avg.dims
    x, y = np.asarray(avg[dim].values, dtype=float), np.asarray(avg.values, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    return x[ok], y[ok]


def compare(st_xy, xt_xy) -> dict:
    xs, ys = (np.ma.filled(np.ma.asarray(a, dtype=float), np.nan) for a in st_xy)
    ok = np.isfinite(xs) & np.isfinite(ys) & (xs > 0) & (ys > 0)
    xs, ys = xs[ok], ys[ok]
    xx, yx = xt_xy
    cs, cx = _cells(xs), _cells(xx)
    out = {"st_decades": len(cs) / CELLS, "xtopo_decades": len(cx) / CELLS,
           "covered": len(cs & cx) / len(cs) if cs else float("nan"), "st_points": xs.size, "xtopo_points": xx.size}
    common = np.array([any(c in cx for c in (int(np.floor(np.log10(v) * CELLS)),)) for v in xs], dtype=bool)
    common &= (xs >= xx.min()) & (xs <= xx.max()) if xx.size else False
    if xx.size > 1 and common.any():
        yi = np.exp(np.interp(np.log(xs[common]), np.log(xx), np.log(yx)))
        dev = np.abs(yi / ys[common] - 1)
        out.update(median_dev=float(np.median(dev)), max_dev=float(np.max(dev)), common=int(common.sum()))
    else:
        out.update(median_dev=float("nan"), max_dev=float("nan"), common=0)
    return out


def _times(fn, repeats: int) -> list:
    fn()  # warm-up: imports, FFT plans
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def run(path: str, label: str, repeats: int) -> list:
    from SurfaceTopography.Container.IO import read_container

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        t0 = time.perf_counter()
        containers = read_container(path)
        container = containers[0]
        st_topos = [container[i] for i in range(len(container))]  # read (lazily) now: not timed below
        t_st_read = time.perf_counter() - t0
    from SurfaceTopography.Container.SurfaceContainer import InMemorySurfaceContainer

    st = InMemorySurfaceContainer(st_topos)
    t0 = time.perf_counter()
    twin = xtopo.open_twin(path, surface=0) if len(containers) > 1 else xtopo.open_twin(path)
    t_x_read = time.perf_counter() - t0
    print(f"\n== {label}: {path}\n   {len(twin.children)} measurements; read: SurfaceTopography {t_st_read:.2f} s, "
          f"xtopo {t_x_read:.2f} s (includes the preprocessing the metadata ask for)")
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for name, st_fn, x_fn, x_kw in ANALYSES:
            try:
                st_res = getattr(st, st_fn)(unit="m", nb_points_per_decade=10)
            except Exception as exc:  # noqa: BLE001  (the peer's failure is a result here)
                print(f"   {name}: SurfaceTopography fails: {type(exc).__name__}: {exc}")
                continue
            x_res = getattr(twin.topo, x_fn)(**x_kw)
            row = compare(st_res, _xtopo_curve(x_res))
            ts = _times(lambda: getattr(st, st_fn)(unit="m", nb_points_per_decade=10), repeats)
            tx = _times(lambda: getattr(twin.topo, x_fn)(**x_kw), repeats)
            row.update(name=name, t_st=ts, t_x=tx)
            rows.append(row)
    print(f"   {'':4} {'ST dec':>7} {'xtopo dec':>9} {'covered':>8} {'med dev':>8} {'max dev':>8} {'common':>6}   "
          f"{'ST s (min/med/max)':>22} {'xtopo s (min/med/max)':>22} {'ratio':>6}")
    for r in rows:
        st_t = "/".join(f"{v:.3f}" for v in (min(r["t_st"]), statistics.median(r["t_st"]), max(r["t_st"])))
        x_t = "/".join(f"{v:.3f}" for v in (min(r["t_x"]), statistics.median(r["t_x"]), max(r["t_x"])))
        ratio = statistics.median(r["t_x"]) / statistics.median(r["t_st"])
        print(f"   {r['name']:4} {r['st_decades']:7.2f} {r['xtopo_decades']:9.2f} {100 * r['covered']:7.0f}% "
              f"{100 * r['median_dev']:7.1f}% {100 * r['max_dev']:7.0f}% {r['common']:6d}   {st_t:>22} {x_t:>22} "
              f"{ratio:6.2f}")
    print("   VBM: areal squares, mean of their RMS heights (paper §4.8, xtopo's default); VBM1: the same definition "
          "as SurfaceTopography (profiles along x, RMS over all segments: twin.topo.vbm(kind='1d', average='rms'));\n"
          "        SurfaceTopography's nonuniform line scans take the mean of the segments' RMS heights, as VBM does")
    ok = bool(rows) and all(r["covered"] >= 0.9 and r["median_dev"] <= 0.25 for r in rows if r["name"] != "VBM")
    print(f"   acceptance (covered >= 90 %, median deviation <= 25 %; VBM compared like with like, VBM1): "
          f"{'met' if ok else 'NOT met'}")
    per_measurement(st_topos, twin)
    return rows


def per_measurement(st_topos, twin) -> None:
    """Each measurement's own curve, both packages (reliable part): where the averages differ, is it the curves
    or the averaging? Median |xtopo/SurfaceTopography - 1| at SurfaceTopography's points inside xtopo's range."""
    from xtopo.analysis.acf import acf
    from xtopo.analysis.psd import psd
    from xtopo.analysis.vbm import vbm

    funcs = (("PSD", "power_spectrum_from_profile", lambda ds: psd(ds, kind="1d", **({"dim": "x"} if ds.height.ndim
                                                                                       == 2 else {}))),
             ("ACF", "autocorrelation_from_profile", lambda ds: acf(ds, kind="1d", **({"dim": "x"} if ds.height.ndim
                                                                                        == 2 else {}))),
             ("VBM", "variable_bandwidth_from_profile", vbm),
             ("VBM1", "variable_bandwidth_from_profile", lambda ds: vbm(ds, kind="1d", average="rms")))
    print("   per measurement (reliable parts; median |xtopo/ST - 1| on common points, decades ST / xtopo):")
    for t, (name, node) in zip(st_topos, twin.children.items()):
        ds = node.to_dataset()
        cells = []
        for label, st_fn, x_fn in funcs:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    xs, ys = getattr(t.to_unit("m"), st_fn)(reliable=True, resampling_method=None)
                xs, ys = (np.ma.filled(np.ma.asarray(a, dtype=float), np.nan) for a in (xs, ys))
            except Exception as exc:  # noqa: BLE001
                cells.append(f"{label} ST: {type(exc).__name__}")
                continue
            try:
                c = x_fn(ds)
            except xtopo.XtopoError as exc:
                cells.append(f"{label} xtopo: {str(exc)[:40]}")
                continue
            dim, = c.dims
            xx, yx = np.asarray(c[dim].values, float), np.asarray(c.values, float)
            okx = np.isfinite(yx) & (xx > 0) & (yx > 0)
            oks = np.isfinite(ys) & (xs > 0) & (ys > 0)
            xx, yx, xs, ys = xx[okx], yx[okx], xs[oks], ys[oks]
            if xx.size < 2 or xs.size < 1:
                cells.append(f"{label} ST {xs.size} / xtopo {xx.size} points")
                continue
            inside = (xs >= xx.min()) & (xs <= xx.max())
            dev = np.abs(np.exp(np.interp(np.log(xs[inside]), np.log(xx), np.log(yx))) / ys[inside] - 1)
            span = lambda v: np.log10(v.max() / v.min())  # noqa: E731
            cells.append(f"{label} {100 * np.median(dev) if dev.size else float('nan'):5.1f}% "
                         f"({span(xs):.1f}/{span(xx):.1f})")
        print(f"     {name[:28]:28} " + "  ".join(cells))


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--which", choices=("real", "example", "both"), default="both")
    p.add_argument("--container", help="a contact.engineering download (ZIP) to compare on instead")
    p.add_argument("--real-data", default=REAL, help="directory of the shared real files")
    p.add_argument("--seed", type=int, default=7, help="seed of the example twin")
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args(argv)
    print(f"load average: {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} {os.getloadavg()[2]:.2f} "
          f"(cpus: {os.cpu_count()})")
    import logging

    import SurfaceTopography

    logging.getLogger("SurfaceTopography").setLevel(logging.ERROR)  # "contributes no data" per measurement
    print(f"xtopo {xtopo.__version__}, SurfaceTopography {SurfaceTopography.__version__}")
    with tempfile.TemporaryDirectory() as d:
        if args.container:
            run(args.container, "container", args.repeats)
            return
        if args.which in ("real", "both"):
            if os.path.isdir(args.real_data):
                run(real_container(d, args.real_data), "real files (AFM + optical + stylus)", args.repeats)
            else:
                print(f"(real data not found at {args.real_data}; pass --real-data)")
        if args.which in ("example", "both"):
            run(example_container(d, args.seed), f"example twin (seed {args.seed})", args.repeats)


if __name__ == "__main__":
    main()
