"""The chunk contract (DESIGN.md §4): wrap numpy kernels with ``xr.apply_ufunc``.

Kernels take arrays with the lateral core dims last; extra (batch) dims broadcast
and dask arrays stay lazy. Global transforms need the lateral dims in one chunk.
Results have the declared output dtypes (float64 by default) whatever the input
precision, so numpy and dask agree and a lazy result's ``dtype`` is what it computes to.

Extreme height scales are handled here, once, for every analysis and preprocessing step
(``height_power=``): results are linear or power-law in the height scale (a PSD goes as h², an
RMS height as h, a skewness as h⁰), so a kernel given heights of order 1e±300 computes on
``h / 2**e`` (``2**e`` near the largest |h|: an exact rescaling) and its results are multiplied
by ``2**(e·p)``. Where the true result lies beyond float64 (the PSD of heights 1e300 m is
1e600 m³) it is refused with an :class:`~xtopo.errors.XtopoError` instead of turning into inf or
an underflowed 0: results are finite and right, or an error.
"""

from __future__ import annotations

import functools

import numpy as np
import xarray as xr

from .conventions import lateral_dims
from .errors import ChunkError, MissingDataError, XtopoError

__all__ = ["check_core_chunks", "apply_lateral", "scale_exponent", "rescaled"]


def check_core_chunks(da: xr.DataArray, core_dims, what: str = "this analysis") -> None:
    """Raise :class:`ChunkError` if ``da`` is split into several chunks along a core dim."""
    if da.chunks is None:
        return
    for dim, chunks in zip(da.dims, da.chunks):
        if dim in core_dims and len(chunks) > 1:
            raise ChunkError(
                f"{what} needs dimension {dim!r} in a single chunk, but it has {len(chunks)} chunks; "
                f"rechunk with .chunk({{{dim!r}: -1}}) and chunk along batch dimensions instead")


#: heights beyond 2**±SCALED_FROM (about 1e±19) are analysed in scaled units: the squares, cubes and
#: fourth powers the kernels form stay inside float64 below that
SCALED_FROM = 64


def scale_exponent(h: np.ndarray) -> int:
    """``e`` with ``2**e`` near the largest finite |h| when that is beyond ``2**±SCALED_FROM``, else 0."""
    if h.dtype.kind not in "fc" or h.size == 0:
        return 0
    hi, lo = float(h.real.max()), float(h.real.min())  # one pass each, no temporaries (~2 % of an FFT's time)
    if np.isnan(hi) or np.isnan(lo):  # missing data: the NaN-skipping reductions (all NaN gives NaN: 0 below)
        hi, lo = float(np.fmax.reduce(h.real, axis=None)), float(np.fmin.reduce(h.real, axis=None))
    top = max(abs(hi), abs(lo))
    if not np.isfinite(top) or top == 0.0:
        return 0
    e = int(np.frexp(top)[1])
    return e if abs(e) > SCALED_FROM else 0


def rescaled(out, e: int, power, what: str) -> np.ndarray:
    """``out · 2**(e·power)``; an XtopoError where a finite nonzero value leaves float64's normal range."""
    if power is None or e == 0:
        return out
    out = np.asarray(out)
    exponent = e * np.asarray(power)
    if not np.any(exponent):
        return out
    with np.errstate(over="ignore", under="ignore", invalid="ignore"):  # an overflow is what is checked next
        scaled = np.ldexp(out, exponent.astype(np.int64)) if out.dtype.kind == "f" else out * 2.0 ** exponent
        finite = np.isfinite(out)
        # an element may underflow where it is below eps² of the output's largest value (a spectrum's tail far
        # under its peak, as float64 arithmetic on unscaled heights would also flush it); a significant one may not
        top = float(np.max(np.abs(out), where=finite, initial=0.0))
        significant = np.abs(out) > np.finfo(np.float64).eps ** 2 * top
        lost = finite & (out != 0) & significant & ~(np.abs(scaled) >= np.finfo(scaled.dtype).tiny) | \
            (finite & ~np.isfinite(scaled))
    if lost.any():
        raise XtopoError(f"{what}: heights of order 2**{e} (1e{e * np.log10(2):+.0f}) give results beyond the range "
                         f"of float64 (about 1e±308): the result goes as height**{np.max(np.abs(power))}; express "
                         "the heights in a unit that brings them nearer to 1 (xtopo.convert_length)")
    return scaled


def _run_declared(kernel, dtypes, height_power, what, heights_out, h, *args, **kwargs):
    """``kernel`` with its output(s) cast to ``dtypes`` (a float32 FFT would otherwise give float32), computed in
    scaled units when ``height_power`` (one entry per output) says how each output scales (:func:`apply_lateral`)."""
    e = scale_exponent(h) if height_power is not None else 0
    hs = np.ldexp(h, -e) if e else h
    try:
        out = kernel(hs, *args, **kwargs)
    except MissingDataError as exc:  # the kernels say what is wrong; the advice is the layer's above
        raise MissingDataError(f"{exc}; fill them first, e.g. with xtopo.preprocess.fill_missing, or crop to a "
                               "complete region") from None
    outs = (out,) if len(dtypes) == 1 else tuple(out)
    if e and heights_out:
        noise = 4 * np.finfo(np.float64).eps * float(np.nanmax(np.abs(hs), initial=0.0))
        outs = tuple(np.where(np.abs(o) > noise, o, 0.0 * o) for o in outs)
    powers = height_power if height_power is not None else (None,) * len(outs)
    res = tuple(np.asarray(rescaled(np.asarray(o, dtype=d), e, p, what), dtype=d)
                for o, p, d in zip(outs, powers, dtypes))
    return res[0] if len(dtypes) == 1 else res


def apply_lateral(kernel, da: xr.DataArray, *, output_core_dims=((),), output_sizes=None, output_dtypes=None,
                  kwargs=None, what: str = "this analysis", core_dims=None, exclude_dims=frozenset(),
                  height_power=None, heights_out: bool = False):
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
    height_power : sequence, optional
        For each output, how it scales with the heights: a number (2 for a PSD, 0 for a skewness),
        an array along the output's last axis (one power per parameter), or ``None`` (not a
        function of the height scale alone). Given, extreme heights are analysed in scaled units
        (module docstring).
    heights_out : bool
        The outputs are heights on the input's scale after a fit (detrend): rounding noise below
        the largest input height's precision becomes 0 instead of an underflow error.
    """
    core = tuple(core_dims) if core_dims is not None else lateral_dims(da)
    check_core_chunks(da, core, what)
    dtypes = list(output_dtypes or [float] * len(output_core_dims))
    # a partial of a module-level function, not a closure: dask tokenizes the function of every lazy analysis, and
    # a closure is pickled by value for it (cloudpickle), which cost a twin of a thousand measurements seconds
    return xr.apply_ufunc(
        functools.partial(_run_declared, kernel, tuple(dtypes), height_power, what, heights_out), da,
        input_core_dims=[list(core)],
        output_core_dims=[list(c) for c in output_core_dims],
        exclude_dims=set(exclude_dims),
        kwargs=kwargs or {},
        dask="parallelized",
        output_dtypes=dtypes,
        dask_gufunc_kwargs={"output_sizes": output_sizes or {}, "allow_rechunk": False},
        keep_attrs=False,
    )
