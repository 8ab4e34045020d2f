"""Shared plumbing of the scale-dependent analyses (PSD, ACF, VBM, SDRP): input preparation,
log binning of xarray results and result annotation. Not public API."""

from __future__ import annotations

import numpy as np
import xarray as xr

from .._apply import apply_lateral
from .._checks import bin_count
from .._kernels.binning import BinPlan, log_edges
from ..conventions import (PROVENANCE_ATTRS, X, Y, append_history, height_of, is_nonuniform, is_periodic,
                           lateral_dims, length_coord, provenance_of, shared_length_unit, spacing)
from ..errors import GridError

__all__ = ["Prepared", "prepare", "log_bin", "per_decade", "length_coord", "finish", "provenance", "split_parameters",
           "log_plan", "unit_of"]

#: default density of logarithmic bins/collocation points
POINTS_PER_DECADE = 10


class Prepared:
    """Heights plus what the analyses need to know about their grid."""

    def __init__(self, h: xr.DataArray, units: str, periodic: bool, lat: tuple, resampled: bool):
        self.h = h
        self.units = units
        self.periodic = periodic
        self.lat = lat
        self.resampled = resampled

    @property
    def is_area(self) -> bool:
        return self.lat == (Y, X)

    def spacing(self, dim: str) -> float:
        return spacing(self.h, dim)

    def size(self, dim: str) -> float:
        return self.h.sizes[dim] * spacing(self.h, dim)

    def check_iso(self, what: str, kind: str = "iso") -> None:
        """Raise :class:`GridError` unless the data are an area scan (for ``kind="iso"``: of more than one pixel)."""
        if not self.is_area:
            raise GridError(f"{what}(kind={kind!r}) needs an area scan; use kind='1d' for line scans")
        if kind == "iso" and self.h.sizes[X] * self.h.sizes[Y] < 2:
            raise GridError(f"{what}(kind='iso') needs at least 2 pixels along 'x' or 'y'; this map is 1×1")

    def check_dim(self, dim: str) -> str:
        if not isinstance(dim, str) or dim not in self.lat:
            raise GridError(f"dim={dim!r} is not a lateral dimension of these data (they have {self.lat})")
        return dim

    def along(self, kernel, dim: str, coord: xr.Variable, height_power, what: str, **kwargs) -> xr.DataArray:
        """``kernel`` over the profiles along ``dim`` (the other lateral dim as its ``rows``), onto ``coord``."""
        other = tuple(d for d in self.lat if d != dim)
        name = coord.dims[0]
        out = apply_lateral(kernel, self.h, core_dims=other + (dim,), output_core_dims=[[name]],
                            output_sizes={name: coord.size}, kwargs=dict(kwargs, rows=len(other)),
                            height_power=(height_power,), what=what)
        return out.assign_coords({name: coord})

    def attrs(self, **extra) -> dict:
        a = {"periodic": int(self.periodic)}
        if self.resampled:
            a["resampled"] = "nonuniform line scan linearly interpolated onto a uniform grid with the same number of points"
        a.update(extra)
        return a


def prepare(obj) -> Prepared:
    """Heights of a measurement, with nonuniform line scans interpolated onto a uniform grid."""
    h = height_of(obj)
    lat = lateral_dims(h)
    units = shared_length_unit(h, "heights")
    resampled = False
    if is_nonuniform(h) or is_nonuniform(obj):
        xv = np.asarray(h[X].values, dtype=float)
        new = np.linspace(xv[0], xv[-1], xv.size)
        attrs = {k: v for k, v in h.attrs.items() if k != "grid"}
        cattrs = {**h[X].attrs, "spacing": float(new[1] - new[0])}
        if h.chunks is None and h.dims == (X,) and set(h.coords) == {X} and h.dtype == np.float64:
            # float64 in memory: numpy's linear interpolation, as xarray's runs it, without the reindexing (0.1 of
            # 4 ms for 4000 points; the twin averages resample each TEM profile once per analysis)
            h = xr.DataArray(np.interp(new, xv, h.values), dims=(X,), coords={X: (X, new, cattrs)}, attrs=attrs,
                             name=h.name)
        else:
            h = h.chunk({X: -1}) if h.chunks is not None else h
            h = h.interp({X: new}, method="linear", assume_sorted=True)
            h.attrs = attrs
            h.coords[X].attrs = cattrs
        resampled = True
    return Prepared(h, units, is_periodic(h) or is_periodic(obj), lat, resampled)


