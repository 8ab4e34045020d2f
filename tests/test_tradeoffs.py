"""Smoke test of benchmarks/tradeoffs.py --quick (issue 9): runs, writes the CSV and the PNG."""

import csv
import importlib.util
import pathlib

import pytest

REPO = pathlib.Path(__file__).resolve().parents[1]


def load_tradeoffs():
    """benchmarks/tradeoffs.py as a module (benchmarks/ is not a package)."""
    spec = importlib.util.spec_from_file_location("tradeoffs", REPO / "benchmarks" / "tradeoffs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_quick_run_of_two_panels(tmp_path):
    """The whole pipeline (panels, knees, CSV, PNG) on two cheap panels: a few seconds."""
    rows = load_tradeoffs().main(["--quick", "--out", str(tmp_path), "--only", "psd_bins", "preset"])
    table = list(csv.DictReader(open(tmp_path / "tradeoffs.csv")))
    assert {r["panel"] for r in table} == {"psd_bins", "preset"} and len(table) == len(rows)
    assert sum(r["knee"] == "1" for r in table) == 2  # one per PSD series
    presets = {r["value"]: float(r["error"]) for r in table if r["panel"] == "preset" and r["series"] == "Hertz"}
    assert set(presets) == {"fast", "default", "accurate"}
    assert (tmp_path / "tradeoffs.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow  # 7-16 s on 2 shared cores
def test_quick_run_writes_table_and_figure(tmp_path):
    rows = load_tradeoffs().main(["--quick", "--out", str(tmp_path)])
    table = list(csv.DictReader(open(tmp_path / "tradeoffs.csv")))
    assert len(table) == len(rows) > 0
    panels = {r["panel"] for r in table}
    assert {"tol", "maxiter", "grid", "dtype", "boundary", "psd_bins", "psd_window", "sdrp", "fft_backend",
            "preset"} <= panels
    for r in table:
        assert float(r["time_s"]) > 0 and float(r["error"]) > 0, r
    # every swept knob has a knee and its default marked
    for panel in ("tol", "maxiter", "psd_bins"):
        assert any(r["knee"] == "1" for r in table if r["panel"] == panel), panel
        assert any(r["default"] == "1" for r in table if r["panel"] == panel), panel
    png = (tmp_path / "tradeoffs.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10000
    # the committed docs figure and table exist and list the same panels
    committed = list(csv.DictReader(open(REPO / "docs" / "tradeoffs.csv")))
    assert {r["panel"] for r in committed} == panels
    assert (REPO / "docs" / "tradeoffs.png").stat().st_size > 10000


def test_knee_is_where_the_error_stops_falling():
    mod = load_tradeoffs()
    times = [1.0, 2.0, 3.0, 4.0, 5.0]
    errors = [1.0, 0.1, 0.0105, 0.0101, 0.0100]
    rows = [mod.row("tol", "s", "tol", v, t, e, "err") for v, t, e in zip(range(5), times, errors)]
    mod.mark_knees(rows)
    assert [r["knee"] for r in rows] == [0, 0, 1, 0, 0]
    power_law = [mod.row("grid", "s", "px", v, t, 1 / t, "err") for v, t in zip(range(5), times)]
    mod.mark_knees(power_law)
    assert not any(r["knee"] for r in power_law)  # the error keeps falling: no knee
    flat = [mod.row("psd_bins", "s", "bins", v, 1.0, e, "err") for v, e in zip(range(3), (0.3, 0.1, 0.2))]
    mod.mark_knees(flat)
    assert [r["knee"] for r in flat] == [0, 1, 0]


def _two_digits(x: float) -> float:
    return float(f"{x:.2g}")


def test_docs_presets_table_is_the_committed_csv():
    """docs/tradeoffs.md's preset table quotes docs/tradeoffs.csv (times and errors to 2 digits) and
    xtopo.presets (dtype, tol, maxiter)."""
    import re

    from xtopo.contact.solve import default_tol
    from xtopo.presets import PRESETS

    text = (REPO / "docs" / "tradeoffs.md").read_text(encoding="utf-8")
    committed = [r for r in csv.DictReader(open(REPO / "docs" / "tradeoffs.csv")) if r["panel"] == "preset"]
    series = ("Hertz", "fractal 256² periodic", "fractal 256² free")
    rows = re.findall(r"^\| `(fast|default|accurate)` \| (\w+) \| ([^|]+) \| (\d+) \|(.*)\|\s*$", text, re.M)
    assert [r[0] for r in rows] == ["fast", "default", "accurate"]
    for name, dtype, tol, maxiter, cells in rows:
        knobs = PRESETS["contact"][name]
        assert dtype == knobs["dtype"] and int(maxiter) == knobs["maxiter"]
        assert float(tol.split()[0]) == (knobs["tol"] if knobs["tol"] is not None else default_tol(dtype))
        for cell, s in zip(cells.split("|"), series):
            time_s, error = (c.strip() for c in cell.split("/"))
            ref = next(r for r in committed if r["value"] == name and r["series"] == s)
            assert float(time_s.removesuffix(" s")) == _two_digits(float(ref["time_s"])), (name, s, time_s)
            if error.endswith("%"):
                assert float(error.removesuffix(" %")) == _two_digits(100 * float(ref["error"])), (name, s, error)
            else:
                assert float(error) == _two_digits(float(ref["error"])), (name, s, error)
