"""Per-measurement summary of a twin: what ``xtopo analyze`` prints and stores."""

from __future__ import annotations

import numpy as np
import xarray as xr

from .analysis.scalars import scalars
from .conventions import HEIGHT, convert_length, height_of, is_nonuniform, physical_size

__all__ = ["summary_table", "format_table", "table_rows"]

_COLUMNS = (
    ("kind", "kind", None),
    ("size", "size", "m"),
    ("grid", "grid", None),
    ("tip_radius", "tip radius", "m"),
    ("missing", "missing", "%"),
    ("Sq", "Sq / Rq", "m"),
    ("Sdq", "SΔq / RΔq", "1"),
    ("Sddq", "SΔ²q / RΔ²q", "m-1"),
)


def _row(name: str, ds: xr.Dataset) -> dict:
    ds = convert_length(ds, "m")
    h = ds[HEIGHT]
    s = scalars(ds)
    area = h.ndim == 2
    row = {"measurement": name}
    row["kind"] = "area" if area else ("line (nonuniform)" if is_nonuniform(ds) else "line")
    row["size"] = (physical_size(ds, "y"), physical_size(ds, "x")) if area else (physical_size(ds, "x"),)
    row["grid"] = tuple(int(n) for n in h.shape)
    row["tip_radius"] = float(ds.attrs["tip_radius"]) if "tip_radius" in ds.attrs else np.nan
    row["missing"] = 100 * float((~np.isfinite(height_of(ds))).mean())  # masked, NaN or inf
    if area:
        row.update(Sq=float(s.Sq), Sdq=float(s.Sdq), Sddq=float(s.Sddq))
    else:
        r = s.sel(direction="x")
        row.update(Sq=float(r.Rq), Sdq=float(r.Rdq), Sddq=float(r.Rddq))
    row["instrument"] = str(ds.attrs.get("instrument", ""))
    return row


def summary_table(measurements: dict) -> xr.Dataset:
    """Scalars and grid facts of each measurement, along a ``measurement`` dim (lengths in m).

    Parameters
    ----------
    measurements : dict of str to xarray.Dataset
        Name → measurement.
    """
    rows = [_row(name, ds) for name, ds in measurements.items()]
    names = [r["measurement"] for r in rows]
    coords = {"measurement": ("measurement", names, {"long_name": "measurement"})}
    data = {
        "kind": ("measurement", [r["kind"] for r in rows], {"long_name": "kind of scan"}),
        "instrument": ("measurement", [r["instrument"] for r in rows], {"long_name": "instrument"}),
        "size_x": ("measurement", [r["size"][-1] for r in rows], {"units": "m", "long_name": "physical size in x"}),
        "size_y": ("measurement", [r["size"][0] if len(r["size"]) == 2 else np.nan for r in rows],
                   {"units": "m", "long_name": "physical size in y"}),
        "nx": ("measurement", [r["grid"][-1] for r in rows], {"units": "1", "long_name": "points in x"}),
        "ny": ("measurement", [r["grid"][0] if len(r["grid"]) == 2 else 1 for r in rows],
               {"units": "1", "long_name": "points in y"}),
        "tip_radius": ("measurement", [r["tip_radius"] for r in rows], {"units": "m", "long_name": "tip radius"}),
        "missing_percent": ("measurement", [r["missing"] for r in rows],
                            {"units": "%", "long_name": "missing data"}),
        "rms_height": ("measurement", [r["Sq"] for r in rows],
                       {"units": "m", "long_name": "root mean square height (Sq areas, Rq lines)"}),
        "rms_slope": ("measurement", [r["Sdq"] for r in rows],
                      {"units": "1", "long_name": "root mean square gradient (SΔq areas, RΔq lines)"}),
        "rms_curvature": ("measurement", [r["Sddq"] for r in rows],
                          {"units": "m-1", "long_name": "root mean square curvature (SΔ²q areas, RΔ²q lines)"}),
    }
    return xr.Dataset(data, coords=coords, attrs={"title": "measurement summary"})


def _fmt_len(v: float) -> str:
    if not np.isfinite(v):
        return "-"
    for unit, f in (("mm", 1e-3), ("µm", 1e-6), ("nm", 1e-9)):
        if abs(v) >= f:
            return f"{v / f:.3g} {unit}"
    return f"{v / 1e-12:.3g} pm"


def table_rows(table: xr.Dataset) -> tuple[list[str], list[list[str]]]:
    """Header and formatted cells of :func:`summary_table` (lengths in readable units)."""
    header = ["measurement", "kind", "size", "grid", "tip radius", "missing", "Sq/Rq", "SΔq/RΔq", "SΔ²q/RΔ²q"]
    lines = []
    for i in range(table.sizes["measurement"]):
        t = table.isel(measurement=i)
        if t.kind.item() == "area":
            size = f"{_fmt_len(float(t.size_y))} × {_fmt_len(float(t.size_x))}"
            grid = f"{int(t.ny)} × {int(t.nx)}"
        else:
            size, grid = _fmt_len(float(t.size_x)), f"{int(t.nx)}"
        lines.append([str(t.measurement.item()), str(t.kind.item()), size, grid, _fmt_len(float(t.tip_radius)),
                      f"{float(t.missing_percent):.1f} %", _fmt_len(float(t.rms_height)),
                      f"{float(t.rms_slope):.3g}", f"{float(t.rms_curvature):.3g} m⁻¹"])
    return header, lines


def format_table(table: xr.Dataset) -> str:
    """A plain-text table of :func:`summary_table` for the terminal."""
    header, lines = table_rows(table)
    widths = [max(len(r[k]) for r in [header] + lines) for k in range(len(header))]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    out = [fmt.format(*header), fmt.format(*["-" * w for w in widths])]
    out += [fmt.format(*r) for r in lines]
    return "\n".join(out)
