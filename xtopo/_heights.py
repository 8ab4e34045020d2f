"""New heights back into a measurement, with their history: shared by the steps that make new heights
(:mod:`xtopo.preprocess`: detrend, fill_missing; :mod:`xtopo.filtration`: ISO 16610 filters). Not public API."""

from __future__ import annotations

import numpy as np
import xarray as xr

from ._apply import apply_lateral
from ._kernels import polyfit as _poly
from .conventions import HEIGHT, X, Y, append_history
from .errors import GridError

__all__ = ["fit_positions", "subtract_polynomial", "replace_heights"]


def fit_positions(h, dim):
    """Positions along ``dim`` for the polynomial fit (pixel indices when there is no coordinate)."""
    if dim not in h.coords:
        return np.arange(h.sizes[dim], dtype=float)
    v = np.asarray(h.coords[dim].values, dtype=float)
    if not np.all(np.isfinite(v)):
        raise GridError(f"detrend: coordinate {dim!r} has {int(np.count_nonzero(~np.isfinite(v)))} NaN or infinite "
                        "positions; the fit needs a position for every pixel")
    return v


def subtract_polynomial(h, dims, degree: int, what: str, per_line: bool = False, **options):
    """``h`` minus its least-squares polynomial of ``degree`` in the positions: over the map for both lateral
    ``dims`` (each row's own with ``per_line``), along each profile for one; ``options`` go to ``apply_lateral``."""
    if len(dims) == 2:
        kernel, kwargs = _poly.subtract_polynomial_2d, {"y": fit_positions(h, Y), "x": fit_positions(h, X),
                                                        "per_line": per_line}
    else:
        kernel, kwargs = _poly.subtract_polynomial_1d, {"x": fit_positions(h, dims[0])}
    return apply_lateral(kernel, h, core_dims=dims, output_core_dims=[dims], what=what,
                         kwargs=dict(kwargs, degree=degree), **options).transpose(*h.dims)


def replace_heights(obj, result, line: str, *, nonperiodic: bool = False):
    """Put ``result`` (the new heights) back into a Dataset/DataArray like ``obj``.

    ``nonperiodic``: the new heights are no longer periodic; attr ``periodic`` becomes 0 (the history ``line`` says so).
    """
    if nonperiodic:
        line += "; periodic set to 0"
    h_in = obj[HEIGHT] if isinstance(obj, xr.Dataset) else obj
    # h_in's coordinates with their attrs (units, spacing); apply_ufunc drops coordinate attrs
    result = h_in.copy(data=result.transpose(*h_in.dims).data)
    result.attrs = dict(h_in.attrs)
    if nonperiodic and "periodic" in result.attrs:
        result.attrs["periodic"] = 0
    if isinstance(obj, xr.Dataset):
        out = obj.copy(deep=False)
        out[h_in.name] = result
        if nonperiodic:
            out.attrs["periodic"] = 0
        return append_history(out, line)
    return append_history(result, line)
