"""Read every real instrument file with xtopo and with SurfaceTopography, side by side.

Usage::

    python benchmarks/bench_io.py [--data ../shared/data/real] [--repeats 5] [--json out.json]

For each file: the median wall time of ``repeats`` complete reads (xtopo:
``open_topography`` → validated Dataset in metres, including the SHA-256 provenance
checksum; SurfaceTopography: ``open_topography(path).topography()`` → heights in memory),
after one untimed warm-up read. Files one package cannot read are listed but left out of
the totals; the totals and their ratio cover the files both read.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import statistics
import sys
import time
import warnings

REPO = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

#: Generic files that state no unit: both packages get the unit from the caller.
XTOPO_OPTIONS = {"opdx-3.txt": {"file_units": "m"}}
ST_OPTIONS = {"opdx-3.txt": {"unit": "m"}}


def _xtopo_reader():
    import xtopo

    def read(path):
        ds = xtopo.open_topography(path, **XTOPO_OPTIONS.get(path.name, {}))
        return ds.height.values

    return read


def _st_reader():
    import SurfaceTopography

    def read(path):
        reader = SurfaceTopography.open_topography(str(path))
        try:
            topo = reader.topography(**ST_OPTIONS.get(path.name, {}))
            return topo.heights()
        finally:
            close = getattr(reader, "close", None)
            if close is not None:
                close()

    return read


def time_reads(read, path, repeats):
    """Median seconds of ``repeats`` reads after a warm-up; ``None`` and the error if it fails."""
    try:
        read(path)
    except Exception as exc:  # noqa: BLE001  report, do not stop the benchmark
        return None, f"{type(exc).__name__}: {str(exc)[:80]}"
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        read(path)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), None


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=str((REPO / ".." / "shared" / "data" / "real").resolve()))
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", default=None, help="write the per-file results here")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")
    files = sorted(p for p in pathlib.Path(args.data).iterdir() if p.is_file() and p.name != "MANIFEST.md")
    readers = {"xtopo": _xtopo_reader(), "SurfaceTopography": _st_reader()}
    rows = []
    print(f"{'file':38s} {'bytes':>9s} {'xtopo ms':>10s} {'ST ms':>10s} {'ratio':>7s}")
    for path in files:
        row = {"file": path.name, "bytes": path.stat().st_size}
        for name, read in readers.items():
            row[name], row[f"{name}_error"] = time_reads(read, path, args.repeats)
        rows.append(row)
        x, s = row["xtopo"], row["SurfaceTopography"]
        fmt = lambda v: f"{1e3 * v:10.2f}" if v is not None else f"{'n/a':>10s}"  # noqa: E731
        ratio = f"{x / s:7.2f}" if x is not None and s is not None else f"{'':>7s}"
        print(f"{path.name:38s} {row['bytes']:9d} {fmt(x)} {fmt(s)} {ratio}", flush=True)
    both = [r for r in rows if r["xtopo"] is not None and r["SurfaceTopography"] is not None]
    tx = sum(r["xtopo"] for r in both)
    ts = sum(r["SurfaceTopography"] for r in both)
    print(f"\nfiles read by both: {len(both)} of {len(rows)}; total xtopo {1e3 * tx:.1f} ms, "
          f"SurfaceTopography {1e3 * ts:.1f} ms, ratio xtopo/ST {tx / ts if ts else float('nan'):.2f}")
    for name in readers:
        failed = [(r["file"], r[f"{name}_error"]) for r in rows if r[name] is None]
        if failed:
            print(f"{name} could not read {len(failed)}: " + "; ".join(f"{f} ({e})" for f, e in failed))
    if args.json:
        pathlib.Path(args.json).write_text(json.dumps({"rows": rows, "total_xtopo": tx, "total_st": ts,
                                                       "n_both": len(both)}, indent=1))
    return rows


if __name__ == "__main__":
    main()
