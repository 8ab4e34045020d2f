"""Speed versus accuracy of the knobs users turn (issue 9): error vs time, one panel per knob.

Usage::

    PYTHONPATH=. python benchmarks/tradeoffs.py            # writes docs/tradeoffs.{png,csv} (~5 min, 2 cores)
    PYTHONPATH=. python benchmarks/tradeoffs.py --quick --out /tmp/t   # tiny sizes, seconds

Knobs and the reference each error is measured against:

=============  ==============================================================  =========================
panel          knob                                                            error against
=============  ==============================================================  =========================
tol            contact ``tol`` (float64 and float32)                           Hertz (analytic); a fractal
                                                                               solved to tol 1e-11
maxiter        contact ``maxiter`` at the default tol                          fractal solved to tol 1e-11
grid           pixels across the contact spot (2a/Δx)                          Hertz; Westergaard (line)
dtype          float32 vs float64 (each at its default tol)                    Hertz; fractal reference
boundary       free (Love, 2N padding) vs periodic with a larger cell          Hertz (sphere: free is exact)
psd_bins       log bins per decade of ``psd(kind="iso")``                     prescribed PSD (FractalPSD)
psd_window     Hann vs no window on nonperiodic data                           prescribed PSD
sdrp           linear interpolation (log-spaced ℓ) vs integer η (ℓ = kΔx)      slope of the prescribed PSD
fft_backend    scipy vs pyFFTW, 1 or 2 threads (30 CG iterations, plans built  scipy, 2-thread result
               beforehand)
=============  ==============================================================  =========================

Errors are relative L2 norms of the pressure field (contact) or RMS of ``ln(measured/true)``
(PSD, SDRP), averaged over seeds for the statistical quantities. Times are medians of
``--repeat`` runs (default 5) of the call the knob affects (contact: the solve, Green's function built
beforehand). The knee of each swept series is its cheapest knob value whose error is within
10 % of the smallest error of the series (where the curve reaches its floor, e.g. the
discretisation error of a Hertz contact); a series whose error still falls at its most
expensive value has no knee in range; where the knob does not change the time (PSD bins) the
knee is the point of smallest error.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import sys
import time
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)

from xtopo import datasets  # noqa: E402
from xtopo.analysis.psd import psd  # noqa: E402
from xtopo.analysis.sdrp import sdrp  # noqa: E402
from xtopo.contact import Scene  # noqa: E402
from xtopo.contact.solve import default_tol  # noqa: E402
from xtopo.errors import ConvergenceWarning  # noqa: E402
from xtopo.presets import NAMES, PRESETS  # noqa: E402

FIELDS = ["panel", "series", "knob", "value", "time_s", "error", "error_measure", "default", "knee"]
MEAN_PRESSURE = 0.005  # p/E* on the fractal (rms slope 0.1): about 10 % contact
BACKEND_ITERATIONS = 30  # fixed CG iterations of the FFT-backend comparison


class Config:
    """Problem sizes of a full or a quick run."""

    def __init__(self, quick: bool, repeat: int | None):
        self.quick = quick
        self.repeat = repeat if repeat is not None else (1 if quick else 5)
        self.hertz_ppr = 8 if quick else 32  # pixels per contact radius of the Hertz reference case
        self.fractal_n = 64 if quick else 256
        self.psd_n = 128 if quick else 512
        self.seeds = 2 if quick else 6
        self.tols = [1e-2, 1e-3, 1e-5, 1e-8] if quick else [1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9]
        self.maxiters = [5, 20, 80, 1000] if quick else [10, 20, 40, 60, 80, 100, 120, 160, 1000]
        self.spots = [8, 16, 32] if quick else [8, 12, 16, 24, 32, 48, 64, 96]
        self.cells = [3, 6] if quick else [3, 4, 6, 8, 12]
        self.bins = [5, 10, 20] if quick else [2.5, 5, 10, 20, 40]
        self.backend_sizes = [32] if quick else [256, 512]


def timed(fn, repeat):
    """Median wall time of ``repeat`` calls of ``fn`` and the last result."""
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def rel_l2(a, b, mask=None):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if mask is not None:
        a, b = a[mask], b[mask]
    return float(np.sqrt(np.sum((a - b) ** 2) / np.sum(b**2)))


def rms_log(measured, true):
    m = np.asarray(measured, dtype=float)
    t = np.asarray(true, dtype=float)
    ok = (m > 0) & (t > 0)
    return float(np.sqrt(np.mean(np.log(m[ok] / t[ok]) ** 2)))


# -- contact problems -------------------------------------------------------------------------
class Hertz:
    """Paraboloid (R = 1, E* = 1) pressed to contact radius a = 1: analytic pressure p0 sqrt(1 - r²)."""

    def __init__(self, ppr, cell=3.0, periodic=False):
        n = int(round(cell * ppr))
        self.size = n / ppr
        self.ds = datasets.sphere((n, n), self.size, 1.0, kind="paraboloid", units="um", periodic=periodic)
        self.load = 4.0 / 3.0
        p0 = 3 * self.load / (2 * np.pi)
        y, x = np.meshgrid(*(np.arange(n) / ppr - self.size / 2,) * 2, indexing="ij")
        self.r = np.hypot(x, y)
        self.exact = p0 * np.sqrt(np.clip(1 - self.r**2, 0, None))
        self.periodic = periodic

    def scene(self, **kw):
        sc = Scene(self.ds, periodic=self.periodic, **kw)
        sc.convolution  # Green's function outside the timing
        return sc

    def error(self, res):
        return rel_l2(res.pressure.values, self.exact, self.r <= 1.5)

    def solve(self, scene, repeat, **kw):
        t, r = timed(lambda: scene.solve(load=self.load, **kw), repeat)
        return t, self.error(r)


class Westergaard:
    """Periodic sinusoid ``A cos(2πx/λ)`` (line scan): analytic pressure (Johnson 1985, §13.2).

    The grid has ``spot_px`` pixels across the contact at p̄ = 0.3 p*; the error is averaged over
    nine loads p̄/p* = 0.2 … 0.4 so that where the contact edge falls between pixels averages out.
    """

    RATIOS = tuple(np.linspace(0.2, 0.4, 9))

    def __init__(self, spot_px):
        width = 2 / np.pi * np.arcsin(np.sqrt(0.3))  # 2a/λ at p̄ = 0.3 p*
        n = max(8, int(round(spot_px / width)))
        amp = 0.01
        self.ds = datasets.sinusoid(n, 1.0, amplitude=amp, units="um")
        self.pstar = np.pi * amp
        x = np.arange(n) / n
        self.x = np.where(x > 0.5, x - 1, x)
        self.mean_pressure = 0.3 * self.pstar
        self.exact = self.pressure(0.3)

    def pressure(self, ratio):
        """``p(x) = 2 p̄ cos(πx/λ) sqrt(sin²(πa/λ) - sin²(πx/λ)) / sin²(πa/λ)``, ``sin²(πa/λ) = p̄/p*``."""
        inside = np.clip(ratio - np.sin(np.pi * self.x) ** 2, 0, None)
        return 2 * self.pstar * np.cos(np.pi * self.x) * np.sqrt(inside)

    def solve(self, repeat):
        sc = Scene(self.ds)
        sc.convolution
        times, errs = [], []
        for ratio in self.RATIOS:
            t, r = timed(lambda: sc.solve(mean_pressure=ratio * self.pstar), repeat)
            times.append(t)
            errs.append(rel_l2(r.pressure.values, self.pressure(ratio)))
        return statistics.median(times), float(np.mean(errs))


class Fractal:
    """Seeded fractal contact at ``MEAN_PRESSURE``; reference: the same grid solved to tol 1e-11."""

    def __init__(self, n, periodic):
        self.ds = datasets.fractal_surface((n, n), 1.0, hurst=0.8, rms_slope=0.1, short_cutoff=4.0 / n, seed=11,
                                           periodic=periodic, units="um")
        self.periodic = periodic
        self.ref = Scene(self.ds).solve(mean_pressure=MEAN_PRESSURE, tol=1e-11, maxiter=50000).pressure.values

    def scene(self, **kw):
        sc = Scene(self.ds, **kw)
        sc.convolution
        return sc

    def solve(self, scene, repeat, **kw):
        t, r = timed(lambda: scene.solve(mean_pressure=MEAN_PRESSURE, **kw), repeat)
        return t, rel_l2(r.pressure.values, self.ref)


# -- the panels -------------------------------------------------------------------------------
def row(panel, series, knob, value, t, err, measure, default=False):
    return dict(panel=panel, series=series, knob=knob, value=value, time_s=t, error=err, error_measure=measure,
                default=int(bool(default)), knee=0)


def panel_tol(cfg, hertz, fractal):
    rows = []
    for dtype in ("float64", "float32"):
        sc = hertz.scene(dtype=dtype)
        for tol in cfg.tols:
            if dtype == "float32" and tol < 1e-6:
                continue  # float32 cannot resolve it
            t, e = hertz.solve(sc, cfg.repeat, tol=tol, maxiter=100000)
            rows.append(row("tol", f"Hertz {dtype}", "tol", tol, t, e, "rel. L2 pressure error (Hertz: vs analytic)",
                            tol == default_tol(dtype) and dtype == "float64"))
    sc = fractal.scene()
    for tol in cfg.tols:
        t, e = fractal.solve(sc, cfg.repeat, tol=tol, maxiter=100000)
        rows.append(row("tol", f"fractal {cfg.fractal_n}² periodic", "tol", tol, t, e,
                        "rel. L2 pressure error (fractal: vs tol=1e-11)", tol == default_tol("float64")))
    return rows


def panel_maxiter(cfg, fractals):
    rows = []
    for name, fr in fractals.items():
        sc = fr.scene()
        for m in cfg.maxiters:
            t, e = fr.solve(sc, cfg.repeat, maxiter=m)
            rows.append(row("maxiter", f"fractal {cfg.fractal_n}² {name}", "maxiter", m, t, e,
                            "rel. L2 pressure error vs tol=1e-11 solve", m == 1000))
    return rows


def panel_grid(cfg):
    rows = []
    for spot in cfg.spots:
        h = Hertz(spot / 2)
        t, e = h.solve(h.scene(), cfg.repeat)
        rows.append(row("grid", "Hertz (free, area)", "pixels across contact", spot, t, e,
                        "rel. L2 pressure error vs analytic"))
        w = Westergaard(spot)
        t, e = w.solve(cfg.repeat)
        rows.append(row("grid", "Westergaard (periodic, line)", "pixels across contact", spot, t, e,
                        "rel. L2 pressure error vs analytic"))
    return rows


def panel_scene_option(cfg, hertz, fractals, panel, option, values, default):
    """One point per value of a :class:`Scene` keyword (``dtype``, ``preset``) on each contact problem."""
    rows = []
    for value in values:
        t, e = hertz.solve(hertz.scene(**{option: value}), cfg.repeat)
        rows.append(row(panel, "Hertz", option, value, t, e, "rel. L2 pressure error (Hertz: vs analytic)",
                        value == default))
        for name, fr in fractals.items():
            t, e = fr.solve(fr.scene(**{option: value}), cfg.repeat)
            rows.append(row(panel, f"fractal {cfg.fractal_n}² {name}", option, value, t, e,
                            "rel. L2 pressure error (fractal: vs tol=1e-11)", value == default))
    return rows


def panel_boundary(cfg):
    ppr = cfg.hertz_ppr // 2
    rows = []
    h = Hertz(ppr)
    t, e = h.solve(h.scene(), cfg.repeat)
    rows.append(row("boundary", "free (cell 3a)", "boundary", "free", t, e, "rel. L2 pressure error vs Hertz", True))
    for cell in cfg.cells:
        h = Hertz(ppr, cell=cell, periodic=True)
        t, e = h.solve(h.scene(), cfg.repeat)
        rows.append(row("boundary", "periodic", "cell size / a", cell, t, e, "rel. L2 pressure error vs Hertz"))
    return rows


def _surfaces(cfg, periodic):
    return [datasets.fractal_surface((cfg.psd_n,) * 2, 1.0, hurst=0.8, rms_height=1.0, long_cutoff=0.125, seed=s,
                                     periodic=periodic, units="um") for s in range(cfg.seeds)]


def _self_affine(q, truth, n):
    return (q > 2 * truth.q_long) & (q < np.pi * n / 2)


def panel_psd_bins(cfg, surfaces):
    rows = []
    n = cfg.psd_n
    decades = np.log10(np.sqrt(2) * n / 2)  # from 2π/L to the corner |q| of the grid
    for name, surfs in surfaces.items():
        truth = datasets.prescribed_psd(surfs[0])
        for per_decade in cfg.bins:
            nb = int(np.ceil(per_decade * decades))
            errs, times = [], []
            for ds in surfs:
                t, c = timed(lambda: psd(ds, "iso", nb_points=nb, reliable=False), cfg.repeat)
                q = c.q.values
                m = _self_affine(q, truth, n)
                errs.append(rms_log(c.values[m], truth.c_iso(q[m])))
                times.append(t)
            rows.append(row("psd_bins", f"Ciso {n}² {name}", "bins per decade", per_decade,
                            statistics.median(times), float(np.mean(errs)), "RMS ln(C/C_prescribed)",
                            per_decade == 10))
    return rows


def panel_psd_window(cfg, surfaces):
    rows = []
    n = cfg.psd_n
    surfs = surfaces["nonperiodic"]
    truth = datasets.prescribed_psd(surfs[0])
    for kind in ("1d", "iso"):
        exact = {}
        for window in ("hann", None):
            errs, times = [], []
            for ds in surfs:
                t, c = timed(lambda: psd(ds, kind, window=window, reliable=False), cfg.repeat)
                q = c.q.values
                m = _self_affine(q, truth, n)
                key = tuple(q[m])
                if key not in exact:  # C1D of the prescribed PSD is a quadrature: once per q set
                    exact[key] = truth.c1d(q[m]) if kind == "1d" else truth.c_iso(q[m])
                errs.append(rms_log(c.values[m], exact[key]))
                times.append(t)
            rows.append(row("psd_window", f"C{kind} {n}² nonperiodic", "window", window or "none",
                            statistics.median(times), float(np.mean(errs)), "RMS ln(C/C_prescribed)",
                            window == "hann"))
    return rows


def _slope_truth(ds, distances):
    """Expected scale-dependent slope along x of the band-limited surface ``ds`` was synthesised as."""
    truth = datasets.prescribed_psd(ds)
    n = ds.sizes["x"]
    dx = float(ds.x[1] - ds.x[0])
    m = n if int(ds.attrs["periodic"]) else 2 * n  # nonperiodic: a window of a periodic parent twice as large
    qx = 2 * np.pi * np.fft.fftfreq(m, d=dx)
    qq = np.hypot(qx[None, :], qx[:, None])
    c = truth.c_iso(qq) / (m * dx) ** 2  # E|h̃|²/A² per mode
    cx = c.sum(axis=0)  # marginal over q_y
    return np.array([np.sqrt(2 * np.sum(cx * (1 - np.cos(qx * ell)))) / ell for ell in distances])


def panel_sdrp(cfg, surfaces):
    rows = []
    n = cfg.psd_n
    dx = 1.0 / n
    for name, surfs in surfaces.items():
        nb = int(np.ceil(10 * np.log10(n / 2))) + 1
        log_spaced = np.geomspace(dx, n * dx / 2, nb)  # fractional η, linear interpolation (twin collocation)
        integer = np.unique(np.round(log_spaced / dx)) * dx  # integer η: the default distances of sdrp()
        for label, d in (("linear interpolation", log_spaced), ("integer η", integer)):
            small = d <= 16 * dx  # interpolation matters at small η
            errs, times = [], []
            for ds in surfs:
                t, s = timed(lambda: sdrp(ds, distances=d, reliable=False), cfg.repeat)
                errs.append(rms_log(s.values[small], _slope_truth(ds, d[small])))
                times.append(t)
            rows.append(row("sdrp", f"slope {n}² {name}", "distances", label, statistics.median(times),
                            float(np.mean(errs)), "RMS ln(slope/prescribed), ℓ ≤ 16Δx",
                            label.startswith("integer")))
    return rows


def panel_fft_backend(cfg):
    rows = []
    old = os.environ.get("XTOPO_FFT_THREADS")
    try:
        for n in cfg.backend_sizes:
            ds = datasets.fractal_surface((n, n), 1.0, hurst=0.8, rms_slope=0.1, short_cutoff=4.0 / n, seed=11,
                                          units="um")
            results = {}
            for backend in ("scipy", "pyfftw"):
                for threads in (1, 2):
                    os.environ["XTOPO_FFT_THREADS"] = str(threads)
                    sc = Scene(ds, backend=backend)
                    sc.solve(mean_pressure=MEAN_PRESSURE, maxiter=1)  # FFTW plans (FFTW_MEASURE) untimed
                    t, r = timed(lambda: sc.solve(mean_pressure=MEAN_PRESSURE, tol=1e-12, maxiter=BACKEND_ITERATIONS),
                                 cfg.repeat)
                    results[(backend, threads)] = (t, r.pressure.values)
            ref = results[("scipy", 2)][1]
            for (backend, threads), (t, p) in results.items():
                err = max(rel_l2(p, ref), 1e-16)
                rows.append(row("fft_backend", f"{backend}, {threads} thread{'s' if threads > 1 else ''}",
                                f"grid {n}² periodic", n, t, err, "rel. L2 difference to scipy, 2 threads",
                                backend == "pyfftw" and threads == 1))  # the default below 2048² FFT grids
    finally:
        if old is None:
            os.environ.pop("XTOPO_FFT_THREADS", None)
        else:
            os.environ["XTOPO_FFT_THREADS"] = old
    return rows


# -- knees, table, figure ---------------------------------------------------------------------
SWEPT = {"tol", "maxiter", "grid", "psd_bins", "boundary"}
KNEE_WITHIN = 0.1  # a point is on the error floor within 10 % of the smallest error of its series


def mark_knees(rows, within=KNEE_WITHIN):
    """Set ``knee=1`` on the knee of every swept series (see the module docstring)."""
    series = {}
    for r in rows:
        if r["panel"] in SWEPT and isinstance(r["value"], (int, float)):
            series.setdefault((r["panel"], r["series"]), []).append(r)
    for pts in series.values():
        if len(pts) < 3:
            continue
        t = np.array([p["time_s"] for p in pts])
        e = np.array([p["error"] for p in pts])
        if t.max() < 1.5 * t.min():  # the knob does not cost time: the best error
            k = int(np.argmin(e))
        else:  # sweep order = cheap to expensive: the first value on the error floor
            k = int(np.flatnonzero(e <= (1 + within) * e.min())[0])
            if k == len(pts) - 1:
                continue  # the error still falls at the end of the sweep: no knee in range
        pts[k]["knee"] = 1
    return rows


def write_csv(rows, path):
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=FIELDS)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{r[k]:.4g}" if isinstance(r[k], float) else r[k]) for k in FIELDS})


TITLES = {"tol": "solver tolerance tol", "maxiter": "solver maxiter", "grid": "pixels across a contact spot",
          "dtype": "float32 vs float64", "boundary": "free vs periodic boundary (sphere)",
          "psd_bins": "PSD log bins per decade", "psd_window": "PSD window (nonperiodic data)",
          "sdrp": "SDRP: interpolated vs integer η", "fft_backend": "FFT backend and threads (same result)",
          "preset": "presets fast / default / accurate"}


#: panels whose knob does not change the time: error against the knob value instead
VALUE_AXIS = {"psd_bins"}
#: panels of alternatives rather than a sweep: markers joined by a dashed line
CATEGORICAL = {"dtype", "psd_window", "sdrp", "preset"}


def _label(value):
    return f"{value:g}" if isinstance(value, (int, float)) else str(value)


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    panels = list(dict.fromkeys(r["panel"] for r in rows))
    ncol = 4
    nrow = int(np.ceil(len(panels) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.4 * ncol, 3.7 * nrow), squeeze=False)
    for ax, panel in zip(axes.flat, panels):
        pr = [r for r in rows if r["panel"] == panel]
        backend = panel == "fft_backend"
        for s in dict.fromkeys(r["series"] for r in pr):
            pts = [r for r in pr if r["series"] == s]
            if backend:  # every backend gives the same answer (≤ 1e-13): time against the grid size
                xy = [(p["value"], p["time_s"]) for p in pts]
            elif panel in VALUE_AXIS:
                xy = [(p["value"], p["error"]) for p in pts]
            else:
                xy = [(p["time_s"], p["error"]) for p in pts]
            style = "o--" if panel in CATEGORICAL else "o-"
            ax.plot(*zip(*xy), style, ms=4, lw=1, label=s)
            for p, (x, y) in zip(pts, xy):
                ax.annotate(_label(p["value"]), (x, y), fontsize=6, xytext=(3, 3), textcoords="offset points")
                if p["default"]:
                    ax.plot(x, y, "*", ms=13, mfc="none", mec="k", mew=1.2)
                if p["knee"]:
                    ax.plot(x, y, "D", ms=9, mfc="none", mec="r", mew=1.2)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(TITLES.get(panel, panel), fontsize=9)
        if backend:
            ax.set_xlabel("grid (N², periodic), 30 CG iterations", fontsize=8)
            ax.set_ylabel("time (s, median)", fontsize=8)
        elif panel in VALUE_AXIS:
            t = statistics.median(p["time_s"] for p in pr)
            ax.set_xlabel(f"{pr[0]['knob']} (time flat: {1e3 * t:.1f} ms)", fontsize=8)
            ax.set_ylabel("\n".join(dict.fromkeys(p["error_measure"] for p in pr)), fontsize=7)
        else:
            ax.set_xlabel("time (s, median)", fontsize=8)
            ax.set_ylabel("\n".join(dict.fromkeys(p["error_measure"] for p in pr)), fontsize=7)
        ax.tick_params(labelsize=7)
        for axis in (ax.xaxis, ax.yaxis):  # ticks at 1, 2, 5 × 10^k: readable on axes spanning < 1 decade
            axis.set_major_locator(matplotlib.ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
            axis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.legend(fontsize=6, loc="best")
    for ax in list(axes.flat)[len(panels):]:
        ax.axis("off")
    fig.suptitle("xtopo speed vs accuracy (black star: default, red diamond: knee)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def read_csv(path):
    """Rows of a ``tradeoffs.csv`` (numbers parsed), e.g. to redraw the figure."""
    rows = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            for k in ("time_s", "error"):
                r[k] = float(r[k])
            for k in ("default", "knee"):
                r[k] = int(r[k])
            try:
                r["value"] = float(r["value"])
            except ValueError:
                pass
            rows.append(r)
    return rows


def print_summary(rows):
    print(f"\n{'panel':>12} {'series':>30} {'value':>22} {'time s':>9} {'error':>10}  default knee")
    for r in rows:
        v = f"{r['value']:g}" if isinstance(r["value"], (int, float)) else str(r["value"])
        print(f"{r['panel']:>12} {r['series']:>30} {v:>22} {r['time_s']:9.4f} {r['error']:10.3g}  "
              f"{'*' if r['default'] else ' ':>7} {'◇' if r['knee'] else ''}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="tiny sizes (seconds): a smoke test")
    ap.add_argument("--out", default=os.path.join(ROOT, "docs"), help="folder for tradeoffs.png / tradeoffs.csv")
    ap.add_argument("--repeat", type=int, default=None, help="timing repeats (median); default 5 (quick: 1)")
    ap.add_argument("--only", nargs="*", default=None, help="run only these panels")
    ap.add_argument("--replot", action="store_true", help="redraw tradeoffs.png from the tradeoffs.csv in --out")
    args = ap.parse_args(argv)
    if args.replot:
        rows = read_csv(os.path.join(args.out, "tradeoffs.csv"))
        plot(rows, os.path.join(args.out, "tradeoffs.png"))
        return rows
    cfg = Config(args.quick, args.repeat)
    os.makedirs(args.out, exist_ok=True)
    t_start = time.perf_counter()
    print(f"load average at start {os.getloadavg()}, cpus {os.cpu_count()}, "
          f"XTOPO_FFT_THREADS={os.environ.get('XTOPO_FFT_THREADS', 'unset')}, repeat {cfg.repeat}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # maxiter sweeps stop early on purpose
        rows = run_panels(cfg, args.only)
    mark_knees(rows)
    csv_path = os.path.join(args.out, "tradeoffs.csv")
    png_path = os.path.join(args.out, "tradeoffs.png")
    write_csv(rows, csv_path)
    plot(rows, png_path)
    print_summary(rows)
    print(f"\npresets (xtopo.presets.PRESETS['contact']): "
          + "; ".join(f"{k}: {dict(v)}" for k, v in PRESETS["contact"].items()))
    print(f"wrote {csv_path} and {png_path} in {time.perf_counter() - t_start:.0f} s; "
          f"load average at end {os.getloadavg()}")
    return rows


def run_panels(cfg, only=None):
    """Rows of every panel (or of those named in ``only``)."""
    hertz = Hertz(cfg.hertz_ppr)
    fractals = {"periodic": Fractal(cfg.fractal_n, True), "free": Fractal(cfg.fractal_n, False)}
    surfaces = {"periodic": _surfaces(cfg, True), "nonperiodic": _surfaces(cfg, False)}
    panels = {
        "tol": lambda: panel_tol(cfg, hertz, fractals["periodic"]),
        "maxiter": lambda: panel_maxiter(cfg, fractals),
        "grid": lambda: panel_grid(cfg),
        "dtype": lambda: panel_scene_option(cfg, hertz, fractals, "dtype", "dtype", ("float32", "float64"),
                                            "float64"),
        "boundary": lambda: panel_boundary(cfg),
        "psd_bins": lambda: panel_psd_bins(cfg, surfaces),
        "psd_window": lambda: panel_psd_window(cfg, surfaces),
        "sdrp": lambda: panel_sdrp(cfg, surfaces),
        "fft_backend": lambda: panel_fft_backend(cfg),
        "preset": lambda: panel_scene_option(cfg, hertz, fractals, "preset", "preset", NAMES, "default"),
    }
    rows = []
    for name, fn in panels.items():
        if only and name not in only:
            continue
        t0 = time.perf_counter()
        rows += fn()
        print(f"{name:>12}: {time.perf_counter() - t0:6.1f} s   (load {os.getloadavg()[0]:.2f})", flush=True)
    return rows


if __name__ == "__main__":
    main()