def per_decade(lo: float, hi: float, nb_points=None, *, samples: int) -> int:
    """Number of log bins: ``nb_points`` or ``POINTS_PER_DECADE`` per decade of ``[lo, hi]``.

    ``samples``: how many values are binned (see :func:`xtopo._checks.bin_count` for the limit on ``nb_points``).
    """
    if nb_points is not None:
        return max(1, bin_count(nb_points, "nb_points", samples))
    return max(1, int(np.ceil(POINTS_PER_DECADE * np.log10(hi / lo))))


def log_plan(values: np.ndarray, lo: float, hi: float, nb_points=None, weights=None) -> BinPlan:
    """Logarithmic bins from ``lo`` to ``hi`` of the positive ``values`` (each weighted by ``weights``)."""
    pos = values > 0
    bins = per_decade(lo, hi, nb_points, samples=int(np.count_nonzero(pos)))
    return BinPlan(np.where(pos, values, -1.0), log_edges(lo, hi, bins), weights)


def log_bin(da: xr.DataArray, dim: str, nb_points=None) -> xr.DataArray:
    """Average ``da`` over logarithmically spaced bins of its positive coordinate ``dim``.

    Empty bins are dropped; the new coordinate is the mean abscissa of each bin.
    Works lazily on dask (``dim`` must be one chunk).
    """
    x = np.asarray(da[dim].values, dtype=float)
    pos = x > 0
    if not pos.any():
        raise GridError(f"no positive {dim!r} values to bin")
    lo, hi = x[pos].min(), x[pos].max()
    plan = log_plan(x, lo, hi, nb_points)
    out = xr.apply_ufunc(plan.mean, da, input_core_dims=[[dim]], output_core_dims=[["_bin"]],
                         exclude_dims={dim}, dask="parallelized", output_dtypes=[float],
                         dask_gufunc_kwargs={"output_sizes": {"_bin": len(plan)}, "allow_rechunk": False},
                         keep_attrs=True)
    return out.rename({"_bin": dim}).assign_coords({dim: (dim, plan.centers, dict(da[dim].attrs))})


def finish(da: xr.DataArray, name: str, units: str, long_name: str, prep: Prepared, **attrs):
    """Name and annotate a result of the analysis ``name``."""
    da.name = name
    da.attrs = {"units": units, "long_name": long_name, "analysis": name, **prep.attrs(**attrs)}
    return da


def unit_of(kind: str, length: str) -> str:
    """The unit a parameter table names by ``kind``: "L" the length unit ``length``, "V" a volume per area, "L-1"
    and "L-2" inverse lengths and areas; any other kind ("1", "%", "degree") is the unit itself."""
    return {"L": length, "V": f"{length}3 {length}-2", "L-1": f"{length}-1", "L-2": f"{length}-2"}.get(kind, kind)


def split_parameters(out: xr.DataArray, attrs: dict) -> dict:
    """One variable per entry of ``attrs`` (name → its attrs), in order along the ``parameter`` dim of ``out``."""
    return {name: out.isel(parameter=i, drop=True).assign_attrs(a) for i, (name, a) in enumerate(attrs.items())}


def _param(value) -> str:
    """``value`` for a history line: short sequences in full, long ones summarised."""
    if isinstance(value, (str, bytes)) or np.ndim(value) == 0:
        return repr(value.item() if isinstance(value, (np.generic, np.ndarray)) else value)
    v = np.asarray(value)
    if v.size <= 8:
        return repr(v.tolist())
    return f"<{v.size} values from {v.min().item()!r} to {v.max().item()!r}>" if v.dtype.kind in "iuf" else \
        f"<{v.size} values>"


def provenance(result, obj, analysis: str, **params):
    """``result`` (a DataArray or Dataset) with the provenance of the measurement ``obj`` it was computed from.

    ``source_file`` and ``source_sha256`` are copied when ``obj`` has them, and ``history`` is
    ``obj``'s history plus one line naming the analysis and its parameters. Only attrs change:
    dask results stay lazy. The one place where analysis results get their provenance.
    """
    result.attrs = {k: v for k, v in result.attrs.items() if k not in PROVENANCE_ATTRS}
    result.attrs.update(provenance_of(obj))
    args = ", ".join(f"{k}={_param(v)}" for k, v in params.items())
    return append_history(result, f"xtopo.{analysis}({args})")
