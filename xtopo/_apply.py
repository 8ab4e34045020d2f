"""The chunk contract (DESIGN.md §4): wrap numpy kernels with ``xr.apply_ufunc``.

Kernels take arrays with the lateral core dims last; extra (batch) dims broadcast
and dask arrays stay lazy. Global transforms need the lateral dims in one chunk.
Results have the declared output dtypes (float64 by default) whatever the input
precision, so numpy and dask agree and a lazy result's ``dtype`` is what it computes to.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from .conventions import lateral_dims
from .errors import ChunkError

__all__ = ["check_core_chunks", "apply_lateral"]


def check_core_chunks(da: xr.DataArray, core_dims, what: str = "this analysis") -> None:
    """Raise :class:`ChunkError` if ``da`` is split into several chunks along a core dim."""
    if da.chunks is None:
        return
    for dim, chunks in zip(da.dims, da.chunks):
        if dim in core_dims and len(chunks) > 1:
            raise ChunkError(
                f"{what} needs dimension {dim!r} in a single chunk, but it has {len(chunks)} chunks; "
                f"rechunk with .chunk({{{dim!r}: -1}}) and chunk along batch dimensions instead")


def _declared(kernel, dtypes):
    """``kernel`` with its output(s) cast to ``dtypes`` (a float32 FFT would otherwise give float32)."""
    def run(*args, **kwargs):
        out = kernel(*args, **kwargs)
        if len(dtypes) == 1:
            return np.asarray(out, dtype=dtypes[0])
        return tuple(np.asarray(o, dtype=d) for o, d in zip(out, dtypes))

    return run


def apply_lateral(kernel, da: xr.DataArray, *, output_core_dims=((),), output_sizes=None, output_dtypes=None,
                  kwargs=None, what: str = "this analysis", core_dims=None, exclude_dims=frozenset()):
    """Apply ``kernel(values, **kwargs)`` over the lateral dims of ``da``.

    Parameters
    ----------
    kernel : callable
        numpy function; receives an array with the core dims last.
    da : xarray.DataArray
        Heights; any extra dims are broadcast (vectorised by the kernel itself).
    output_core_dims : sequence of sequence of str
        Core dims of each output.
    output_sizes : dict, optional
        Sizes of new output dims (needed for dask).
    core_dims : tuple of str, optional
        Input core dims; default the lateral dims of ``da``.
    """
    core = tuple(core_dims) if core_dims is not None else lateral_dims(da)
    check_core_chunks(da, core, what)
    dtypes = list(output_dtypes or [float] * len(output_core_dims))
    return xr.apply_ufunc(
        _declared(kernel, dtypes), da,
        input_core_dims=[list(core)],
        output_core_dims=[list(c) for c in output_core_dims],
        exclude_dims=set(exclude_dims),
        kwargs=kwargs or {},
        dask="parallelized",
        output_dtypes=dtypes,
        dask_gufunc_kwargs={"output_sizes": output_sizes or {}, "allow_rechunk": False},
        keep_attrs=False,
    )
