"""FFT convolution with an elastic Green's function, plans and buffers reused (paper §5.3).

:class:`Convolution` applies ``u = G * p`` for pressures on the *active* grid (the
measurement grid) and returns displacements on the same grid.  Periodic problems
transform on the native grid; free-boundary problems on the ``2N`` padded grid with
the padding handled inside: the forward transform along ``x`` runs only over the
``N_y`` rows that carry pressure (the others are zero) and the inverse along ``x``
only over the ``N_y`` rows that are returned, so one application costs about 3/4 of
a full padded forward+inverse real FFT pair.

Backends (``backend=``): ``"scipy"`` (``scipy.fft``, pocketfft caches its plans) or
``"pyfftw"`` (FFTW plans built once on preallocated, aligned buffers; no allocation per
call); ``"auto"`` picks by FFT grid size (:func:`xtopo._kernels.fft.choose_backend`).
"""

from __future__ import annotations

import numpy as np
import scipy.fft as sfft

from . import fft as _fft
from .greens import free_greens, padded_shape, periodic_greens

__all__ = ["Convolution"]

_COMPLEX = {np.dtype(np.float32): np.complex64, np.dtype(np.float64): np.complex128}


class Convolution:
    """``u = G * p`` on a grid of ``shape`` (``(ny, nx)`` or ``(nx,)``).

    Parameters
    ----------
    shape : tuple of int
        Active grid (the measurement's pixels).
    spacing : tuple of float
        Pixel sizes, same order as ``shape`` (length units).
    modulus : float
        Contact modulus ``E*``.
    periodic : bool
        Periodic Green's function eq. (17) on the native grid, or the free-boundary
        kernel (eq. 19 / plane-strain strip) on the padded grid.
    dtype : {"float64", "float32"}
        Floating point type of the arrays and transforms.
    backend : {"auto", "scipy", "pyfftw"}
        FFT library.
    """

    def __init__(self, shape, spacing, modulus: float = 1.0, *, periodic: bool, dtype="float64",
                 backend: str = "auto"):
        self.shape = tuple(int(n) for n in shape)
        self.ndim = len(self.shape)
        self.periodic = bool(periodic)
        self.dtype = np.dtype(dtype)
        self.cdtype = np.dtype(_COMPLEX[self.dtype])
        self.fft_shape = self.shape if self.periodic else padded_shape(self.shape)
        self.backend = _fft.choose_backend(self.fft_shape, backend)
        self.workers = _fft.workers()
        make = periodic_greens if self.periodic else free_greens
        self.greens = make(self.shape, spacing, modulus, dtype=self.dtype)
        self._plan = None

    # -- plans -------------------------------------------------------------------------------
    def __getstate__(self):
        state = dict(self.__dict__)
        state["_plan"] = None  # FFTW plans do not pickle; rebuilt on first use
        return state

    def _build_pyfftw(self):
        import pyfftw

        flags = ("FFTW_MEASURE",) if int(np.prod(self.fft_shape)) <= 2**22 else ("FFTW_ESTIMATE",)
        kw = dict(threads=self.workers, flags=flags)
        nx_fft = self.fft_shape[-1]
        nxc = nx_fft // 2 + 1
        real_shape = self.shape[:-1] + (nx_fft,)
        r_in = pyfftw.zeros_aligned(real_shape, dtype=self.dtype)
        r_out = pyfftw.empty_aligned(real_shape, dtype=self.dtype)
        if self.ndim == 1 or self.periodic:
            c = pyfftw.empty_aligned(self.fft_shape[:-1] + (nxc,), dtype=self.cdtype)
            axes = tuple(range(-self.ndim, 0))
            fwd = pyfftw.FFTW(r_in, c, axes=axes, direction="FFTW_FORWARD", **kw)
            bwd = pyfftw.FFTW(c, r_out, axes=axes, direction="FFTW_BACKWARD",
                              flags=kw["flags"] + ("FFTW_DESTROY_INPUT",), threads=self.workers)
            self._plan = ("direct", r_in, c, r_out, fwd, bwd, None, None)
            return
        ny = self.shape[0]
        big_in = pyfftw.zeros_aligned((self.fft_shape[0], nxc), dtype=self.cdtype)
        big_out = pyfftw.empty_aligned((self.fft_shape[0], nxc), dtype=self.cdtype)
        fx = pyfftw.FFTW(r_in, big_in[:ny], axes=(-1,), direction="FFTW_FORWARD", **kw)
        fy = pyfftw.FFTW(big_in, big_out, axes=(0,), direction="FFTW_FORWARD", **kw)
        by = pyfftw.FFTW(big_out, big_out, axes=(0,), direction="FFTW_BACKWARD", **kw)
        bx = pyfftw.FFTW(big_out[:ny], r_out, axes=(-1,), direction="FFTW_BACKWARD",
                         flags=kw["flags"] + ("FFTW_DESTROY_INPUT",), threads=self.workers)
        self._plan = ("pruned", r_in, big_out, r_out, fx, fy, by, bx)

    # -- application -------------------------------------------------------------------------
    def __call__(self, p: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Displacements ``G * p`` on the active grid (written into ``out`` when given)."""
        if out is None:
            out = np.empty(self.shape, dtype=self.dtype)
        if self.backend == "pyfftw":
            return self._apply_pyfftw(p, out)
        return self._apply_scipy(p, out)

    def _apply_scipy(self, p, out):
        w = self.workers
        if self.periodic:
            axes = tuple(range(-self.ndim, 0))
            f = sfft.rfftn(p, axes=axes, workers=w)
            f *= self.greens
            out[...] = sfft.irfftn(f, s=self.shape, axes=axes, workers=w, overwrite_x=True)
            return out
        nx_fft = self.fft_shape[-1]
        f = sfft.rfft(p, n=nx_fft, axis=-1, workers=w)
        if self.ndim == 1:
            f *= self.greens
            out[...] = sfft.irfft(f, n=nx_fft, workers=w, overwrite_x=True)[: self.shape[0]]
            return out
        ny = self.shape[0]
        f = sfft.fft(f, n=self.fft_shape[0], axis=0, workers=w, overwrite_x=True)
        f *= self.greens
        f = sfft.ifft(f, axis=0, workers=w, overwrite_x=True)
        out[...] = sfft.irfft(f[:ny], n=nx_fft, axis=-1, workers=w, overwrite_x=True)[:, : self.shape[1]]
        return out

    def _apply_pyfftw(self, p, out):
        if self._plan is None:
            self._build_pyfftw()
        kind, r_in, c, r_out, a, b, cc, d = self._plan
        n = self.shape[-1]
        scale_free = 1.0 / float(np.prod(self.fft_shape))
        if self.periodic:
            r_in[...] = p
        else:
            r_in[..., :n] = p
        if kind == "direct":
            a.execute()
            c *= self.greens
            b.execute()
        else:
            a.execute()
            b.execute()
            c *= self.greens
            cc.execute()
            d.execute()
        np.multiply(r_out[..., :n], scale_free, out=out)
        return out
